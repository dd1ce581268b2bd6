"""Fault-injection suite for long pile runs (docs/reliability.md). Run with Debian's Python:

    /usr/bin/python3 scripts/fault_injection.py [--out out/faults] [--kills 24] [--grains 300] [--relax 2] [--seed 1]

1. an uninterrupted reference pile;
2. the same pile killed with SIGKILL at ``--kills`` random moments (every fourth one during a
   checkpoint write), with the newest checkpoint damaged after three of the kills (a truncated
   state.npz, bytes flipped in scene.yade.gz, a truncated meta.json), resumed after each;
3. the same pile on a small tmpfs that is filled mid-run (needs root), then resumed with space back;
4. the first release's checkpoint in tests/data, resumed by this code.

Every run must end bit for bit where the reference ends, and no kill may lose more than one
checkpoint interval (plus the write in progress). Writes ``faults.json`` and ``faults.md`` in
--out (the table of docs/reliability.md). Takes about 10 minutes for 300 grains.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import time

import numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
from yadecd.testing import faults  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(prog='fault_injection.py', description=__doc__.split('\n')[0])
    ap.add_argument('--out', default='out/faults')
    ap.add_argument('--kills', type=int, default=24)
    ap.add_argument('--grains', type=int, default=300)
    ap.add_argument('--relax', type=float, default=2.0, help='relaxation [s]: long enough for every kill to land mid-run')
    ap.add_argument('--checkpoint-every', type=float, default=2.0, help='wall seconds between checkpoints')
    ap.add_argument('--seed', type=int, default=1, help='seed of the pile and of the kill moments')
    a = ap.parse_args(argv)
    if a.kills < 1 or a.grains < 1 or a.checkpoint_every <= 0 or a.relax <= 0:
        ap.error('--kills, --grains, --relax and --checkpoint-every must be positive')
    if os.path.exists(a.out):
        ap.error('%s exists: choose another --out (a fault run never overwrites one)' % a.out)
    os.makedirs(a.out)
    rng = np.random.default_rng(a.seed)
    options = ['--n-grains', str(a.grains), '--relax', str(a.relax), '--seed', str(a.seed), '--snap-every', '1e9',
               '--checkpoint-every', str(a.checkpoint_every)]
    record = dict(options=options, started=time.strftime('%Y-%m-%d %H:%M:%S'))

    print('faults: reference run ...', flush=True)
    t0 = time.time()
    ref_dir = os.path.join(a.out, 'reference')
    subprocess.run(faults.pile_command(ref_dir, options), check=True, stdout=subprocess.DEVNULL)
    record['reference_wall_s'] = time.time() - t0
    ref = faults.final_state(ref_dir)
    print('faults: reference %.0f s' % record['reference_wall_s'], flush=True)

    # each start is killed 2.5–6.5 s later (YADE starts in about 2 s, a checkpoint every 2 s by
    # default): some kills land before the start's first checkpoint, most after a few
    delays = [float(rng.uniform(2.5, 6.5)) for _ in range(a.kills)]
    delays = [-d if k % 4 == 1 else d for k, d in enumerate(delays)]
    damage = {5: ('state.npz', 'truncate'), 11: ('scene.yade.gz', 'flip'), 17: ('meta.json', 'truncate')}
    damage = {k: v for k, v in damage.items() if k < a.kills}
    kill_dir = os.path.join(a.out, 'killed')
    campaign = faults.KillCampaign(kill_dir, options, delays, damage_after=damage, rng=rng)
    t0 = time.time()
    events = campaign.run()
    resumed, skipped = campaign.resumed_units()
    killed = [e for e in events if e.get('killed')]
    lost_own = [e['lost_s'] for e in killed if e['checkpoint_written_by_this_start']]
    lost_none = [e['lost_s'] for e in killed if not e['checkpoint_written_by_this_start']]
    record['kills'] = dict(events=events, wall_s=time.time() - t0, killed=len(killed), planned=a.kills,
                           during_write=sum(e['during_checkpoint_write'] for e in killed),
                           before_first_checkpoint=sum(e['units_after'] == 0 for e in killed),
                           before_own_checkpoint=len(lost_none),
                           damaged=len([e for e in killed if 'damaged' in e]), resumes=len(resumed),
                           skipped_units=skipped, max_lost_after_own_checkpoint_s=max(lost_own, default=0.0),
                           max_lost_before_own_checkpoint_s=max(lost_none, default=0.0),
                           end_difference=faults.compare_states(faults.final_state(kill_dir), ref))
    print('faults: %d kills, end difference: %s' % (len(killed), record['kills']['end_difference'] or 'none'), flush=True)

    if os.geteuid() == 0:
        mnt = os.path.abspath(os.path.join(a.out, 'small_disk'))
        os.makedirs(mnt)
        size_mb = 6
        subprocess.run(['mount', '-t', 'tmpfs', '-o', 'size=%dm' % size_mb, 'tmpfs', mnt], check=True)
        try:
            run_dir = os.path.join(mnt, 'run')
            r = faults.fill_disk_trial(run_dir, options, filler=os.path.join(mnt, 'filler'),
                                       log_path=os.path.join(a.out, 'full_disk.log'))
            r['disk_mb'] = size_mb
            r['end_difference'] = faults.compare_states(faults.final_state(run_dir), ref) \
                if r['resume_returncode'] == 0 else 'resume failed'
            record['full_disk'] = r
        finally:
            subprocess.run(['umount', mnt], check=False)
        print('faults: full disk: exit %d, "%s"' % (r['returncode'], r['error']), flush=True)
    else:
        record['full_disk'] = 'not run: mounting a tmpfs needs root'

    src = os.path.join(REPO, 'tests', 'data', 'checkpoint_release_6e7a405')
    old_dir = os.path.join(a.out, 'release_6e7a405')
    os.makedirs(old_dir)
    for name in ('run.json', 'checkpoint.json', 'checkpoint.yade.gz'):
        shutil.copy(os.path.join(src, name), old_dir)
    proc = subprocess.run(faults.pile_command(old_dir, resume=True), capture_output=True, text=True)
    record['previous_release'] = dict(returncode=proc.returncode,
                                      resumed=[ln for ln in proc.stdout.splitlines() if ln.startswith('resumed')])

    with open(os.path.join(a.out, 'faults.json'), 'w') as f:
        json.dump(record, f, indent=1, default=str)
    write_table(record, os.path.join(a.out, 'faults.md'))
    ok = not record['kills']['end_difference'] and record['kills']['killed'] == a.kills and (not isinstance(record['full_disk'], dict)
                                                    or not record['full_disk']['end_difference'])
    print(open(os.path.join(a.out, 'faults.md')).read())
    return 0 if ok and record['previous_release']['returncode'] == 0 else 1


def write_table(r, path):
    """The fault-injection record ``r`` as a markdown table at ``path``: each fault, how often it
    was tried, and what happened."""
    k = r['kills']
    lines = ['| fault | tried | outcome |', '|---|---|---|',
             '| SIGKILL at a random moment | %d%s | %d resumes; end bit-identical to the uninterrupted run: %s |'
             % (k['killed'], '' if k['killed'] == k['planned'] else ' (of %d planned: the run ended first)' % k['planned'],
                k['resumes'], 'yes' if not k['end_difference'] else 'NO (%s)' % k['end_difference']),
             '| … of which during a checkpoint write | %d | the unit in progress ignored, the previous one used |'
             % k['during_write'],
             '| … of which before the first checkpoint | %d | the run started again from its run.json |'
             % k['before_first_checkpoint'],
             '| newest checkpoint damaged after a kill | %d | reported, moved aside (%d units), the previous one used |'
             % (k['damaged'], len(k['skipped_units'])),
             '| work lost by a kill after the start had written a checkpoint: computing since its newest '
             'verified one (interval %s s, plus a write in progress) | %d | at most %.2f s |'
             % (r['options'][-1], k['killed'] - k['before_own_checkpoint'], k['max_lost_after_own_checkpoint_s']),
             '| work lost by a kill before the start wrote its first checkpoint (YADE start-up included) | %d | at most '
             '%.2f s |' % (k['before_own_checkpoint'], k['max_lost_before_own_checkpoint_s'])]
    fd = r['full_disk']
    if isinstance(fd, dict):
        lines.append('| disk full mid-run (%d MB tmpfs) | 1 | exit %d: "%s"; last checkpoint valid: %s; resumed once space was '
                     'back, end bit-identical: %s |' % (fd['disk_mb'], fd['returncode'], fd['error'].replace('|', '/'),
                                                        fd['last_unit_valid'], 'yes' if not fd['end_difference']
                                                        else 'NO (%s)' % fd['end_difference']))
    else:
        lines.append('| disk full mid-run | 0 | %s |' % fd)
    pr = r['previous_release']
    lines.append('| checkpoint of the first release (6e7a405) | 1 | %s |'
                 % ('resumed and finished' if pr['returncode'] == 0 else 'FAILED (exit %d)' % pr['returncode']))
    lines.append('')
    lines.append('Pile: %s; reference run %.0f s; the kill campaign took %.0f s.'
                 % (' '.join(r['options']), r['reference_wall_s'], k['wall_s']))
    with open(path, 'w') as f:
        f.write('\n'.join(lines) + '\n')


if __name__ == '__main__':
    sys.exit(main())

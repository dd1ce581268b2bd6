"""Two builds of the plugin timed in one run: the solver benchmark (solver_bench.py) run in turn
under an old and a new YADE prefix (scripts/plugin_variant.py makes them), rounds interleaved so
that the machine's drift hits both alike; prints and saves the median of every figure per build
and their ratio new/old.

    /usr/bin/python3 scripts/bench/ab_plugins.py --old PREFIX_A --new PREFIX_B [--rounds 3]
        [--contacts 1e4,1e5] [--snapshot RUN/snap_0010.000.npz] [--feed] [--out docs/data/core_ab.csv]

A ratio below 1 means the new build is faster. Rows: ns per contact-sweep on FCC blocks (sphere
kernel, general kernel, coloured schedule, with momentum) and ms per step of each integrator
stage on the blocks and on pile states. Run it on an idle machine, with one thread (-j1) unless
--threads says otherwise.
"""
import argparse
import csv
import datetime
import os
import statistics
import subprocess
import sys
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def run_bench(prefix, args, out):
    env = dict(os.environ, YADECD_VARIANT_PREFIX=prefix)
    cmd = [os.path.join(REPO, 'scripts', 'yade'), '-j%d' % args.threads, '-n', '-x',
           os.path.join(REPO, 'scripts', 'bench', 'solver_bench.py'), '--no-siconos', '--contacts', args.contacts,
           '--pile-variants', '', '--pile-steps', str(args.pile_steps), '--out', out] + (['--feed'] if args.feed else []) \
        + (['--no-block-steps'] if args.no_block_steps else [])
    if args.snapshot:
        cmd += ['--snapshot'] + args.snapshot
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        sys.exit('ab_plugins.py: the benchmark failed under %s:\n%s' % (prefix, proc.stdout[-3000:] + proc.stderr[-3000:]))
    with open(out) as f:
        return [r for r in csv.DictReader(f) if r['kind'] in ('sweep', 'stage')]


def main(argv=None):
    ap = argparse.ArgumentParser(prog='ab_plugins.py', description=__doc__.split('\n')[0])
    ap.add_argument('--old', required=True, help='YADE prefix running the old plugin')
    ap.add_argument('--new', required=True, help='YADE prefix running the new plugin')
    ap.add_argument('--rounds', type=int, default=3)
    ap.add_argument('--threads', type=int, default=1)
    ap.add_argument('--contacts', default='1e4,1e5')
    ap.add_argument('--snapshot', nargs='*', default=[])
    ap.add_argument('--feed', action='store_true')
    ap.add_argument('--pile-steps', type=int, default=20)
    ap.add_argument('--no-block-steps', action='store_true', help='on the blocks, only the per-sweep figures')
    ap.add_argument('--out', default=os.path.join(REPO, 'docs', 'data', 'core_ab.csv'))
    args = ap.parse_args(argv)
    for name in ('old', 'new'):
        if not os.path.isdir(getattr(args, name)):
            ap.error('--%s %s: no such prefix (make one with scripts/plugin_variant.py)' % (name, getattr(args, name)))
    values = {}  # (scene, contacts-ish key, method, quantity) -> {'old': [...], 'new': [...]}
    with tempfile.TemporaryDirectory() as tmp:
        for rnd in range(args.rounds):
            order = ('old', 'new') if rnd % 2 == 0 else ('new', 'old')
            for build in order:
                rows = run_bench(getattr(args, build), args, os.path.join(tmp, '%s_%d.csv' % (build, rnd)))
                for r in rows:
                    key = (r['kind'], r['scene'], r['method'], r['quantity'], r['unit'])
                    values.setdefault(key, {'old': [], 'new': [], 'contacts': r['contacts'], 'sweeps': []})
                    values[key][build].append(float(r['value']))
                    if r['sweeps']:
                        values[key]['sweeps'].append(float(r['sweeps']))
                print('round %d/%d: %s done' % (rnd + 1, args.rounds, build), flush=True)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    fields = ['date', 'threads', 'rounds', 'kind', 'scene', 'contacts', 'method', 'quantity', 'unit', 'old_median', 'new_median',
              'ratio_new_old', 'old_min', 'new_min', 'ratio_min', 'ratio_paired', 'sweeps']
    with open(args.out, 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for (kind, scene, method, quantity, unit), v in values.items():
            if not v['old'] or not v['new']:
                continue
            mo, mn = statistics.median(v['old']), statistics.median(v['new'])
            # noise on a shared host only ever slows a run down: the best of the rounds estimates the intrinsic cost;
            # the median of the per-round ratios cancels drift slower than one round
            lo, ln = min(v['old']), min(v['new'])
            paired = statistics.median(n / o for o, n in zip(v['old'], v['new']) if o)
            row = dict(date=datetime.date.today().isoformat(), threads=args.threads, rounds=args.rounds, kind=kind, scene=scene,
                       contacts=v['contacts'], method=method, quantity=quantity, unit=unit, old_median='%.4g' % mo,
                       new_median='%.4g' % mn, ratio_new_old='%.3f' % (mn / mo if mo else float('nan')),
                       old_min='%.4g' % lo, new_min='%.4g' % ln, ratio_min='%.3f' % (ln / lo if lo else float('nan')),
                       ratio_paired='%.3f' % paired,
                       sweeps='%.1f' % statistics.median(v['sweeps']) if v['sweeps'] else '')
            w.writerow(row)
            print('%-6s %-34s %-24s %-28s old %9.4g  new %9.4g  new/old: medians %.3f, best %.3f, paired %.3f'
                  % (kind, scene[:34], method[:24], quantity[:28], mo, mn, mn / mo if mo else float('nan'),
                     ln / lo if lo else float('nan'), paired))
    print('wrote', args.out)
    return 0


if __name__ == '__main__':
    sys.exit(main())

"""Two builds of the plugin on the same stretch of a pile run, end to end: a scratch copy of the run
is resumed from its checkpoint by each build in turn and run to ``--stop-time`` by ``pile.py``
(feeding, collider, engine, snapshots, checkpoints: everything a pile run pays), rounds interleaved
so that the machine's drift hits both alike; prints and saves the wall time of every run and the
median ratio new/old.

    /usr/bin/python3 scripts/bench/ab_pile.py RUN --old PREFIX_A [--new PREFIX_B] --stop-time T
        [--rounds 2] [--threads 1] [--out docs/data/ab_pile.csv]

PREFIX: a YADE prefix from scripts/plugin_variant.py (the installed YADE when ``--new`` is not
given). RUN is never touched. Both builds resume the same checkpoint (each through YADE's archive
when the checkpoint was written by it, else through the run state: the same physical state), so
the stretches differ at most by rounding. The wall time includes YADE's start (about 3 s). Run it
on an idle machine (stop other runs with SIGSTOP meanwhile).
"""
import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(REPO, 'py'))
from yadecd.io import write_csv  # noqa: E402


def run_once(run, prefix, stop_time, threads, scratch):
    """Wall time [s] of resuming a copy of ``run`` to ``stop_time`` with the build in ``prefix``."""
    work = os.path.join(scratch, 'run')
    shutil.rmtree(work, ignore_errors=True)
    shutil.copytree(run, work)
    env = dict(os.environ)
    if prefix:
        env['YADECD_VARIANT_PREFIX'] = prefix
    cmd = [os.path.join(REPO, 'scripts', 'yade'), '-j%d' % threads, '-n', '-x', os.path.join(REPO, 'scripts', 'pile.py'),
           '--out', work, '--resume', '--stop-time', repr(stop_time)]
    t0 = time.time()
    out = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.time() - t0
    if out.returncode != 0:
        raise RuntimeError('ab_pile: %s failed (exit %d):\n%s' % (' '.join(cmd), out.returncode, out.stderr[-2000:]))
    resumed = [ln for ln in out.stdout.splitlines() if ln.startswith('resumed')]
    return wall, resumed[0] if resumed else ''


def main(argv=None):
    ap = argparse.ArgumentParser(prog='ab_pile.py', description=__doc__.split('\n')[0])
    ap.add_argument('run', help='a pile run directory (with a checkpoint)')
    ap.add_argument('--old', required=True, help='YADE prefix of the old build (scripts/plugin_variant.py)')
    ap.add_argument('--new', default=None, help='YADE prefix of the new build (default: the installed one)')
    ap.add_argument('--stop-time', type=float, required=True, help='simulated time [s] to run to')
    ap.add_argument('--rounds', type=int, default=2)
    ap.add_argument('--threads', type=int, default=1)
    ap.add_argument('--out', default=None, help='CSV of every run and the ratio')
    a = ap.parse_args(argv)
    if not os.path.isdir(a.run):
        ap.error('%s is not a run directory' % a.run)
    walls = {'old': [], 'new': []}
    rows = []
    with tempfile.TemporaryDirectory(prefix='ab-pile-') as scratch:
        for k in range(a.rounds):
            for which, prefix in (('old', a.old), ('new', a.new)):
                wall, resumed = run_once(a.run, prefix, a.stop_time, a.threads, scratch)
                walls[which].append(wall)
                rows.append(dict(round=k + 1, build=which, prefix=prefix or 'installed', run=os.path.abspath(a.run),
                                 stop_time_s=a.stop_time, threads=a.threads, wall_s='%.2f' % wall))
                print('round %d %-3s %7.2f s  %s' % (k + 1, which, wall, resumed[:90]), flush=True)
    ratio = statistics.median(walls['new']) / statistics.median(walls['old'])
    print('median wall: old %.2f s, new %.2f s, new/old %.3f' % (statistics.median(walls['old']), statistics.median(walls['new']),
                                                                 ratio))
    rows.append(dict(round='median', build='new/old', prefix='', run=os.path.abspath(a.run), stop_time_s=a.stop_time,
                     threads=a.threads, wall_s='%.3f' % ratio))
    if a.out:
        write_csv(a.out, rows)
    return 0


if __name__ == '__main__':
    sys.exit(main())

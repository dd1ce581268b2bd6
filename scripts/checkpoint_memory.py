"""Where a long run's memory goes: checkpoints alone, then steps alone, on one pile state.

    scripts/yade -j1 -n -x scripts/checkpoint_memory.py RUN_DIR [--checkpoints 100] [--steps 1000] [--out F.csv]

Resumes the pile run in RUN_DIR (a copy is made: the run itself is not touched), writes
``--checkpoints`` checkpoints in a row without stepping, then runs ``--steps`` steps without
checkpoints, sampling this process's resident memory (VmRSS) after every checkpoint and every 50
steps. A leak in the checkpoint path grows memory in the first phase, one in the solver in the
second. Prints the wall time and size of one checkpoint, the growth per checkpoint and per 1000
steps (least-squares slopes over each phase's second half) and writes the samples to --out.
"""
import argparse
import os
import shutil
import sys
import tempfile
import time

import numpy as np

from yade import O
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)
from yadecd import pile  # noqa: E402
from yadecd.io import rss_mb, write_csv  # noqa: E402


ap = argparse.ArgumentParser(prog='checkpoint_memory.py', description=__doc__.split('\n')[0])
ap.add_argument('run_dir')
ap.add_argument('--checkpoints', type=int, default=100)
ap.add_argument('--steps', type=int, default=1000)
ap.add_argument('--out', default=None)
a = ap.parse_args(sys.argv[1:])
if a.checkpoints < 2 or a.steps < 100:
    ap.error('--checkpoints must be >= 2 and --steps >= 100')
tmp = tempfile.mkdtemp(prefix='ckmem-')
try:
    work = os.path.join(tmp, 'run')
    shutil.copytree(a.run_dir, work, ignore=shutil.ignore_patterns('snap_*', 'vtk_*', '*.log', 'log.txt'))
    run = pile.PileRun.resume(work, {}, log=lambda s: None)
    rows = [('start', 0, rss_mb())]
    t0 = time.perf_counter()
    for k in range(a.checkpoints):
        run.checkpoint()
        rows.append(('checkpoint', k + 1, rss_mb()))
    per_checkpoint = (time.perf_counter() - t0) / a.checkpoints
    unit = run.store.latest()[1]
    unit_bytes = sum(os.path.getsize(os.path.join(unit, n)) for n in os.listdir(unit))
    for k in range(a.steps // 50):
        O.run(50, True)
        rows.append(('steps', 50 * (k + 1), rss_mb()))
finally:
    shutil.rmtree(tmp, ignore_errors=True)


def slope(phase, scale):
    """Growth of the resident memory over the second half of the samples of ``phase`` (MB per unit
    of count, times ``scale``), with the first and last values."""
    pts = np.array([(n, m) for p, n, m in rows if p == phase])
    half = pts[len(pts) // 2:]
    return np.polyfit(half[:, 0], half[:, 1], 1)[0] * scale, pts[0, 1], pts[-1, 1]


ck, ck0, ck1 = slope('checkpoint', 1.0)
st, st0, st1 = slope('steps', 1000.0)
print('checkpoint_memory: %d bodies, %d contacts; one checkpoint %.3f s of wall time, %.2f MB on disk'
      % (len(O.bodies), O.interactions.countReal(), per_checkpoint, unit_bytes / 1e6))
print('checkpoint_memory: start %.1f MB; after %d checkpoints %.1f MB (second half: %+.3f MB per checkpoint)'
      % (rows[0][2], a.checkpoints, ck1, ck))
print('checkpoint_memory: then after %d steps %.1f MB (second half: %+.3f MB per 1000 steps)' % (a.steps, st1, st))
if a.out:
    write_csv(a.out, [dict(phase=p, count=c, rss_mb=m) for p, c, m in rows])

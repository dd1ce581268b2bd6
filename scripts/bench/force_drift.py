"""Does a pile step's Gauss–Seidel solve converge, and if its residual stalls, where do the forces
still move? (docs/pile.md, force accuracy of the full pile.)

    scripts/yade -j1 -n -x scripts/bench/force_drift.py RUN_DIR [--sweeps 20000,22000] [--momentum 1]
        [--out FILE.json]

Loads the run's newest checkpoint (``PileRun.load``: YADE's archive, or a carried run's
state.npz) once per sweep count, solves the next step with exactly that many sweeps (tolerance
unreachable) and the solver's momentum on or off, and compares the contact forces of the last
two solves with ``yadecd.analysis.force_change``: total relative change, the share of it carried
by the contacts that change most (small shares: a drift spread over the pile; large ones: a few
culprits), and where those contacts are. Prints and writes the residual of every solve and the
comparison.
"""
import argparse
import json
import os
import sys
import tempfile
import time

from yade import O
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd (README: which yadecd)
from yadecd import pile, analysis as pa  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
ap.add_argument('run_dir')
ap.add_argument('--sweeps', default='20000,22000', help='sweep counts, comma-separated (at least two)')
ap.add_argument('--momentum', type=int, choices=(0, 1), default=1, help="the solver's momentum (ContactDynamicsIntegrator.momentum)")
ap.add_argument('--out', default=None, help='JSON output (default RUN_DIR/force_drift.json)')
a = ap.parse_args(sys.argv[1:])
try:
    counts = [int(float(x)) for x in a.sweeps.split(',') if x.strip()]
except ValueError:
    ap.error('--sweeps: comma-separated sweep counts, got %r' % a.sweeps)
if len(counts) < 2 or min(counts) < 1:
    ap.error('--sweeps needs at least two positive sweep counts, got %r' % a.sweeps)

solves, snaps = [], []
for n in counts:
    run = pile.PileRun.load(a.run_dir, log=lambda s: None)
    cd = O.engines[-1]
    cd.momentum, cd.tolerance, cd.maxIter, cd.warnUnconverged = bool(a.momentum), 1e-300, n, False
    t0 = time.time()
    O.step()
    solves.append(dict(sweeps=cd.iterations, residual=cd.residual, wall_s=time.time() - t0))
    print('%d sweeps: residual %.3e (%.0f s)' % (cd.iterations, cd.residual, solves[-1]['wall_s']), flush=True)
    path = os.path.join(tempfile.mkdtemp(), 'snap.npz')
    pile.snapshot(path, {}, run.p)
    snaps.append(pa.load_snapshot(path))
change = pa.force_change(snaps[-2], snaps[-1])
print('forces from %d to %d sweeps: %.3g relative in all; the 10 / 100 / 1000 / 5000 that change most carry %s of it; '
      'largest single share %.2g' % (counts[-2], counts[-1], change['rel_total'],
                                     ' / '.join('%.3f' % v for v in change['top_share'].values()), change['largest_share']))
print('where (quartiles, cm): the 1000 that change most at z %s, r %s; all contacts z %s, r %s'
      % tuple(', '.join('%.2f' % (100 * v) for v in change[k]) for k in ('worst_z_m', 'worst_r_m', 'all_z_m', 'all_r_m')))
out = a.out or os.path.join(a.run_dir, 'force_drift.json')
with open(out, 'w') as f:
    json.dump(dict(run_dir=a.run_dir, momentum=bool(a.momentum), solves=solves, change=change), f, indent=1)
print('saved', out)

"""Do small piles come to rest, with the plain and with the accelerated position correction?

    scripts/yade -j1 -n -x scripts/bench/rest_check.py [--seeds 3-10] [--grains 60] [--relax 0.6]
        [--work /tmp/rest_check] [--out docs/data/rest_60grain_correction_momentum.json]

For each seed, one pile by the paper's protocol (``yadecd.pile``) with ``correction_momentum``
False, then True; at the end of the relaxation its rest speed (``yadecd.analysis.rest_speed``: the
largest grain speed, grains standing alone on the floor wall counted by their vertical speed only,
since rolling on a flat wall is a neutral equilibrium), the largest speed of all, and how many
grains stand alone on the wall. Prints one JSON line per pile and writes the list to --out.
"""
import argparse
import glob
import json
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd (README: which yadecd)

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0]))))
import numpy as np  # noqa: E402
from yadecd import pile, analysis as pa  # noqa: E402
from yadecd.runs.ensemble import parse_seeds  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
ap.add_argument('--seeds', default='3-10')
ap.add_argument('--grains', type=int, default=60)
ap.add_argument('--relax', type=float, default=0.6, help='simulated seconds after the last grain [s]')
ap.add_argument('--work', default='/tmp/rest_check', help='directory for the runs (replaced)')
ap.add_argument('--out', default=os.path.join(REPO, 'docs', 'data', 'rest_60grain_correction_momentum.json'))
args = ap.parse_args()

rows = []
for seed in parse_seeds(args.seeds):
    for momentum in (False, True):
        run_dir = os.path.join(args.work, 's%d_%s' % (seed, 'momentum' if momentum else 'plain'))
        pile.run(run_dir, n_grains=args.grains, relax=args.relax, snap_every=1e9, seed=seed,
                 correction_momentum=momentum, log=lambda s: None, overwrite=True)
        snap = pa.load_snapshot(sorted(glob.glob(os.path.join(run_dir, 'snap_*.npz')))[-1])
        free = ~snap['fixed']
        row = dict(seed=seed, correction_momentum=momentum, time_s=snap['time'],
                   largest_speed=float(np.linalg.norm(snap['vel'][free], axis=1).max()),
                   rest_speed=pa.rest_speed(snap), alone_on_wall=int(pa.wall_only_grains(snap).sum()))
        print(json.dumps(row), flush=True)
        rows.append(row)
for momentum in (False, True):
    rest = [r['rest_speed'] for r in rows if r['correction_momentum'] == momentum]
    print('correction_momentum=%s: at rest (< 1e-9 m/s) in %d of %d piles; median rest speed %.2g m/s'
          % (momentum, sum(v < 1e-9 for v in rest), len(rest), float(np.median(rest))))
with open(args.out, 'w') as f:
    json.dump(rows, f, indent=1)

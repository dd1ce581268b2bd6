"""Tilt at which a single grain rolls off the pile's random paving, for the smallest, median and
largest grain of the protocol (yadecd.pile.rolloff).

    scripts/yade -n -x scripts/paving_rolloff.py [--per-size 20] [--out docs/data/paving_rolloff.json]

Prints, per diameter, the median release tilt and its quartiles (grains still held at the largest
tilt, 70°, count as released above it), and writes them as JSON.
"""
import argparse
import json
import sys

import numpy as np
import os
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

from yadecd.pile import rolloff  # noqa: E402

ap = argparse.ArgumentParser(prog='paving_rolloff.py')
ap.add_argument('--per-size', type=int, default=20)
ap.add_argument('--rate', type=float, default=10.0, help='tilt rate [deg/s]')
ap.add_argument('--seed', type=int, default=1)
ap.add_argument('--out', default='out/paving_rolloff.json')
a = ap.parse_args(sys.argv[1:])
diameters = [0.0025, 0.00375, 0.005]
res = rolloff.release_angles(diameters, per_size=a.per_size, rate=a.rate, seed=a.seed)
table = {}
def quantile(v, q):
    """Quantile with the grains still held counted as released above the largest tilt (inf)."""
    x = float(np.quantile(v, q))
    return None if not np.isfinite(x) else x


for d, angles in res.items():
    held = np.isnan(angles)
    v = np.where(held, np.inf, angles)
    table['%.5f' % d] = {'diameter_cm': d * 100, 'n': int(len(angles)), 'held_at_max_tilt': int(held.sum()),
                         'median_deg': quantile(v, 0.5), 'q25_deg': quantile(v, 0.25), 'q75_deg': quantile(v, 0.75),
                         'released_below_26deg': int((v < 26).sum()), 'min_deg': float(v.min()),
                         'angles_deg': angles.tolist()}
    show = lambda x: '> %g' % rolloff_max if x is None else '%.1f' % x
    rolloff_max = 70.0
    print('d = %.3f cm: release tilt median %s deg (quartiles %s-%s), %d of %d released below 26 deg, %d held at %g deg'
          % (d * 100, show(quantile(v, 0.5)), show(quantile(v, 0.25)), show(quantile(v, 0.75)),
             (v < 26).sum(), len(v), held.sum(), rolloff_max))
with open(a.out, 'w') as f:
    json.dump({'rate_deg_s': a.rate, 'seed': a.seed, 'per_size': a.per_size, 'sizes': table}, f, indent=1)
print('written: %s' % a.out)

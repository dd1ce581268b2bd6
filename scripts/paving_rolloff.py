"""Tilt at which a single grain rolls off the pile's random paving, for the smallest, median and
largest grain of the protocol (yadecd.rolloff).

    scripts/yade -n -x scripts/paving_rolloff.py [--per-size 20] [--out docs/data/paving_rolloff.json]

Prints, per diameter, the median release tilt and its spread (quartiles), and writes them as JSON.
"""
import argparse
import json
import sys

import numpy as np

from yadecd import rolloff

ap = argparse.ArgumentParser(prog='paving_rolloff.py')
ap.add_argument('--per-size', type=int, default=20)
ap.add_argument('--rate', type=float, default=10.0, help='tilt rate [deg/s]')
ap.add_argument('--seed', type=int, default=1)
ap.add_argument('--out', default='out/paving_rolloff.json')
a = ap.parse_args(sys.argv[1:])
diameters = [0.0025, 0.00375, 0.005]
res = rolloff.release_angles(diameters, per_size=a.per_size, rate=a.rate, seed=a.seed)
table = {}
for d, angles in res.items():
    held = np.isnan(angles)
    v = angles[~held]
    table['%.5f' % d] = {'diameter_cm': d * 100, 'n': int(len(angles)), 'held_at_max_tilt': int(held.sum()),
                         'median_deg': float(np.median(v)) if len(v) else None,
                         'q25_deg': float(np.quantile(v, 0.25)) if len(v) else None,
                         'q75_deg': float(np.quantile(v, 0.75)) if len(v) else None,
                         'min_deg': float(v.min()) if len(v) else None, 'angles_deg': angles.tolist()}
    print('d = %.3f cm: release tilt median %.1f deg (quartiles %.1f-%.1f, min %.1f), %d of %d held at the end'
          % (d * 100, np.median(v), np.quantile(v, 0.25), np.quantile(v, 0.75), v.min(), held.sum(), len(angles)))
with open(a.out, 'w') as f:
    json.dump({'rate_deg_s': a.rate, 'seed': a.seed, 'per_size': a.per_size, 'sizes': table}, f, indent=1)
print('written: %s' % a.out)

#!/usr/bin/env python3
"""How the pile estimators read constructed cases with known answers (py/yadecd/synthetic.py).

    python3 scripts/estimator_check.py [--out docs/data/estimator_check.md] [--seeds 3]

Slope: cones of 20-30°, 2.5-6 cm high, with each awkward feature of real piles (rounded cap,
sparse axis, a foot of single grains, stray grains) and all of them together, read by the flank
estimator (mean ± spread over seeds, and its own bootstrap error) and by the former least-squares
estimator. Dip: constructed floors with a known D, single piles and ensembles of 8, coverage of
the 95 % intervals and the rate of false dips. Writes a markdown table. numpy only.
"""
import argparse
import math
import os
import sys

import numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

from yadecd import analysis as pa  # noqa: E402
from yadecd.testing import synthetic as sy  # noqa: E402

FEATURES = [('plain cone', {}), ('rounded cap (1 cm)', dict(cap_radius=0.01)), ('sparse axis', dict(sparse_axis=True)),
            ('foot (3 cm)', dict(foot=True)), ('12 stray grains', dict(strays=12)),
            ('all four', dict(cap_radius=0.01, sparse_axis=True, foot=True, strays=12))]


def slope_rows(seeds):
    """Table rows of the flank-slope estimators on constructed cones, ``seeds`` cones per case:
    each feature alone, then all four at several slopes and heights."""
    rows = []
    cases = [(26.0, 0.03, f) for f in FEATURES] + [(s, h, FEATURES[-1]) for s, h in
                                                   ((20.0, 0.025), (30.0, 0.025), (20.0, 0.06), (30.0, 0.055), (26.0, 0.06))]
    for slope, H, (name, feat) in cases:
        new, err, old, chord = [], [], [], []
        for seed in range(seeds):
            snap, _ = sy.constructed_pile(slope, H, seed=seed, **feat)
            p = pa.profile_and_slope(snap)
            new.append(p['slope_deg'])
            err.append(p['slope_err_deg'])
            old.append(p['slope_ls_window_deg'])
            chord.append(p['chord_angle_deg'])
        rows.append('| %g° | %.1f | %s | %.2f ± %.2f (bootstrap error %.2f) | %.1f | %.1f |'
                    % (slope, H * 100, name, np.mean(new), np.std(new), np.mean(err), np.mean(chord), np.mean(old)))
    return rows


def dip_rows(n_single=200, n_ens=200):
    """Table rows of the central-dip estimator on constructed floors: single piles and ensembles
    of 8 (mean, spread, interval coverage, how often a dip is declared)."""
    rows = []
    r0, r1 = 0.0075, 0.015
    for dip, flat in ((0.0, True), (0.3, False), (0.4, True)):
        D = sy.dip_value(dip, math.inf if flat else 0.06, r0, r1)
        singles = [pa.central_dip(sy.constructed_floor(dip=dip, flat=flat, seed=s)[0]) for s in range(n_single)]
        est = np.array([r['D'] for r in singles])
        cover = np.mean([r['ci95'][0] <= D <= r['ci95'][1] for r in singles])
        ens = []
        for e in range(n_ens):
            rs = [pa.central_dip(sy.constructed_floor(dip=dip, flat=flat, seed=100000 + 100 * e + k)[0]) for k in range(8)]
            ens.append(pa.jackknife_ratio_dip([r['p_disc_Pa'] for r in rs], [r['p_ring_Pa'] for r in rs]))
        ens_D = np.array([r['D'] for r in ens])
        rows.append('| %s, dip %.1f | %.3f | %.3f ± %.3f | %.0f %% | %.3f ± %.3f | %.0f %% | %.0f %% |'
                    % ('flat' if flat else 'linear', dip, D, est.mean(), est.std(), 100 * cover, ens_D.mean(), ens_D.std(),
                       100 * np.mean([r['ci95'][0] <= D <= r['ci95'][1] for r in ens]),
                       100 * np.mean([r['confidence_positive'] > 0.95 for r in ens])))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--out', default=None)
    ap.add_argument('--seeds', type=int, default=3)
    a = ap.parse_args()
    if a.seeds < 2:
        ap.error('--seeds must be at least 2 (the tables give spreads over seeds; got %d)' % a.seeds)
    lines = ['Flank slope on constructed cones (%d seeds each; grains of the protocol, d = 0.375 cm)' % a.seeds, '',
             '| true slope | H [cm] | features | flank estimator [°] | chord angle [°] | former estimator [°] |',
             '| --- | --- | --- | --- | --- | --- |'] + slope_rows(a.seeds)
    lines += ['', 'Central dip D = 1 - p(r < 2d)/p(2d..4d) on constructed floors (exponential contact loads, about 14 '
              'contacts in the disc); single piles (200) and ensembles of 8 piles (200)', '',
              '| floor | true D | single pile: mean ± spread | single: 95 % interval covers | ensemble of 8: mean ± spread '
              '| ensemble: interval covers | ensemble: dip declared (> 95 %) |',
              '| --- | --- | --- | --- | --- | --- | --- |'] + dip_rows()
    text = '\n'.join(lines) + '\n'
    print(text)
    if a.out:
        with open(a.out, 'w') as f:
            f.write(text)
        print('written: %s' % a.out)


if __name__ == '__main__':
    main()

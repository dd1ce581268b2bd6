"""Figures of docs/performance.md from the benchmark CSVs (numpy + matplotlib, no YADE):

    python3 scripts/bench/plot_performance.py [--bench docs/data/solver_bench.csv ...]
        [--progress RUN/progress.csv] [--out docs/figures]

- perf_sweep.png: ns per contact per sweep against contacts, per method (CD fast path, general
  path, coloured with 1 and 2 threads, Siconos NSGS);
- perf_pile_cost.png: a pile run's wall time per step, sweeps per step and per-contact-sweep
  cost against its number of contacts (from the run's progress.csv: consecutive lines give
  wall time and simulated time elapsed), with the extrapolation to the paper's 33 000 contacts.
"""
import argparse
import csv
import os

import numpy as np
import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ap = argparse.ArgumentParser()
ap.add_argument('--bench', nargs='*', default=[os.path.join(REPO, 'docs', 'data', 'solver_bench.csv'),
                                              os.path.join(REPO, 'docs', 'data', 'solver_bench_2threads.csv')])
ap.add_argument('--progress', default=os.path.join(REPO, 'docs', 'data', 'pile2000_progress.csv'))
ap.add_argument('--dt', type=float, default=2e-4, help='time step of the pile run [s]')
ap.add_argument('--out', default=os.path.join(REPO, 'docs', 'figures'))
a = ap.parse_args()
os.makedirs(a.out, exist_ok=True)

# --- ns per contact-sweep
series = {}
for path in a.bench:
    if not os.path.exists(path):
        print('skipped (missing):', path)
        continue
    with open(path) as f:
        for row in csv.DictReader(f):
            if row['kind'] != 'sweep':
                continue
            name = row['method'] + ('' if row['method'] == 'Siconos NSGS' else ', %s thread%s' % (row['threads'], 's' if row['threads'] != '1' else ''))
            if row['method'] != 'CD coloured' and row['threads'] != '1':
                continue  # only the coloured sweep uses threads
            series.setdefault(name, []).append((int(row['contacts']), float(row['value'])))
if series:
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for name, pts in sorted(series.items()):
        pts.sort()
        ax.loglog([p[0] for p in pts], [p[1] for p in pts], 'o-', label=name)
    ax.axhline(30, color='k', ls=':', lw=0.8)
    ax.text(ax.get_xlim()[0] * 1.1, 32, 'target 30 ns', fontsize=8)
    ax.set_xlabel('contacts')
    ax.set_ylabel('ns per contact per Gauss–Seidel sweep')
    ax.set_title('Cost of one contact update (FCC blocks)')
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, 'perf_sweep.png'), dpi=120)
    print('wrote perf_sweep.png')

# --- pile cost against contacts
if os.path.exists(a.progress):
    d = np.genfromtxt(a.progress, delimiter=',', names=True)
    t, c, sw, wall = d['time_s'], d['contacts'], d['sweeps'], d['wall_s']
    keep = np.diff(t) > 0
    steps = np.diff(t)[keep] / a.dt
    per_step = np.diff(wall)[keep] / steps  # s per step between consecutive progress lines
    cm = 0.5 * (c[1:] + c[:-1])[keep]
    swm = 0.5 * (sw[1:] + sw[:-1])[keep]
    ns = per_step / (cm * np.maximum(swm, 1)) * 1e9  # rough: the sweeps printed are one step's
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.5))
    a1.plot(cm, per_step * 1e3, '.', ms=4, label='measured (pile run)')
    # cost = contacts × sweeps × (ns per contact-sweep). How sweeps grow with the pile is the
    # uncertain part: constant (cost ∝ c), like the height (∝ c^(4/3), c ∝ N ∝ H³), or like the
    # contacts (∝ c²). One-parameter fits through the origin; the middle one is drawn.
    models = {p: float(np.sum(per_step * cm ** p) / np.sum(cm ** (2 * p))) for p in (1.0, 4 / 3, 2.0)}
    cost = lambda p, cc: models[p] * np.asarray(cc, float) ** p
    x = np.linspace(0, 33000, 200)
    a1.plot(x, cost(4 / 3, x) * 1e3, 'r--', lw=1, label='fit a·c^(4/3), extrapolated')
    a1.plot(x, cost(1.0, x) * 1e3, 'r:', lw=0.8, label='fits a·c and a·c²')
    a1.plot(x, cost(2.0, x) * 1e3, 'r:', lw=0.8)
    a1.set_ylim(0, 1.2 * cost(4 / 3, 33000) * 1e3)
    a1.axvline(33000, color='k', ls=':', lw=0.8)
    a1.axhline(50, color='g', ls=':', lw=0.8)
    a1.set_xlabel('contacts')
    a1.set_ylabel('wall time per step [ms]')
    a1.set_title('Pile: step cost (tolerance 1e-3), 1 thread')
    a1.legend(fontsize=8)
    a2.plot(cm, swm, '.', ms=4)
    a2.set_xlabel('contacts')
    a2.set_ylabel('Gauss–Seidel sweeps per step (sampled)')
    a2.set_title('Pile: sweeps to tolerance 1e-3')
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, 'perf_pile_cost.png'), dpi=120)
    print('wrote perf_pile_cost.png; ms/step at 33 000 contacts: %s' % ', '.join('c^%.2f: %.0f' % (p, cost(p, 33000) * 1e3) for p in models))
    # The paper's full run, extrapolated (labelled so): contacts grow in proportion to grains
    # (fitted on this run), 1/(rate·dt) = 25 steps per grain, 14 000 grains, cost from the fit.
    g = d['grains']
    k = float(np.sum(c * g) / np.sum(g * g))
    n = np.arange(1, 14001)
    hours = {p: 25 * cost(p, k * n).sum() / 3600 for p in models}
    print('contacts per grain %.2f; extrapolated full 14 000-grain deposition (%d steps): %s' % (
        k, 25 * 14000, ', '.join('c^%.2f: %.0f h' % (p, h) for p, h in hours.items())))

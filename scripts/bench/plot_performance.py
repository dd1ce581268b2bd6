"""Figures of docs/performance.md from the benchmark CSVs (numpy + matplotlib, no YADE):

    python3 scripts/bench/plot_performance.py [--bench docs/data/solver_bench.csv ...]
        [--progress RUN/progress.csv] [--out docs/figures]

- perf_sweep.png: ns per contact per sweep against contacts, per method (CD fast path, general
  path, coloured with 1 and 2 threads, Siconos NSGS);
- perf_pile_cost.png: a pile step's cost against its number of contacts, per solver variant:
  the model overhead × ns × contacts × sweeps(contacts), with ns and the overhead (step over
  solve) from the pile benchmark and sweeps fitted to that variant's run (progress.csv),
  extrapolated to the paper's 33 000 contacts and to the full run; with the steps measured on
  large fed pile states (cone_pile.py + solver_bench.py --snapshot --feed) drawn over it.
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
ap.add_argument('--run', nargs='*', metavar='LABEL,PROGRESS_CSV,NS,STEP_OVER_SOLVE',
                # ns and step/solve: docs/data/solver_bench_pile.csv, mean of the t = 8 s and 10 s states
                default=['plain Gauss–Seidel,%s,24.8,1.20' % os.path.join(REPO, 'docs', 'data', 'pile2000_progress.csv'),
                         'momentum (default),%s,41.6,1.47' % os.path.join(REPO, 'docs', 'data', 'pile2000m_progress.csv')],
                help='a pile run per solver variant: label, its progress.csv, ns per contact-sweep of its solve and '
                     'step time over solve time (both from solver_bench.py --snapshot)')
ap.add_argument('--states', nargs='*', default=[os.path.join(REPO, 'docs', 'data', 'solver_bench_cones.csv'),
                                               os.path.join(REPO, 'docs', 'data', 'solver_bench_cones_2threads.csv')],
                help='solver_bench.py --snapshot CSVs of large pile states (cone_pile.py): measured steps drawn over the model')
ap.add_argument('--dt', type=float, default=2e-4, help='time step of the pile runs [s]')
ap.add_argument('--out', default=os.path.join(REPO, 'docs', 'figures'))
a = ap.parse_args()
os.makedirs(a.out, exist_ok=True)



def decorate(ax, xlabel, ylabel, title, fontsize=8):
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=fontsize)


def save(fig, name):
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, name), dpi=120)
    print('wrote', name)


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
    decorate(ax, 'contacts', 'ns per contact per Gauss–Seidel sweep', 'Cost of one contact update (FCC blocks)')
    save(fig, 'perf_sweep.png')

# --- pile cost against contacts
# Model (each factor measured): step = overhead × ns_per_contact_sweep × contacts × sweeps(contacts),
# ns and the overhead (step over solve) from the quiet pile benchmark, sweeps(contacts) a power
# law fitted to the run's sampled sweeps. The run's own wall times (shared machine, pauses for
# benchmarks) are drawn for comparison.
def fit_run(path, ns, step_over_solve):
    """Per-step wall times of a run, and the fitted model: sweeps = A·contacts^β on the
    deposition (relaxation steps are cheaper), step = step_over_solve·ns·contacts·sweeps."""
    d = np.genfromtxt(path, delimiter=',', names=True)
    t, c, sw, wall, g = d['time_s'], d['contacts'], d['sweeps'], d['wall_s'], d['grains']
    keep = np.diff(t) > 0
    per_step = np.diff(wall)[keep] / (np.diff(t)[keep] / a.dt)
    cm = 0.5 * (c[1:] + c[:-1])[keep]
    ok = (c > 1000) & (sw > 0) & (g < g.max())
    beta, log_a = np.polyfit(np.log(c[ok]), np.log(sw[ok]), 1)
    sweeps = lambda cc: np.exp(log_a) * np.asarray(cc, float) ** beta
    step = lambda cc: step_over_solve * ns * 1e-9 * np.asarray(cc, float) * sweeps(cc)
    k = float(np.sum(c * g) / np.sum(g * g))  # contacts per grain
    return dict(cm=cm, per_step=per_step, c=c[ok], sw=sw[ok], beta=beta, sweeps=sweeps, step=step, k=k)


runs = []
for spec in a.run:
    label, path, ns, sos = spec.rsplit(',', 3)
    if not os.path.exists(path):
        print('skipped (missing):', path)
        continue
    runs.append((label, float(ns), fit_run(path, float(ns), float(sos))))
if runs:
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.5))
    x = np.linspace(500, 42000, 200)
    for (label, ns, f), colour in zip(runs, ('r', 'b', 'g', 'm')):
        a1.plot(f['cm'], f['per_step'] * 1e3, '.', ms=2, color=colour, alpha=0.3)
        a1.plot(x, f['step'](x) * 1e3, '-', color=colour, label='%s: model (dots: the run, shared machine)' % label)
        a2.loglog(f['c'], f['sw'], '.', ms=3, color=colour, alpha=0.4)
        a2.loglog(x, f['sweeps'](x), '-', color=colour, label='%s: sweeps ∝ contacts^%.2f' % (label, f['beta']))
        # The paper's full run, extrapolated (labelled so): contacts in proportion to grains,
        # 1/(rate·dt) = 25 steps per grain, 14 000 grains, then no relaxation.
        n = np.arange(1, 14001)
        hours = 25 * f['step'](f['k'] * n).sum() / 3600
        print('%s: sweeps ~ contacts^%.2f; model step at 33 000 contacts: %.2f s; contacts per grain %.2f; '
              'extrapolated full 14 000-grain deposition (350 000 steps): %.0f h' % (label, f['beta'], f['step'](33000), f['k'], hours))
    marks = {('CD', '1'): ('bs', 'measured, default (momentum, slabs), 1 thread'), ('CD plain GS', '1'): ('r^', 'measured, plain GS, 1 thread'),
             ('CD', '2'): ('gD', 'measured, default, 2 threads')}
    for path in a.states:
        if not os.path.exists(path):
            print('skipped (missing):', path)
            continue
        with open(path) as f:
            rows = [r for r in csv.DictReader(f) if r['kind'] == 'stage' and r['quantity'] == 'step']
        for (method, threads), (style, label) in marks.items():
            sel = [r for r in rows if r['method'] == method and r['threads'] == threads]
            if sel:
                cc = [float(r['contacts']) for r in sel]
                a1.plot(cc, [float(r['value']) for r in sel], style, ms=6, mfc='none', label=label + ' (fed cone states)')
                a2.loglog(cc, [float(r['sweeps']) for r in sel], style, ms=6, mfc='none', label=label)
    a1.axvline(33000, color='k', ls=':', lw=0.8)
    a1.axhline(50, color='g', ls=':', lw=0.8)
    a1.set_yscale('log')
    decorate(a1, 'contacts', 'wall time per step [ms]', 'Pile step cost, 1 thread, tolerance 1e-3 (target 50 ms at 33 000)', 7)
    decorate(a2, 'contacts', 'sweeps per step', 'Sweeps to tolerance 1e-3 (sampled deposition steps)', 7)
    save(fig, 'perf_pile_cost.png')

"""Where a step's sweeps go: the residual of each saved step against the sweep, and the sweeps
each tolerance would have taken (the first sweep at or below it).

    /usr/bin/python3 scripts/bench/residual_tail.py STEP.cdp [...] [--thresholds 1e-2,3e-3,2e-3,1e-3]
        [--label TEXT] [--out DIR]

Each step is solved once more by build/cd_core_bench --history (the residual evaluated at every
sweep, the run's own options otherwise; sweep counts do not depend on the machine). Writes
DIR/residual_tail.csv (one row per step: contacts, sweeps to each threshold) and
DIR/residual_tail.png (the histories), and prints the table.
"""
import argparse
import csv
import os
import subprocess
import sys
import tempfile
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd (README: which yadecd)

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from yadecd.analysis.stats import sweeps_to  # noqa: E402
from yadecd.io import write_csv  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
ap.add_argument('steps', nargs='+', help='problem files (save_step.py)')
ap.add_argument('--thresholds', default='1e-2,3e-3,2e-3,1e-3')
ap.add_argument('--label', default='', help='what the steps are, for the figure title')
ap.add_argument('--out', default='/tmp/residual_tail')
ap.add_argument('--bench', default=os.path.join(REPO, 'build', 'cd_core_bench'))
a = ap.parse_args()
thresholds = [float(x) for x in a.thresholds.split(',')]
if not os.access(a.bench, os.X_OK):
    ap.error('no %s: build the plugin first (scripts/setup.sh)' % a.bench)

rows, histories = [], []
with tempfile.TemporaryDirectory() as tmp:
    for path in a.steps:
        hist, summary = os.path.join(tmp, 'h.csv'), os.path.join(tmp, 's.csv')
        subprocess.run([a.bench, path, '--time-sweeps', '0', '--history', hist, '--csv', summary], check=True,
                       capture_output=True, env=dict(os.environ, OMP_NUM_THREADS='1'))
        with open(summary) as f:
            contacts = int(next(csv.DictReader(f))['contacts'])
        os.remove(summary)                      # the bench appends to an existing file
        with open(hist) as f:
            h = [float(r['residual']) for r in csv.DictReader(f)]
        histories.append((os.path.basename(path), h))
        row = {'step': os.path.basename(path), 'contacts': contacts}
        for th, n in zip(thresholds, sweeps_to(h, thresholds)):
            row['sweeps_to_%g' % th] = '' if n is None else n
        rows.append(row)

keys = list(rows[0])
print(' '.join('%16s' % k for k in keys))
for r in rows:
    print(' '.join('%16s' % r[k] for k in keys))
write_csv(os.path.join(a.out, 'residual_tail.csv'), rows)

import matplotlib  # noqa: E402
matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
fig, ax = plt.subplots(figsize=(7, 4.2))
for name, h in histories:
    ax.semilogy(range(1, len(h) + 1), h, lw=1, label=name)
for th in thresholds:
    ax.axhline(th, color='0.6', lw=0.6, ls='--')
ax.set_xlabel('sweep')
ax.set_ylabel('relative residual (natural map) [-]')
ax.set_title('residual per sweep' + (': ' + a.label if a.label else ''), fontsize=10)
ax.legend(fontsize=7)
fig.tight_layout()
png = os.path.join(a.out, 'residual_tail.png')
fig.savefig(png, dpi=110)
print('wrote %s' % png)

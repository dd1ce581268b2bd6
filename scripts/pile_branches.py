"""One pile under two protocols: a run against its branch (scripts/pile.py --branch-from), or
against another run of the same pile (same grains, seed and feed) from the start under other
settings, such as the paper's h = 2e-4 s against h = 1e-3 s. The observables of both at the
snapshot times they share (after the branch point for a branch), and their differences in units
of the spread between seeds of an ensemble (yadecd.analysis.protocols.compare_runs).

    /usr/bin/python3 scripts/pile_branches.py RUN OTHER [--summary docs/data/ensemble_summary.json]
        [--group 2000] [--times 25,26] [--out DIR]

--group names the ensemble size whose seed spreads scale the differences (the feed-end group for
snapshots at or before the end of the feed, the relaxed group after it). Writes DIR/branches.md
and DIR/branches.json and prints the table. numpy and matplotlib only (no YADE).
"""
import argparse
import json
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
from yadecd.analysis import protocols as protocol  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
ap.add_argument('run')
ap.add_argument('branch')
ap.add_argument('--summary', default=os.path.join(REPO, 'docs', 'data', 'ensemble_summary.json'))
ap.add_argument('--group', default='2000', help='ensemble size whose seed spreads scale the differences')
ap.add_argument('--times', default=None, help='snapshot times [s] to compare (default: all shared after the branch point)')
ap.add_argument('--out', default=None, help='output directory (default BRANCH/branches)')
a = ap.parse_args()
for d in (a.run, a.branch):
    if not os.path.exists(os.path.join(d, 'run.json')):
        ap.error('%s holds no pile run (no run.json)' % d)
if not os.path.isfile(a.summary):
    ap.error('--summary %s does not exist (the ensembles\' ensemble_summary.json)' % a.summary)
times = None
if a.times:
    try:
        times = [float(x) for x in a.times.split(',')]
    except ValueError:
        ap.error('--times must be comma-separated times in seconds (got %r)' % a.times)
with open(a.summary) as f:
    summary = json.load(f)
try:
    res = protocol.compare_runs(a.run, a.branch, summary, a.group, times, log=lambda s: print(s, flush=True))
except (ValueError, KeyError) as e:
    ap.error(str(e).strip("'\""))
print(res['text'])
out = a.out or os.path.join(a.branch, 'branches')
os.makedirs(out, exist_ok=True)
with open(os.path.join(out, 'branches.md'), 'w') as f:
    f.write(res['text'])
with open(os.path.join(out, 'branches.json'), 'w') as f:
    json.dump({'run': a.run, 'branch': a.branch, 'is_branch': res['branch'], 'branch_time_s': res['start_s'],
               'changes': res['changes'], 'epochs': res['epochs']}, f, indent=1)
print('wrote %s' % out)

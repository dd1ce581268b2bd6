"""A pile run against its branch (scripts/pile.py --branch-from): the observables of both at the
snapshot times they share after the branch point, and their differences in units of the spread
between seeds of an ensemble.

    /usr/bin/python3 scripts/pile_branches.py RUN BRANCH [--summary docs/data/ensemble_summary.json]
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
from yadecd import analysis as pa  # noqa: E402
from yadecd.analysis import protocols as protocol  # noqa: E402
from yadecd.pile.protocol import feed_time  # noqa: E402
from yadecd.analysis.ensemble import run_record  # noqa: E402

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
with open(os.path.join(a.branch, 'run.json')) as f:
    bp = json.load(f)
if not bp.get('branches'):
    ap.error('%s is not a branch (its run.json lists no branches)' % a.branch)
t_branch = bp['branches'][-1]['time']
changes = bp['branches'][-1]['changes']
if not os.path.isfile(a.summary):
    ap.error('--summary %s does not exist (the ensembles\' ensemble_summary.json)' % a.summary)
with open(a.summary) as f:
    summary = json.load(f)
snaps_a = {round(t, 3): p for t, p in pa.list_snapshots(a.run)}
snaps_b = {round(t, 3): p for t, p in pa.list_snapshots(a.branch)}
shared = sorted(t for t in set(snaps_a) & set(snaps_b) if t > t_branch + 1e-9)
if a.times:
    try:
        wanted = [round(float(x), 3) for x in a.times.split(',')]
    except ValueError:
        ap.error('--times must be comma-separated times in seconds (got %r)' % a.times)
    missing = [t for t in wanted if t not in shared]
    if missing:
        ap.error('no snapshot at %s in both runs after the branch point (shared: %s)' % (missing, shared))
    shared = wanted
if not shared:
    ap.error('the two runs share no snapshot after the branch point t = %.3f s' % t_branch)
t_feed = feed_time(int(bp['n_grains']), bp.get('rate'), bp.get('dt'))
params = pa.run_parameters(a.branch)
rows, records = [], []
for t in shared:
    group = '%s_%s' % (a.group, 'feed' if t <= t_feed + 1e-6 else 'relaxed')
    ra, rb = run_record(snaps_a[t], params), run_record(snaps_b[t], params)
    res = protocol.paired(ra, rb, protocol.ensemble_spreads(summary, group))
    label = 't = %g s%s' % (t, ' (end of feed)' if abs(t - t_feed) < 1e-6 else '')
    rows.append((label, res))
    records.append({'time_s': t, 'spread_group': group, 'result': res})
    print('compared t = %g s (spreads of %s)' % (t, group), flush=True)
text = ('Branch %s of %s at t = %.3f s (%s); differences in seed spreads of the %s-grain ensemble.\n\n'
        % (a.branch, a.run, t_branch, ', '.join('%s %s -> %s' % (k, v[0], v[1]) for k, v in changes.items()), a.group)
        + protocol.paired_markdown(rows, '%s grains' % a.group))
print(text)
out = a.out or os.path.join(a.branch, 'branches')
os.makedirs(out, exist_ok=True)
with open(os.path.join(out, 'branches.md'), 'w') as f:
    f.write(text)
with open(os.path.join(out, 'branches.json'), 'w') as f:
    json.dump({'run': a.run, 'branch': a.branch, 'branch_time_s': t_branch, 'changes': changes, 'epochs': records}, f, indent=1)
print('wrote %s' % out)

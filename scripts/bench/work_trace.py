"""Where the sweeps of saved steps work: the table and figures of docs/performance.md from traces.

    build/cd_core_bench STEP.cdp --time-sweeps 0 --trace /tmp/trace/NAME     # for each step
    /usr/bin/python3 scripts/bench/work_trace.py /tmp/trace/NAME [...] [--out-md docs/data/work_trace.md]
        [--figures docs/figures]

Per trace: the shares of contacts whose update and whose residual exceed θ₀ = tol·‖q‖/√n and
10 θ₀ after 1, 5, 10, 20, 50, 100, 150 sweeps and at the last, and the share of each sweep's work
carried by the top 1 % and 10 % of contacts (yadecd.analysis.worktrace); a figure per trace.
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd
from yadecd.analysis import worktrace  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(prog='work_trace.py', description=__doc__.split('\n')[0])
    ap.add_argument('prefixes', nargs='+')
    ap.add_argument('--out-md', default=None)
    ap.add_argument('--figures', default=None, help='directory for work_trace_<name>.png')
    args = ap.parse_args(argv)
    lines = []
    for prefix in args.prefixes:
        tr = worktrace.load(prefix)
        name = os.path.basename(prefix)
        m = tr['meta']
        lines.append('### %s: %d contacts, %d sweeps to tolerance %g (θ₀ = %.3g m/s)\n'
                     % (name, m['contacts'], m['sweeps'], m['tolerance'], worktrace.threshold(m)))
        rows = worktrace.summary(tr)
        keys = [k for k in rows[0] if k != 'sweep']
        lines.append('| sweep | ' + ' | '.join(keys) + ' |')
        lines.append('| --- ' * (len(keys) + 1) + '|')
        for r in rows:
            lines.append('| %d | ' % r['sweep'] + ' | '.join('%.3f' % r[k] for k in keys) + ' |')
        lines.append('')
        if args.figures:
            os.makedirs(args.figures, exist_ok=True)
            path = worktrace.figure(tr, os.path.join(args.figures, 'work_trace_%s.png' % name),
                                    title='%s: where one fed step\'s sweeps work (%d contacts, %d sweeps, momentum, slabs)'
                                    % (name, m['contacts'], m['sweeps']))
            print('work_trace.py: figure %s' % path)
    text = '\n'.join(lines)
    print(text)
    if args.out_md:
        with open(args.out_md, 'w') as f:
            f.write('# Where a fed step\'s sweeps work\n\nWritten by `scripts/bench/work_trace.py` from '
                    '`cd_core_bench --trace` (docs/performance.md, "Where a fed step\'s work is"). Shares of '
                    'contacts (0–1); θ₀ = tolerance·‖q‖/√n; topX%: share of the sweep\'s Σ(update²) carried by '
                    'the X % largest updates.\n\n' + text + '\n')
        print('work_trace.py: table %s' % args.out_md)


if __name__ == '__main__':
    main()

#!/usr/bin/env python3
"""The central dip while a pile grows: every fed snapshot of long runs measured as the ensembles
measure a pile, against the grains it holds, beside the ensembles' piles at the end of their feed
(module yadecd.analysis.growth; docs/pile.md, "The full pile").

    /usr/bin/python3 scripts/pile_growth.py RUN [RUN ...] --out DIR [--records docs/data/ensemble_runs] [--docs docs]

Writes DIR/growth.md (one row per snapshot, then the mean over runs of distinct seeds at the times
they share, then the ensembles' reference) and DIR/growth_dip.png;
each snapshot's record is kept in DIR/records/ and read back on the next call while the snapshot
is unchanged. With --docs, growth.md and growth_dip.png are then copied to their places in that
docs tree (yadecd.analysis.publish). numpy only (no YADE needed): carried runs in runs/ are read as they are.
"""
import argparse
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('runs', nargs='+', help='run directories (holding run.json and snap_<t>.npz)')
    p.add_argument('--out', required=True, help='output directory')
    p.add_argument('--records', action='append', default=[],
                   help='directory of stored ensemble records (the reference at the end of the feed)')
    p.add_argument('--docs', default=None, metavar='DOCS',
                   help="then copy the table and the figure to their places in a docs tree (this checkout's: docs)")
    args = p.parse_args(argv)
    for run in args.runs:
        if not os.path.exists(os.path.join(run, 'run.json')):
            p.error('%s is not a pile run directory (no run.json)' % run)
    for d in args.records:
        if not os.path.isdir(d):
            p.error('--records %s is not a directory' % d)
    from yadecd.analysis import growth
    from yadecd.analysis.publish import check_docs_root, publish
    if args.docs:
        try:
            check_docs_root(args.docs)
        except ValueError as e:
            p.error(str(e))
    from yadecd.analysis.ensemble import stored_records
    os.makedirs(args.out, exist_ok=True)
    curves = {os.path.basename(os.path.normpath(r)): growth.growth_records(r, os.path.join(args.out, 'records'),
                                                                          log=lambda m: print(m, flush=True))
              for r in args.runs}
    reference = growth.fed_reference(stored_records(args.records, set())) if args.records else {}
    pooled = growth.over_runs(curves)
    table = growth.growth_table_markdown(curves, reference, pooled)
    with open(os.path.join(args.out, 'growth.md'), 'w') as f:
        f.write(table)
    growth.fig_growth(curves, reference, os.path.join(args.out, 'growth_dip.png'), pooled)
    print(table)
    print('written: %s, %s' % (os.path.join(args.out, 'growth.md'), os.path.join(args.out, 'growth_dip.png')))
    if args.docs:
        publish(args.out, args.docs, log=lambda m: print(m, flush=True))
    return 0 if any(curves.values()) else 1


if __name__ == '__main__':
    sys.exit(main())

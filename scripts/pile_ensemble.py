#!/usr/bin/env python3
"""Ensembles of Moreau sand piles: run them, watch them, analyse them.

    python3 scripts/pile_ensemble.py run OUT --sizes 300,1000,2000 --seeds 1-8 [--relax 1] [--jobs 2 | --scheduler tcp://HOST:8786] [-- PILE OPTIONS]
    python3 scripts/pile_ensemble.py status OUT
    python3 scripts/pile_ensemble.py analyse OUT [--out DIR]
    python3 scripts/pile_ensemble.py carry OUT DEST [--every MIN] [--snap-every S]

``run`` runs each pile as a task of Dask's distributed engine, one YADE process per pile
(``scripts/pile.py``, one thread each): on a local cluster of ``--jobs`` workers, or on the
workers of the Dask scheduler given by ``--scheduler`` (several machines sharing the directories);
snapshots at half the feed, at the end of the feed and after ``--relax`` seconds of
relaxation. Calling it again resumes: finished runs are skipped, interrupted ones continue from
their checkpoints, failed ones are reported (``--retry-failed`` tries them again). ``analyse``
runs the pile analysis on every snapshot of every finished run and writes per-run summaries,
the ensemble statistics (means, spreads, 95 % intervals) and figures. ``carry`` copies every
run's portable part (``scripts/pile_carry.py``) to ``DEST/<run>``, beside running piles, and with
``--every`` again every MIN minutes until every run is done and carried: an ensemble then
outlives its machine (carry into a checkout's ``runs/``). Needs no YADE for ``status``,
``analyse`` and ``carry``; all work with Debian's /usr/bin/python3.
"""
import argparse
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    extra = []
    if '--' in argv:
        k = argv.index('--')
        argv, extra = argv[:k], argv[k + 1:]
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    sub = p.add_subparsers(dest='cmd', required=True)
    r = sub.add_parser('run', help='run (or resume) the ensemble')
    r.add_argument('out')
    r.add_argument('--sizes', default='2000', help='grain counts, comma-separated')
    r.add_argument('--seeds', default='1-8', help="seeds: '1-8' or '1,2,5'")
    r.add_argument('--relax', type=float, default=1.0, help='relaxation after the feed [s]')
    r.add_argument('--jobs', type=int, default=2, help='runs at a time on the local cluster (one single-threaded worker each)')
    r.add_argument('--scheduler', default=None, metavar='ADDRESS',
                   help='a Dask scheduler (tcp://host:8786) whose workers run the piles instead of a local cluster; '
                        'they must see OUT and this checkout at the same paths')
    r.add_argument('--order', choices=('small-first', 'large-first'), default='small-first')
    r.add_argument('--retry-failed', action='store_true')
    s = sub.add_parser('status', help='one line per run')
    s.add_argument('out')
    a = sub.add_parser('analyse', help='per-run summaries, ensemble statistics and figures')
    a.add_argument('out')
    a.add_argument('--figures', default=None, help='output directory (default OUT/analysis)')
    a.add_argument('--n-boot', type=int, default=2000, help='bootstrap resamples')
    a.add_argument('--records', action='append', default=[],
                   help='directory of stored per-run records (e.g. docs/data/ensemble_runs) for runs not in OUT')
    a.add_argument('--docs', default=None, metavar='DOCS',
                   help="then copy the tables and figures to their places in a docs tree (this checkout's: docs; "
                        'yadecd.analysis.publish)')
    c = sub.add_parser('carry', help="copy every run's portable part to DEST/<run> (pile_carry.py), beside running piles")
    c.add_argument('out')
    c.add_argument('dest')
    c.add_argument('--every', type=float, default=None, metavar='MIN',
                   help='carry again every MIN minutes until every run is done and carried')
    c.add_argument('--snap-every', type=float, default=None, metavar='S',
                   help='carry only the snapshots at multiples of S seconds (and the newest, and the end of the feed)')
    args = p.parse_args(argv)

    from yadecd.runs import ensemble as ens
    if args.cmd in ('status', 'analyse', 'carry') and not os.path.isdir(args.out):
        p.error('%s is not a directory: give an ensemble made by `run`%s' % (
            args.out, ', or an empty directory with --records' if args.cmd == 'analyse' else ''))
    if args.cmd == 'run':
        try:
            sizes = [int(x) for x in args.sizes.split(',') if x.strip()]
            seeds = ens.parse_seeds(args.seeds)
        except ValueError as e:
            p.error(str(e))
        if not sizes or min(sizes) < 1:
            p.error('--sizes must be positive grain counts')
        if args.relax < 0 or args.jobs < 1:
            p.error('--relax must be >= 0 and --jobs >= 1')
        e = ens.Ensemble(args.out)
        try:
            e.plan(sizes, seeds, args.relax, extra)
        except ValueError as err:
            p.error(str(err))
        ens.run_ensemble(args.out, REPO, jobs=args.jobs, order=args.order, retry_failed=args.retry_failed,
                         log=lambda m: print(m, flush=True), scheduler=args.scheduler)
        print('\n'.join(ens.status_lines(args.out)))
        failed = [k for k, v in ens.Ensemble(args.out).runs().items() if v['state'] == 'failed']
        if failed:
            print('%d run(s) failed: %s (see their log.txt)' % (len(failed), ', '.join(sorted(failed))))
        return 1 if failed else 0
    if args.cmd == 'status':
        print('\n'.join(ens.status_lines(args.out)))
        return 0
    if args.cmd == 'carry':
        return carry(p, ens, args)
    from yadecd.analysis.ensemble_report import analyse_ensemble
    from yadecd.analysis.publish import check_docs_root, publish
    out = args.figures or os.path.join(args.out, 'analysis')
    if args.docs:
        try:
            check_docs_root(args.docs)
        except ValueError as e:
            p.error(str(e))
    summary = analyse_ensemble(args.out, out, n_boot=args.n_boot, log=lambda m: print(m, flush=True),
                               records_from=args.records)
    print('written: %s' % os.path.join(out, 'ensemble_summary.json'))
    if args.docs:
        publish(out, args.docs, log=lambda m: print(m, flush=True))
    return 0 if summary['n_runs_analysed_all_shapes'] else 1


def carry(p, ens, args):
    """The ``carry`` command: once, or every ``--every`` minutes until every run is done and carried."""
    import time
    if args.every is not None and not args.every > 0:
        p.error('--every must be a positive number of minutes')
    if args.snap_every is not None and not args.snap_every > 0:
        p.error('--snap-every must be a positive time in seconds')
    while True:
        try:
            outcome = ens.carry_ensemble(args.out, args.dest, snap_every=args.snap_every,
                                         log=lambda m: print(m, flush=True))
        except (OSError, ValueError) as e:
            p.error(str(e))
        counts = {}
        for v in outcome.values():
            key = v if v in ('carried', 'unchanged', 'no checkpoint', 'not started') else 'failed'
            counts[key] = counts.get(key, 0) + 1
        print('%s carry of %s: %s' % (time.strftime('%H:%M:%S'), args.out,
                                      ', '.join('%d %s' % (n, k) for k, n in sorted(counts.items()))), flush=True)
        all_done = all(ens.is_done(os.path.join(args.dest, name)) for name in outcome)
        if args.every is None or all_done:
            return 1 if counts.get('failed') else 0
        time.sleep(60 * args.every)


if __name__ == '__main__':
    sys.exit(main())

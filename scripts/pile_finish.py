#!/usr/bin/env python3
"""Finish a long pile run: its end of feed and relaxed pile re-solved tightly, their ensemble
records and their figures (yadecd.analysis.finish).

    python3 scripts/pile_finish.py RUN_DIR --out DIR [--epochs feed,relaxed] [--records DEST]
                                   [--tight 1e-6] [--max-iter 600000] [--threads 1]
                                   [--fossil T1 T2]... [--no-figures] [--docs docs]

The end of the feed comes from RUN_DIR/at_feed_end (the runner keeps it), the relaxed pile from the
run's newest checkpoint (the run must be done). Each tight re-solve runs in a YADE process of its
own (``scripts/pile_tolerance.py``; at full size it takes tens of minutes: say ``--epochs feed`` to
do the end of the feed while the run relaxes). DIR gets, per epoch, ``<epoch>/snap_<t>.npz`` (the
tight state), ``<epoch>/tolerance_effect.json``, ``<epoch>/figures/`` and
``records/<run>_<epoch>.json``; ``--records DEST`` copies the records there too (for example
docs/data/ensemble_runs); ``--docs DOCS`` copies each epoch's figures to DOCS/figures/<run>_<epoch>/
and its tolerance record to DOCS/data/tolerance_effect_<run>_<epoch>.json. Done steps are kept: run it again after an interruption. Runs with
Debian's /usr/bin/python3 (numpy, matplotlib); YADE is called for the re-solves only.
"""
import argparse
import os
import shutil
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

from yadecd.analysis.ensemble import record_file  # noqa: E402
from yadecd.analysis.finish import EPOCHS, finish  # noqa: E402
from yadecd.analysis.publish import check_docs_root, publish_finished  # noqa: E402

REPO = os.path.abspath(os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..'))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('run_dir', help='the pile run (run.json, ckpt/, at_feed_end/)')
    ap.add_argument('--out', required=True, help='output directory')
    ap.add_argument('--epochs', default=','.join(EPOCHS), help='comma-separated, among %s' % ', '.join(EPOCHS))
    ap.add_argument('--records', default=None, metavar='DEST', help='also copy the records into DEST')
    ap.add_argument('--tight', type=float, default=1e-6, help='tolerance of the re-solve')
    ap.add_argument('--max-iter', type=int, default=600000, help='sweeps allowed to the re-solve')
    ap.add_argument('--threads', type=int, default=1, help="YADE's threads for the re-solve")
    ap.add_argument('--fossil', type=float, nargs=2, action='append', metavar=('T1', 'T2'),
                    help='birth-time interval [s] of a fossil layer for the figures (repeatable)')
    ap.add_argument('--no-figures', action='store_true', help='records only')
    ap.add_argument('--docs', default=None, metavar='DOCS',
                    help="then copy each epoch's figures and tolerance record into a docs tree (this checkout's: docs; "
                         'yadecd.analysis.publish.finished_places)')
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    if not 0 < a.tight < 1:
        ap.error('--tight must lie in (0, 1), a relative residual (got %r)' % a.tight)
    if a.max_iter < 1 or a.threads < 1:
        ap.error('--max-iter and --threads must be positive (got %d and %d)' % (a.max_iter, a.threads))
    if a.docs:
        try:
            check_docs_root(a.docs)
        except ValueError as e:
            ap.error(str(e))
    epochs = [e.strip() for e in a.epochs.split(',') if e.strip()]
    try:
        records = finish(a.run_dir, a.out, REPO, epochs=epochs, tight=a.tight, max_iter=a.max_iter, threads=a.threads,
                         fossil=a.fossil, figures=not a.no_figures)
    except (ValueError, FileNotFoundError, RuntimeError) as e:
        print('pile_finish: %s' % e, file=sys.stderr)
        return 2
    if a.records:
        os.makedirs(a.records, exist_ok=True)
        for epoch, rec in records.items():
            name = record_file(rec['run'], epoch)
            shutil.copy2(os.path.join(a.out, 'records', name), os.path.join(a.records, name))
            print('record copied to', os.path.join(a.records, name))
    if a.docs:
        for epoch, rec in records.items():
            publish_finished(a.out, rec['run'], [epoch], a.docs, log=print)
    return 0


if __name__ == '__main__':
    sys.exit(main())

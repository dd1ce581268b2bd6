"""Finishing a long pile run: its analysed states re-solved tightly, their records and figures.

A long run (the full pile) is made at a loose tolerance; its analysed states, the end of the feed
and the relaxed pile, are re-solved from their checkpoints to a tight tolerance
(``scripts/pile_tolerance.py``: one step from the saved state, the forces solved to ``tight``)
before their numbers are read. :func:`finish` does every step for one run and skips those whose
output is already there, so that an interrupted finish goes on where it stopped:

1. for each epoch, the tight re-solve in a YADE process of its own: the end of the feed from the
   run's kept copy ``<run>/at_feed_end`` (:data:`yadecd.runs.carry.FEED_END_DIR`), the relaxed
   pile from the run's own newest checkpoint (the run must be done); it writes
   ``<out>/<epoch>/snap_<t>.npz`` (t: the checkpoint's time plus one step) and
   ``<out>/<epoch>/tolerance_effect.json`` (the run's tolerance against the tight one);
2. the epoch's record for the ensemble statistics (:func:`.ensemble.labelled_record`,
   named as the ensembles' records are, :func:`.ensemble.record_file`) in ``<out>/records``;
3. the epoch's figures and ``summary.json`` (:func:`.report.analyse`) in
   ``<out>/<epoch>/figures``.
"""

import json
import os
import subprocess
import time

from ..runs.carry import FEED_END_DIR, is_done
from ..runs.ensemble import run_name
from . import ensemble as ens_analysis, report
from .snapshots import load_snapshot

EPOCHS = ('feed', 'relaxed')


def epoch_sources(run_dir):
    """``{epoch: directory whose newest checkpoint is that epoch's state}`` for the epochs the
    run can give now, and ``{epoch: why not}`` for the others."""
    have, missing = {}, {}
    if os.path.isdir(os.path.join(run_dir, FEED_END_DIR)):
        have['feed'] = os.path.join(run_dir, FEED_END_DIR)
    else:
        missing['feed'] = ('%s has no copy of itself at the end of the feed (%s/: kept by the runner since '
                           '2026-12-06 for runs that relax after the feed)' % (run_dir, FEED_END_DIR))
    if is_done(run_dir):
        have['relaxed'] = run_dir
    else:
        missing['relaxed'] = '%s is not finished: its relaxed pile does not exist yet' % run_dir
    return have, missing


def tight_snapshot(epoch_dir):
    """The tight re-solve's snapshot in ``epoch_dir`` (``snap_<t>.npz``), or None."""
    if not os.path.isdir(epoch_dir):
        return None
    snaps = sorted(n for n in os.listdir(epoch_dir) if n.startswith('snap_') and n.endswith('.npz'))
    return os.path.join(epoch_dir, snaps[-1]) if snaps else None


def resolve_command(repo, source, epoch_dir, tight, max_iter, threads):
    """The YADE command line of one tight re-solve (``scripts/pile_tolerance.py``)."""
    return [os.path.join(repo, 'scripts', 'yade'), '-j%d' % threads, '-n', '-x',
            os.path.join(repo, 'scripts', 'pile_tolerance.py'), source, '--tight', repr(tight),
            '--max-iter', str(max_iter), '--snapshot', os.path.join(epoch_dir, 'tight.npz'),
            '--out', os.path.join(epoch_dir, 'tolerance_effect.json')]


def resolve(repo, source, epoch_dir, tight=1e-6, max_iter=600000, threads=1, log=print):
    """Re-solve the newest checkpoint of ``source`` tightly (unless ``epoch_dir`` holds its
    snapshot already) and return the snapshot's path. Raises RuntimeError naming the log when
    the YADE process fails."""
    done = tight_snapshot(epoch_dir)
    if done:
        log('%s: tight re-solve kept (%s)' % (epoch_dir, os.path.basename(done)))
        return done
    os.makedirs(epoch_dir, exist_ok=True)
    log_path = os.path.join(epoch_dir, 'resolve.log')
    t0 = time.time()
    log('%s: re-solving %s to %.0e (at most %d sweeps; log %s)' % (epoch_dir, source, tight, max_iter, log_path))
    with open(log_path, 'w') as f:
        rc = subprocess.run(resolve_command(repo, source, epoch_dir, tight, max_iter, threads),
                            stdout=f, stderr=subprocess.STDOUT, cwd=repo).returncode
    tmp = os.path.join(epoch_dir, 'tight.npz')
    if rc != 0 or not os.path.exists(tmp):
        raise RuntimeError('the tight re-solve of %s failed (exit %d): see %s' % (source, rc, log_path))
    t = float(load_snapshot(tmp)['time'])
    path = os.path.join(epoch_dir, 'snap_%08.3f.npz' % t)
    os.replace(tmp, path)
    log('%s: re-solved in %.0f s -> %s' % (epoch_dir, time.time() - t0, os.path.basename(path)))
    return path


def finish(run_dir, out_dir, repo, epochs=EPOCHS, tight=1e-6, max_iter=600000, threads=1, fossil=None,
           figures=True, log=print):
    """Every step of the module's docstring for the pile run in ``run_dir``, outputs in ``out_dir``.

    :returns: ``{epoch: record}`` of the epochs finished.
    :raises ValueError: an epoch is unknown, or the run cannot give it yet (the reason named).
    :raises FileNotFoundError: ``run_dir`` holds no pile run.
    """
    if not os.path.exists(os.path.join(run_dir, 'run.json')):
        raise FileNotFoundError('%s holds no pile run (no run.json)' % run_dir)
    unknown = [e for e in epochs if e not in EPOCHS]
    if unknown:
        raise ValueError('unknown epoch %s (known: %s)' % (', '.join(unknown), ', '.join(EPOCHS)))
    have, missing = epoch_sources(run_dir)
    wanted_missing = [missing[e] for e in epochs if e in missing]
    if wanted_missing:
        raise ValueError('; '.join(wanted_missing))
    with open(os.path.join(run_dir, 'run.json')) as f:
        params = json.load(f)
    name = run_name(int(params['n_grains']), int(params['seed']), params.get('grain_shape', 'sphere'))
    records_dir = os.path.join(out_dir, 'records')
    os.makedirs(records_dir, exist_ok=True)
    out = {}
    for epoch in epochs:
        epoch_dir = os.path.join(out_dir, epoch)
        snap = resolve(repo, have[epoch], epoch_dir, tight, max_iter, threads, log)
        rec = ens_analysis.labelled_record(snap, params, name, epoch)
        path = os.path.join(records_dir, ens_analysis.record_file(name, epoch))
        with open(path, 'w') as f:
            json.dump(rec, f)
        log('%s: record %s (slope %.1f deg, D %+.2f)' % (epoch, path, ens_analysis.finite_or_nan(rec['slope_deg']),
                                                        ens_analysis.finite_or_nan(rec['dip_D'])))
        if figures:
            report.analyse(snap, os.path.join(epoch_dir, 'figures'), fossil=fossil)
            log('%s: figures in %s' % (epoch, os.path.join(epoch_dir, 'figures')))
        out[epoch] = rec
    return out

"""The whole analysis of an ensemble of sand piles (``scripts/pile_ensemble.py analyse``): every
finished run's records (:func:`yadecd.analysis.ensemble.collect`) with the stored ones, the
statistics per size (:mod:`.ensemble`), per grain shape (:mod:`.shapes`) and the size trends
(:mod:`.trends`), their tables and figures. It stands above those modules: they never import it.

numpy and matplotlib only (no YADE needed).
"""
import json
import os

from ..io import jsonable
from .ensemble import (aggregate, collect, fig_cuts, fig_dip, fig_pressure, fig_slope, grain_shape, size_labels,
                       stored_records, table_markdown)
from .shapes import analyse_shapes
from .trends import analyse_trends


def analyse_ensemble(root, out_dir, n_boot=2000, log=print, records_from=()):
    """Analyse every finished run of the ensemble in ``root`` (plus the stored per-run records of
    ``records_from`` directories for runs absent from ``root``); write the statistics, the tables
    (per size, per shape, the size trends of :mod:`.trends`) and the figures into ``out_dir``.
    Returns the summary dict."""
    if not os.path.isdir(root):
        raise ValueError('%s is not an ensemble directory (it does not exist)' % root)
    os.makedirs(out_dir, exist_ok=True)
    records, failed, unfinished = collect(root, out_dir, log=log)
    extra = stored_records(records_from, {(r['run'], r['epoch']) for r in records})
    if extra:
        log('added %d stored records (%s)' % (len(extra), ', '.join(sorted({r['run'] for r in extra}))))
    records += extra
    every_shape = records
    records = [r for r in records if grain_shape(r) == 'sphere']   # the size trend of the paper's grains
    stats, changes = aggregate(records)
    summary = {'root': os.path.abspath(root), 'n_runs_analysed': len({r['run'] for r in records}),
               'n_runs_analysed_all_shapes': len({r['run'] for r in every_shape}),
               'failed_runs': failed, 'unfinished_runs': unfinished, 'stats': stats,
               'relaxation_change': changes,
               'conventions': {'interval': '95 % Student-t over seeds (mean ± std over seeds)',
                               'dip_pooled': 'D = 1 - sum_p p_disc / sum_p p_ring over piles p; delete-one-pile jackknife, t interval, '
                                             'confidence = one-sided t probability that D > 0',
                               'units': 'SI unless the key says otherwise'}}
    summary.update((k, v) for k, v in (('shapes', analyse_shapes(every_shape, out_dir)),
                                       ('size_trends', analyse_trends(every_shape, out_dir))) if v)
    with open(os.path.join(out_dir, 'ensemble_summary.json'), 'w') as f:
        json.dump(jsonable(summary), f, indent=1, sort_keys=True)
    table = (table_markdown(stats, changes, size_labels(records)) if records else   # clumps only: no size table, no empty figures
             'No piles of spheres among the analysed runs: the size table and its figures (ensemble_*.png) are not drawn; '
             'the shapes are in shape_table.md.\n')
    if failed:
        table += '\nFailed runs (not in the statistics): ' + '; '.join('%s: %s' % (k, ' '.join(v)) for k, v in failed.items()) + '\n'
    if unfinished:
        table += '\nUnfinished runs (not in the statistics): ' + ', '.join(unfinished) + '\n'
    with open(os.path.join(out_dir, 'ensemble_table.md'), 'w') as f:
        f.write(table)
    if records:
        fig_slope(stats, records, os.path.join(out_dir, 'ensemble_slope.png'))
        fig_dip(stats, records, os.path.join(out_dir, 'ensemble_dip.png'))
        fig_cuts(records, os.path.join(out_dir, 'ensemble_cuts.png'))
        fig_pressure(records, os.path.join(out_dir, 'ensemble_pressure.png'))
    log(table)
    return summary

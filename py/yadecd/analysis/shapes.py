"""The grain-shape comparison of the ensembles (issue 30): per-shape statistics and tables, the
central dip and the flank slope against size per shape, and floor-pressure profiles per shape at
every size two shapes share (``scripts/pile_ensemble.py analyse`` writes them when the records hold
another shape than spheres). The statistics of each shape are :func:`yadecd.analysis.ensemble.aggregate`'s.

numpy and matplotlib only (no YADE needed).
"""
import os

import numpy as np

from .. import analysis as pa
from . import figures as pf
from .ensemble import finite_or_nan, stat_series, size_axis, aggregate, grain_shape, single_pile_dips, size_labels, table_markdown


#: Colours and markers of the grain shapes in the shape figures (spheres first, in black).
SHAPE_STYLE = {'sphere': ('k', 'o'), 'dimer': ('tab:blue', 's'), 'tetra': ('tab:red', '^')}


def _shape_order(shapes):
    return sorted(shapes, key=lambda k: (list(SHAPE_STYLE).index(k) if k in SHAPE_STYLE else len(SHAPE_STYLE), k))


def by_shape(records):
    """{grain shape: its records}, spheres first."""
    out = {}
    for r in records:
        out.setdefault(grain_shape(r), []).append(r)
    return {k: out[k] for k in _shape_order(out)}


def shape_stats(records):
    """{grain shape: (stats, relaxation changes)} by :func:`aggregate` over each shape's records."""
    return {shape: aggregate(recs) for shape, recs in by_shape(records).items()}


def shared_sizes(records):
    """Grain counts that records of two shapes or more share (sorted)."""
    shapes = {}
    for r in records:
        shapes.setdefault(r['n_grains'], set()).add(grain_shape(r))
    return sorted(n for n, k in shapes.items() if len(k) > 1)


def shape_table_markdown(per_shape, records):
    """One ensemble table per grain shape (:func:`table_markdown`), under a heading each, over the
    sizes that two shapes share (every size when none is shared)."""
    parts = []
    groups = by_shape(records)
    sizes = set(shared_sizes(records))
    for shape, (stats, changes) in per_shape.items():
        keep = lambda key: not sizes or int(key.split('_')[0]) in sizes  # noqa: E731
        labels = {n: '%s %s' % (label, shape) for n, label in size_labels(groups[shape]).items()}
        parts.append('## %s\n\n%s' % (shape, table_markdown({k: v for k, v in stats.items() if keep(k)},
                                                              {k: v for k, v in changes.items() if keep(k)}, labels)))
    return '\n'.join(parts)


def _piles(n):
    """'8 piles', or '1 pile, no interval' (one realisation has no spread over seeds)."""
    return '1 pile, no interval' if n == 1 else '%d piles' % n


def _one_axes():
    fig = pf.new_figure(7, 4.2)
    return fig, fig.add_subplot(1, 1, 1)


def _shape_series(per_shape):
    """(shape, its statistics, colour, marker, x factor) for each shape of :func:`shape_stats`'
    result: the factor spreads the shapes' points apart around each size on the log axis."""
    k = len(per_shape)
    for i, (shape, (stats, _)) in enumerate(per_shape.items()):
        colour, marker = SHAPE_STYLE.get(shape, ('tab:green', 'D'))
        yield shape, stats, colour, marker, 1 + 0.04 * (i - (k - 1) / 2)


def fig_shapes_dip(per_shape, records, path, epoch='relaxed'):
    """Central dip D against pile size, one series per grain shape: every pile (dots), the pooled
    D over seeds with its 95 % interval (jackknife over piles) where a size has two piles or more,
    and where it has one, that pile's own interval over sectors (open diamonds): one realisation
    has no spread over seeds."""
    fig, ax = _one_axes()
    for shape, stats, colour, marker, f in _shape_series(per_shape):
        mine = [r for r in records if grain_shape(r) == shape and r['epoch'] == epoch and r.get('dip_D') is not None]
        if mine:
            ax.plot([r['n_grains'] * f for r in mine], [r['dip_D'] for r in mine], '.', color=colour, ms=3, alpha=0.5)
        rows = sorted((int(k.split('_')[0]), g) for k, g in stats.items() if k.endswith('_' + epoch))
        label = '%s (piles per size: %s)' % (shape, ', '.join(str(g['n_runs']) for _, g in rows))
        xs = [(n, g['dip_pooled']) for n, g in rows if np.isfinite(g['dip_pooled']['se'])]
        if xs:
            n, d = np.array([x[0] for x in xs]), [x[1] for x in xs]
            D = np.array([v['D'] for v in d])
            lo, hi = np.array([v['ci95'][0] for v in d]), np.array([v['ci95'][1] for v in d])
            ax.errorbar(n * f, D, yerr=[D - lo, hi - D], fmt=marker + '-', color=colour, capsize=3, lw=0.8, label=label)
            label = None
        lone = single_pile_dips(mine, epoch)
        if lone:
            x, d, lo, hi = map(np.array, zip(*lone))
            ax.errorbar(x * f, d, yerr=[d - lo, hi - d], fmt='d', color=colour, mfc='none', capsize=3, ls='none',
                        elinewidth=0.8, label=label if label else None)
    ax.plot([], [], 'd', color='0.4', mfc='none', label='one pile: its own 95 % interval (sectors)')
    ax.axhline(0, color='k', lw=0.8)
    size_axis(ax, records)
    ax.set_xlabel('grains')
    ax.set_ylabel('D = 1 - p(r < 2d) / p(2d ≤ r < 4d)')
    ax.set_title('central dip against size and grain shape, %s piles (95 %% intervals over seeds; D > 0 is a dip)' % epoch,
                 fontsize=8)
    ax.legend(fontsize=7)
    return pf.save_figure(fig, path)


def fig_shapes_slope(per_shape, records, path, epoch='relaxed'):
    """Flank slope against pile size, one series per grain shape (mean over seeds, 95 %
    interval; dots: single piles); the paper's 26°."""
    fig, ax = _one_axes()
    for shape, stats, colour, marker, f in _shape_series(per_shape):
        for r in records:
            if grain_shape(r) == shape and r['epoch'] == epoch and r.get('slope_deg') is not None:
                ax.plot(r['n_grains'] * f, r['slope_deg'], '.', color=colour, ms=3, alpha=0.5)
        ns, m, lo, hi = stat_series(stats, 'slope_deg', epoch)
        if len(ns):
            runs = [stats['%d_%s' % (n, epoch)]['n_runs'] for n in ns]
            ax.errorbar(ns * f, m, yerr=[m - lo, hi - m], fmt=marker + '-', color=colour, capsize=3, lw=0.8,
                        label='%s (piles per size: %s; one pile: no interval)' % (shape, ', '.join(str(k) for k in runs)))
    ax.axhline(26, color='k', ls='--', lw=0.8, label='paper (spheres, 14 000 grains)')
    size_axis(ax, records)
    ax.set_xlabel('grains')
    ax.set_ylabel('flank slope [deg]')
    ax.set_title('free-surface slope against size and grain shape, %s piles (95 %% intervals over seeds)' % epoch, fontsize=8)
    ax.legend(fontsize=7)
    return pf.save_figure(fig, path)


def fig_shapes_pressure(records, n_grains, path, epoch='relaxed'):
    """Floor pressure over the hydrostatic ρ_bulk·g·H per ring at one pile size, one curve per
    grain shape (mean over seeds, 95 % intervals)."""
    fig, ax = _one_axes()
    groups = by_shape([r for r in records if r['n_grains'] == n_grains and r['epoch'] == epoch])
    for k, (shape, recs) in enumerate(groups.items()):
        colour, marker = SHAPE_STYLE.get(shape, ('tab:green', 'D'))
        m = min(len(r['rings_p_over_hydrostatic']) for r in recs)
        x = np.array(recs[0]['rings_r_over_d'][:m])
        rows = np.array([[finite_or_nan(v) for v in r['rings_p_over_hydrostatic'][:m]] for r in recs])
        st = [pa.mean_interval(rows[:, j]) for j in range(m)]
        mean = np.array([s_['mean'] for s_ in st])
        lo = np.array([s_['ci95'][0] if np.isfinite(s_['ci95'][0]) else s_['mean'] for s_ in st])
        hi = np.array([s_['ci95'][1] if np.isfinite(s_['ci95'][1]) else s_['mean'] for s_ in st])
        shift = (k - (len(groups) - 1) / 2) * 0.12
        ax.errorbar(x + shift, mean, yerr=[mean - lo, hi - mean], fmt=marker + '-', color=colour, ms=3, capsize=2,
                    label='%s (%s)' % (shape, _piles(len(recs))))
    if not groups:
        ax.text(0.5, 0.5, 'no %s pile of %d grains' % (epoch, n_grains), ha='center', va='center', transform=ax.transAxes)
    ax.axhline(1, color='k', ls=':', lw=0.8, label='hydrostatic ρ_bulk g H')
    ax.axvspan(0, 2, color='0.9', zorder=0)
    ax.set_xlabel('r / d (d: mean volume-equivalent diameter; grey: the central disc of D)')
    ax.set_ylabel('floor pressure / (ρ_bulk g H)')
    ax.set_title('floor pressure per ring, %d-grain %s piles, by grain shape (95 %% intervals over seeds)' % (n_grains, epoch),
                 fontsize=8)
    ax.legend(fontsize=7)
    return pf.save_figure(fig, path)


def analyse_shapes(records, out_dir):
    """The grain-shape comparison, when the records hold another shape than spheres: per-shape
    tables (``shape_table.md``), D and the slope against size per shape, and floor-pressure
    profiles per shape at every size two shapes share. Returns the per-shape statistics ({} when
    only spheres are there)."""
    groups = by_shape(records)
    if set(groups) <= {'sphere'}:
        return {}
    per_shape = shape_stats(records)
    with open(os.path.join(out_dir, 'shape_table.md'), 'w') as f:
        f.write(shape_table_markdown(per_shape, records))
    fig_shapes_dip(per_shape, records, os.path.join(out_dir, 'shapes_dip.png'))
    fig_shapes_slope(per_shape, records, os.path.join(out_dir, 'shapes_slope.png'))
    for n in shared_sizes(records):
        fig_shapes_pressure(records, n, os.path.join(out_dir, 'shapes_pressure_n%d.png' % n))
    return {shape: {'stats': st, 'relaxation_change': ch} for shape, (st, ch) in per_shape.items()}

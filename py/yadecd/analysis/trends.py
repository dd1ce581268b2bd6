"""Trends of pile observables with the pile's size, per grain shape: does the central dip deepen
as piles grow, does the flank steepen? (docs/pile.md; issue 30's question, asked of Moreau's.)

Each pile is one point: its own value at an epoch (end of the feed or relaxed) against log10 of
its grain count. :func:`yadecd.analysis.stats.size_trend` fits the line and gives its slope per
decade of grains with a pooled Student-t interval (every pile, the full pile included) and a
Welch–Satterthwaite one (the sizes with two piles or more, each with its own scatter), and the
one-sided confidence that the slope is positive. Piles fed over another disc than the paper's
are left out (a different experiment: docs/pile.md, "Against the literature"); the time step
and tolerance may differ between sizes (the faster protocol, validated against the seed scatter).
"""
import math
import os

import numpy as np

from ..pile.protocol import DEFAULTS
from . import figures as pf
from .ensemble import feed_radius_of
from .shapes import by_shape, shape_stats, SHAPE_STYLE
from .stats import line_prediction, size_trend, t_cdf

#: observables whose size trend is reported: record key -> (name, unit, format of a value)
KEYS = {'dip_D': ('central dip D', '', '%+.3f'), 'slope_deg': ('flank slope', '°', '%+.2f')}


#: the size ranges fitted: every size, and the sizes whose piles have a straight flank (the
#: 300-grain piles have none, and a central peak that alone can tilt a line over all sizes)
RANGES = {'all sizes': 0, '≥ 1000 grains': 1000}

#: the smallest piles the largest size is compared against (those with a straight flank)
LARGEST_MIN_GRAINS = RANGES['≥ 1000 grains']


def is_paper_fed(record):
    """Whether a per-run record's pile was fed over the paper's disc (0.8 cm; records written
    before the feed radius was kept were): the piles the size and shape comparisons take, since
    another feed radius is another experiment."""
    return bool(np.isclose(feed_radius_of(record), DEFAULTS['feed_radius']))


def trend_points(records, epoch, min_grains=0):
    """(grain counts, {key: values}) of the records at ``epoch`` of piles of ``min_grains`` or more,
    fed over the paper's disc; a value the record lacks is nan."""
    mine = [r for r in records if r['epoch'] == epoch and r['n_grains'] >= min_grains and is_paper_fed(r)]
    n = np.array([r['n_grains'] for r in mine], dtype=float)
    vals = {k: np.array([np.nan if r.get(k) is None else r[k] for r in mine], dtype=float) for k in KEYS}
    return n, vals


def size_trends(records, epochs=('feed', 'relaxed'), ranges=RANGES):
    """{shape: {range: {epoch: {key: size_trend result}}}} for every shape and size range
    (``ranges``: label -> smallest pile) with piles at two sizes or more."""
    out = {}
    for shape, recs in by_shape(records).items():
        for label, smallest in ranges.items():
            for epoch in epochs:
                n, vals = trend_points(recs, epoch, smallest)
                if len(set(n)) >= 2:
                    out.setdefault(shape, {}).setdefault(label, {})[epoch] = {k: size_trend(n, v) for k, v in vals.items()}
    return out


def largest_against_line(records, epoch, key, min_grains=LARGEST_MIN_GRAINS):
    """Does the largest size stand off the line of the smaller ones? Per shape with three sizes or
    more of ``min_grains`` and up: the least-squares line of ``key`` on log10(grains) over the
    smaller sizes' piles, the mean of the largest size's m piles, and where the line puts such a
    mean (:func:`~yadecd.analysis.stats.line_prediction` with ``m``: the scatter of single piles
    about the line and the line's own uncertainty that far out), with t = (mean − line)/se and
    the one-sided probability, were the largest piles on the line, of a mean at least that far
    above it. This is the test the docs apply to the full piles (one, then three) against the
    1000–5000-grain ensembles.

    :returns: {shape: dict ``n_grains``, ``m``, ``mean``, ``values``, ``line`` (the prediction),
        ``ci95`` (for a mean of m), ``t``, ``df``, ``p_above``}; shapes without three sizes left out."""
    out = {}
    for shape, recs in by_shape(records).items():
        n, vals = trend_points(recs, epoch, min_grains)
        y = vals[key]
        ok = np.isfinite(y)
        n, y = n[ok], y[ok]
        sizes = sorted(set(n))
        if len(sizes) < 3:
            continue
        big = n == sizes[-1]
        p = line_prediction(np.log10(n[~big]), y[~big], math.log10(sizes[-1]), m=int(big.sum()))
        if not math.isfinite(p['se']) or p['se'] <= 0:
            continue
        mean = float(y[big].mean())
        t = (mean - p['value']) / p['se']
        out[shape] = {'n_grains': int(sizes[-1]), 'm': int(big.sum()), 'mean': mean, 'values': [float(v) for v in y[big]],
                      'line': p['value'], 'se': p['se'], 'ci95': p['ci95'], 't': t, 'df': p['df'],
                      'p_above': 1.0 - t_cdf(t, p['df'])}
    return out


def largest_table_markdown(records, epochs=('feed', 'relaxed'), min_grains=LARGEST_MIN_GRAINS):
    """One row per shape, epoch and observable of :func:`largest_against_line`."""
    rows = ['| shape | epoch | observable | largest size: piles, their values | their mean | the smaller sizes\' line '
            'there [95 % for a mean of that many piles] | t (df) | one-sided p above the line |',
            '| --- | --- | --- | --- | --- | --- | --- | --- |']
    for epoch in epochs:
        for key, (name, unit, fmt) in KEYS.items():
            for shape, c in largest_against_line(records, epoch, key, min_grains).items():
                fmt_u = fmt + unit
                rows.append('| %s | %s | %s | %d grains: %d (%s) | %s | %s %s | %.2f (%d) | %.3f |' % (
                    shape, epoch, name, c['n_grains'], c['m'], ', '.join(fmt_u % v for v in c['values']),
                    fmt_u % c['mean'], fmt_u % c['line'], _interval(c['ci95'], fmt_u), c['t'], c['df'], c['p_above']))
    return '\n'.join(rows) + '\n' if len(rows) > 2 else ''


def _interval(ci, fmt):
    return '[%s, %s]' % (fmt % ci[0], fmt % ci[1]) if np.all(np.isfinite(ci)) else '–'


def trend_table_markdown(trends):
    """One row per shape, size range, epoch and observable: the slope per decade of grains with
    both intervals and confidences, the sizes and pile counts (a range whose piles are those of a
    row above is not repeated)."""
    rows = ['| shape | sizes | epoch | observable | per decade of grains, all piles [95 % t] | confidence > 0 '
            '| replicated sizes only [95 % Welch] (df) | confidence > 0 | piles per size |',
            '| --- | --- | --- | --- | --- | --- | --- | --- | --- |']
    written = set()
    for shape, by_range in trends.items():
        for label, by_epoch in by_range.items():
            for epoch, by_key in by_epoch.items():
                for key, t in by_key.items():
                    same = (shape, epoch, key, tuple(t['sizes'].items()))
                    if same in written:      # a range that leaves out no pile with this value
                        continue
                    written.add(same)
                    name, unit, fmt = KEYS[key]
                    fmt_u = fmt + unit
                    rows.append('| %s | %s | %s | %s | %s %s | %.0f %% | %s %s (%.1f) | %.0f %% | %s |' % (
                        shape, label, epoch, name, fmt_u % t['slope'], _interval(t['ci95_t'], fmt_u),
                        100 * t['confidence_t'], fmt_u % t['slope_welch'], _interval(t['ci95_welch'], fmt_u),
                        t['df_welch'], 100 * t['confidence_welch'], ', '.join('%d: %d' % kv for kv in t['sizes'].items())))
    return '\n'.join(rows) + '\n'


def fig_size_trend(records, trends, path, key='dip_D', epoch='relaxed'):
    """Every pile's value against its grain count (log axis), per shape, with the line fitted over
    every size (solid; dotted: the slopes of its 95 % interval through the mean point) and over the
    sizes from 1000 grains where that leaves piles out (dashed)."""
    name, unit, _ = KEYS[key]
    fig = pf.new_figure(7.5, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    drawn = 0
    for k, (shape, recs) in enumerate(by_shape(records).items()):
        n, vals = trend_points(recs, epoch)
        y = vals[key]
        ok = np.isfinite(y)
        if not ok.any():
            continue
        colour, marker = SHAPE_STYLE.get(shape, ('tab:green', 'D'))
        shift = 1 + 0.03 * (k - 1)
        ax.plot(n[ok] * shift, y[ok], marker, color=colour, ms=3.5, alpha=0.7, ls='none',
                label='%s: one point per pile' % shape)
        drawn += int(ok.sum())
        shown = set()
        for j, label in enumerate(RANGES):
            t = trends.get(shape, {}).get(label, {}).get(epoch, {}).get(key)
            if t is None or not np.isfinite(t['slope']) or tuple(t['sizes']) in shown:
                continue
            shown.add(tuple(t['sizes']))
            x = np.log10(np.array([size for size, c in t['sizes'].items() for _ in range(c)], dtype=float))
            xs = np.linspace(x.min(), x.max(), 20)
            ax.plot(10 ** xs, t['intercept'] + t['slope'] * xs, '-' if j == 0 else '--', color=colour, lw=1.2,
                    label='%s, %s: %.3g per decade, 95 %% [%.3g, %.3g], confidence %.0f %%' % (
                        shape, label, t['slope'], t['ci95_t'][0], t['ci95_t'][1], 100 * t['confidence_t']))
            if j == 0:
                xm, ym = x.mean(), t['intercept'] + t['slope'] * x.mean()
                for b in t['ci95_t']:
                    if np.isfinite(b):
                        ax.plot(10 ** xs, ym + b * (xs - xm), ':', color=colour, lw=0.8)
    if key == 'dip_D':
        ax.axhline(0, color='k', lw=0.6)
    ax.set_xscale('log')
    ax.set_xlabel('grains')
    ax.set_ylabel('%s%s, %s piles' % (name, ' [%s]' % unit.replace('°', 'deg') if unit else '', epoch))
    ax.set_title('%s against size: least-squares lines over single piles (dotted: the 95 %% slopes over all sizes)' % name,
                 fontsize=8)
    if not drawn:
        ax.text(0.5, 0.5, 'no piles with this value', transform=ax.transAxes, ha='center')
    ax.legend(fontsize=6, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    return pf.save_figure(fig, path)


def paper_fed(records):
    """The records of piles fed over the paper's disc (the size and shape comparisons' piles)."""
    return [r for r in records if is_paper_fed(r)]


def _ci(st, fmt):
    if not st or st['n'] == 0 or not np.isfinite(st['mean']):
        return '–'
    if st['n'] < 2 or not np.all(np.isfinite(st['ci95'])):
        return fmt % st['mean']
    return (fmt + ' [' + fmt + ', ' + fmt + ']') % (st['mean'], st['ci95'][0], st['ci95'][1])


def answer_table_markdown(records, epoch='relaxed'):
    """The answer in one table: per grain shape and size, the piles, the flank slope (mean over
    piles [95 % t]), the central dip D pooled over piles (delete-one-pile jackknife [95 %]) with the
    one-sided confidence of a dip, and the packing fraction; a size with one pile gives its own
    D with the interval over its sectors, marked as such (no spread over realisations exists)."""
    rows = ['| shape | grains | piles | flank slope [95 %] | central dip D [95 %] | confidence of a dip | packing fraction |',
            '| --- | --- | --- | --- | --- | --- | --- |']
    mine = paper_fed(records)
    groups = by_shape(mine)
    for shape, (stats, _) in shape_stats(mine).items():
        for key, g in stats.items():
            n, ep = key.split('_', 1)
            if ep != epoch:
                continue
            if g['n_runs'] >= 2:
                d = g['dip_pooled']
                dip = '%+.2f [%+.2f, %+.2f]' % (d['D'], d['ci95'][0], d['ci95'][1]) if np.isfinite(d['se']) else '–'
                conf = '%.1f %%' % (100 * d['confidence_positive']) if np.isfinite(d['confidence_positive']) else '–'
            else:
                one = [r for r in groups[shape] if r['n_grains'] == int(n) and r['epoch'] == epoch][0]
                ci = one.get('dip_ci95') or [float('nan')] * 2
                dip = '%+.2f [%+.2f, %+.2f] (over its sectors)' % (one['dip_D'], ci[0], ci[1])
                conf = '%.1f %% (one pile)' % (100 * one['dip_confidence']) if one.get('dip_confidence') is not None else '–'
            rows.append('| %s | %s | %d | %s | %s | %s | %s |' % (
                shape, n, g['n_runs'], _ci(g['slope_deg'], '%.1f°'), dip, conf, _ci(g['packing_fraction'], '%.3f')))
    return '\n'.join(rows) + '\n'


def analyse_trends(records, out_dir):
    """Write ``answer_table.md`` (slope and D per shape and size, relaxed piles), ``size_trend.md``
    (the slopes per decade, then the largest size against the smaller sizes' line) and
    ``size_trend_{dip,slope}.png`` into ``out_dir``; return the trends ({} and nothing written
    when no shape has two sizes)."""
    trends = size_trends(records)
    if not trends:
        return {}
    with open(os.path.join(out_dir, 'answer_table.md'), 'w') as f:
        f.write(answer_table_markdown(records))
    with open(os.path.join(out_dir, 'size_trend.md'), 'w') as f:
        f.write(trend_table_markdown(trends))
        largest = largest_table_markdown(records)
        if largest:
            f.write('\nThe largest size against the line of the smaller ones (piles of %d grains and up; '
                    '`trends.largest_against_line`):\n\n' % LARGEST_MIN_GRAINS + largest)
    fig_size_trend(records, trends, os.path.join(out_dir, 'size_trend_dip.png'), 'dip_D')
    fig_size_trend(records, trends, os.path.join(out_dir, 'size_trend_slope.png'), 'slope_deg')
    return trends

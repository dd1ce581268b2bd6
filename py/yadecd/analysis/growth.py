"""The central dip while a pile grows: the fed snapshots of a long run, each measured as the
ensembles measure a pile (:func:`yadecd.analysis.ensemble.run_record`), against the grains it
holds at that moment, beside the ensembles' piles at the end of their feed.

A pile fed at the paper's rate does not know how many grains it will get: the full pile at
t = 25 s is, in law, a 5000-grain pile at the end of its feed. So the snapshots of one long run
trace the fed state's D against size within one realisation, where the ensembles give it over
realisations at a few sizes. A single snapshot's D is noisy (its 95 % interval over the pile's
sectors is shown with it, and fed piles move: avalanches come and go within seconds), so a
growth curve says where the dip appears in that realisation, not its law.
"""
import json
import os

import numpy as np

from ..pile.protocol import DEFAULTS, feed_time
from . import figures as pf
from .ensemble import grain_shape, run_record
from .snapshots import list_snapshots, load_snapshot, run_parameters
from .stats import mean_interval
from .trends import is_paper_fed

#: bump when the cached growth records change meaning
CACHE_VERSION = 1


def fed_snapshots(run_dir, params=None):
    """(time [s], path) of the run's snapshots taken while it was fed (up to the end of its feed,
    n_grains / rate rounded to the time step, within 1 ms)."""
    params = run_parameters(run_dir) if params is None else params
    t_feed = feed_time(int(params['n_grains']), params.get('rate', DEFAULTS['rate']), params.get('dt', DEFAULTS['dt']))
    return [(t, p) for t, p in list_snapshots(run_dir) if t <= t_feed + 1e-3]


def growth_records(run_dir, cache_dir=None, measure=run_record, log=print):
    """One record per fed snapshot of ``run_dir`` (``measure(path, params)``, plus ``grains_now``:
    the grains in the pile at that moment, and ``run_name``), in time order. With ``cache_dir``,
    each record is kept there as JSON and read back while its snapshot is unchanged (same size)."""
    params = run_parameters(run_dir)
    name = os.path.basename(os.path.normpath(run_dir))
    out = []
    for t, path in fed_snapshots(run_dir, params):
        key = {'growth_cache_version': CACHE_VERSION, 'snapshot_bytes': os.path.getsize(path)}
        cached = os.path.join(cache_dir, '%s_%s.json' % (name, os.path.basename(path)[:-4])) if cache_dir else None
        rec = None
        if cached and os.path.exists(cached):
            with open(cached) as f:
                rec = json.load(f)
            if any(rec.get(k) != v for k, v in key.items()):
                rec = None
        if rec is None:
            rec = dict(measure(path, params), grains_now=int((~load_snapshot(path)['fixed']).sum()),
                       run_name=name, **key)
            if cached:
                os.makedirs(cache_dir, exist_ok=True)
                with open(cached, 'w') as f:
                    json.dump(rec, f, indent=1, sort_keys=True)
            log('measured %s at t = %.1f s (%d grains)' % (name, t, rec['grains_now']))
        out.append(rec)
    return out


def fed_reference(records, shape='sphere'):
    """{grains: mean_interval of single piles' D} over the stored ensemble records of ``shape`` at
    the end of their feed, fed over the paper's disc, at the sizes with two piles or more: the
    ensembles' answer at each size (a size with one pile is a growth curve's last point)."""
    by_n = {}
    for r in records:
        if r['epoch'] == 'feed' and grain_shape(r) == shape and r.get('dip_D') is not None and is_paper_fed(r):
            by_n.setdefault(r['n_grains'], []).append(r['dip_D'])
    return {n: mean_interval(v) for n, v in sorted(by_n.items()) if len(v) >= 2}


def over_runs(curves, min_runs=2):
    """The fed state's D over realisations at each snapshot time the runs share: {time [s]:
    dict(grains, runs, **mean_interval(D))}, in time order, at the times where at least
    ``min_runs`` runs of distinct seeds have a snapshot (runs fed at the same rate hold the same
    grains then).

    A run that shares its seed with one before it in ``curves`` (a branch of the same realisation,
    such as a run resumed at another tolerance) is left out: two branches of one seed are not two
    realisations. Within one run, successive times are one realisation's history, so the rows are
    correlated across times; each row's interval is over the runs at that time only."""
    seen, kept = set(), []
    for name, recs in curves.items():
        seeds = {r.get('seed') for r in recs}
        if not recs or seeds & seen:
            continue
        seen |= seeds
        kept.append((name, recs))
    by_t = {}
    for name, recs in kept:
        for r in recs:
            if r.get('dip_D') is not None and np.isfinite(r['dip_D']):
                by_t.setdefault(round(float(r['time_s']), 3), []).append((name, r))
    out = {}
    for t in sorted(by_t):
        rows = by_t[t]
        if len(rows) >= min_runs:
            out[t] = dict(mean_interval([r['dip_D'] for _, r in rows]),
                          grains=float(np.mean([r['grains_now'] for _, r in rows])), runs=[n for n, _ in rows])
    return out


def _num(x, fmt):
    """``fmt % x``, or a dash for a value that is missing or not finite."""
    return fmt % x if x is not None and np.isfinite(x) else '–'


def growth_table_markdown(curves, reference, pooled=None):
    """A table per run (time, grains, D with its within-pile 95 % interval, the disc's and the
    ring's pressure over the hydrostatic one, the slope), then the fed state over the runs at the
    times they share (``pooled``, from :func:`over_runs`), then the ensembles' reference."""
    lines = ['| run | t [s] | grains | D [95 % over sectors] | p(r < 2d) / hydrostatic | p(2d–4d) / hydrostatic | flank slope |',
             '| --- | --- | --- | --- | --- | --- | --- |']
    for name, recs in curves.items():
        for r in recs:
            ci = r.get('dip_ci95') or [None, None]
            lines.append('| %s | %.1f | %d | %s [%s, %s] | %s | %s | %s |' % (
                name, r['time_s'], r['grains_now'], _num(r.get('dip_D'), '%+.2f'), _num(ci[0], '%+.2f'),
                _num(ci[1], '%+.2f'), _num(r.get('p_disc_over_hydrostatic'), '%.2f'),
                _num(r.get('p_ring_over_hydrostatic'), '%.2f'), _num(r.get('slope_deg'), '%.1f°')))
    if pooled:
        lines += ['', '| long runs, fed state at t | grains | runs (distinct seeds) | mean D ± spread [95 % over runs] |',
                  '| --- | --- | --- | --- |']
        for t, st in pooled.items():
            lines.append('| %.1f s | %.0f | %d | %+.2f ± %.2f [%+.2f, %+.2f] |' % (
                t, st['grains'], st['n'], st['mean'], st['std'], *st['ci95']))
    if reference:
        lines += ['', '| ensemble, end of feed | piles | mean D ± spread [95 %] |', '| --- | --- | --- |']
        for n, st in reference.items():
            lines.append('| %d grains | %d | %+.2f ± %.2f [%+.2f, %+.2f] |' % (n, st['n'], st['mean'], st['std'], *st['ci95']))
    return '\n'.join(lines) + '\n'


def fig_growth(curves, reference, path, pooled=None):
    """D of each run's fed snapshots against the grains they hold (log axis), with their
    within-pile 95 % intervals, the mean over the runs at the times they share (``pooled``, 95 %
    interval over runs), and the ensembles' single piles at the end of their feed (mean and 95 %
    interval over seeds)."""
    fig = pf.new_figure(7.5, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    colours = ['tab:red', 'tab:blue', 'tab:green', 'tab:purple', 'tab:orange']
    for k, (name, recs) in enumerate(curves.items()):
        if not recs:
            continue
        n = np.array([r['grains_now'] for r in recs], dtype=float) * (1 + 0.02 * k)
        D = np.array([r['dip_D'] for r in recs], dtype=float)
        lo = np.array([(r.get('dip_ci95') or [np.nan, np.nan])[0] for r in recs], dtype=float)
        hi = np.array([(r.get('dip_ci95') or [np.nan, np.nan])[1] for r in recs], dtype=float)
        c = colours[k % len(colours)]
        ax.errorbar(n, D, yerr=[D - lo, hi - D], fmt='o-', color=c, ms=4, lw=1, elinewidth=0.6, capsize=2,
                    label='%s, fed snapshots (bars: 95 %% over sectors)' % name)
    if pooled:
        ns = np.array([st['grains'] for st in pooled.values()]) * 1.02
        m = np.array([st['mean'] for st in pooled.values()])
        ci = np.array([st['ci95'] for st in pooled.values()], dtype=float)
        ax.errorbar(ns, m, yerr=[m - ci[:, 0], ci[:, 1] - m], fmt='D', color='k', ms=5, capsize=3, zorder=5,
                    label='long runs: mean over runs of distinct seeds (95 % over runs)')
    if reference:
        ns = np.array(list(reference), dtype=float)
        m = np.array([st['mean'] for st in reference.values()])
        ci = np.array([st['ci95'] for st in reference.values()], dtype=float)
        ax.errorbar(ns * 0.98, m, yerr=[m - ci[:, 0], ci[:, 1] - m], fmt='s', color='k', mfc='none', capsize=3,
                    label='ensembles at the end of their feed (mean, 95 % over seeds)')
    ax.axhline(0, color='k', lw=0.6)
    ax.set_xscale('log')
    ax.set_xlabel('grains in the pile')
    ax.set_ylabel('central dip D (fed pile)')
    ax.set_title('the central dip while the pile grows: fed states of long runs against the ensembles', fontsize=8)
    if not curves and not reference:
        ax.text(0.5, 0.5, 'no fed snapshots and no ensemble records', transform=ax.transAxes, ha='center')
    ax.legend(fontsize=6, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    return pf.save_figure(fig, path)

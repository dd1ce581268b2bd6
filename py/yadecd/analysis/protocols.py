"""Faster pile protocols against the paper's: do the observables move?

The paper's protocol is h = 2e-4 s with the solver converged to a relative residual of 1e-3.
A larger time step or a looser tolerance is a valid faster protocol for a given observable only
if ensembles run with it give the same observable as the paper's ensemble, to within what the
scatter between seeds can tell apart. This module names the settings, runs their ensembles
(through :mod:`ensemble`, one directory per setting) and compares them with the reference
ensemble observable by observable:

* the difference of means, setting minus reference, with Welch's 95 % interval (unequal spreads;
  Welch–Satterthwaite degrees of freedom rounded down, so the interval is slightly conservative);
* that difference in units of the reference's spread between seeds (how large it is against
  the pile-to-pile scatter), and the interval's half-width in the same units (the resolution of
  the test: with 4 seeds against 8 it cannot see a shift smaller than about 1.2 spreads);
* a verdict: ``differs`` when the interval excludes 0, ``same within scatter`` when it contains 0,
  ``not enough seeds`` when a side has fewer than two values.

numpy and matplotlib only: no YADE needed (``scripts/protocol_study.py`` runs the piles).
"""
import json
import math
import os

import numpy as np

from .. import analysis as pa
from ..io import jsonable
from ..runs import ensemble as ens

# name -> (time step [s], tolerance, further pile.py options); 'paper' is the reference
SETTINGS = {
    'paper': (2e-4, 1e-3, ()),
    'h5e-4': (5e-4, 1e-3, ()),
    'h1e-3': (1e-3, 1e-3, ()),
    'tol3e-3': (2e-4, 3e-3, ()),
    'h1e-3_tol3e-3': (1e-3, 3e-3, ()),
    'tol1e-2': (2e-4, 1e-2, ()),
    'h1e-3_tol1e-2': (1e-3, 1e-2, ()),
    'h1e-3_cm': (1e-3, 1e-3, ('--correction-momentum',)),   # the accelerated position correction
    'feed0.4': (2e-4, 1e-3, ('--feed-radius', '0.004')),     # the paper's protocol fed over a 0.4 cm disc (not a faster protocol: the source-size test)
}


def describe(name):
    """A setting in words: 'h = 0.001 s, tolerance 0.001' (and its further options)."""
    dt, tol, extra = SETTINGS[name]
    words = []
    for o in extra:          # a flag starts a phrase, its value joins it: '--feed-radius 0.004' -> 'feed radius 0.004'
        if o.startswith('--') or not words:
            words.append(o.lstrip('-').replace('-', ' '))
        else:
            words[-1] += ' ' + o
    return 'h = %g s, tolerance %g%s' % (dt, tol, ''.join(', ' + w for w in words))


# observables compared: record key -> (label, unit factor, unit)
OBSERVABLES = {
    'slope_deg': ('flank slope', 1.0, 'deg'),
    'packing_fraction': ('packing fraction', 1.0, ''),
    'H_m': ('apex height H', 100.0, 'cm'),
    'base_radius_m': ('base radius', 100.0, 'cm'),
    'dip_D': ('central dip D', 1.0, ''),
    'p_ring_over_hydrostatic': ('p(2d..4d) / hydrostatic', 1.0, ''),
    'floor_load_over_weight': ('floor load / weight', 1.0, ''),
    'law_advantage_deg': ('fossil-layer law: random - layer', 1.0, 'deg'),
    'n_contacts': ('contacts', 1.0, ''),
}


def setting_options(name):
    """pile.py options of a named setting. Raises KeyError naming the known settings."""
    if name not in SETTINGS:
        raise KeyError('unknown protocol setting %r (known: %s)' % (name, ', '.join(SETTINGS)))
    dt, tol, extra = SETTINGS[name]
    return ['--dt', repr(dt), '--tolerance', repr(tol)] + list(extra)


def is_reference(record, n_grains, grain_shape='sphere'):
    """Whether a stored per-run record belongs to the reference of a study at ``n_grains`` grains of
    ``grain_shape``: that size and shape, fed over the paper's disc (records of another feed
    radius are another experiment, whatever their time step)."""
    from .ensemble import grain_shape as shape_of
    from .trends import is_paper_fed
    return record['n_grains'] == n_grains and shape_of(record) == grain_shape and is_paper_fed(record)


def _finite(values):
    return np.array([float(v) for v in values if v is not None and math.isfinite(float(v))], dtype=float)


def welch(test, ref):
    """Difference of means test − ref of two samples with Welch's 95 % interval.

    None and nan values are dropped. Returns a dict: ``delta``, ``se``, ``df`` (Welch–Satterthwaite,
    before rounding down), ``ci95``, ``n_test``, ``n_ref``, ``std_test``, ``std_ref`` (ddof 1).
    With fewer than two values on either side the spread is undefined: se, df and ci95 are nan."""
    a, b = _finite(test), _finite(ref)
    nan = float('nan')
    out = {'n_test': int(len(a)), 'n_ref': int(len(b)), 'delta': nan, 'se': nan, 'df': nan, 'ci95': (nan, nan),
           'std_test': nan, 'std_ref': nan}
    if len(a) == 0 or len(b) == 0:
        return out
    out['delta'] = float(a.mean() - b.mean())
    if len(a) < 2 or len(b) < 2:
        return out
    va, vb = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
    out['std_test'], out['std_ref'] = float(a.std(ddof=1)), float(b.std(ddof=1))
    se = math.sqrt(va + vb)
    out['se'] = se
    if se == 0:  # both samples constant: the difference is exact
        out['df'], out['ci95'] = float('inf'), (out['delta'], out['delta'])
        return out
    df = (va + vb) ** 2 / (va ** 2 / (len(a) - 1) + vb ** 2 / (len(b) - 1))
    q = pa.t_quantile_975(max(1, int(math.floor(df))))
    out['df'] = float(df)
    out['ci95'] = (out['delta'] - q * se, out['delta'] + q * se)
    return out


def verdict(w):
    """'differs', 'same within scatter' or 'not enough seeds' for a :func:`welch` result."""
    lo, hi = w['ci95']
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return 'not enough seeds'
    return 'differs' if lo > 0 or hi < 0 else 'same within scatter'


def compare(test_records, ref_records, keys=None):
    """Observable by observable, a setting's per-run records against the reference's.
    Returns {key: welch dict + ``mean_test``, ``mean_ref``, ``delta_over_spread``,
    ``resolution_over_spread`` (interval half-width / reference spread) and ``verdict``}."""
    out = {}
    for key in keys or OBSERVABLES:
        t = [r.get(key) for r in test_records]
        ref = [r.get(key) for r in ref_records]
        w = welch(t, ref)
        ft, fr = _finite(t), _finite(ref)
        w['mean_test'] = float(ft.mean()) if len(ft) else float('nan')
        w['mean_ref'] = float(fr.mean()) if len(fr) else float('nan')
        spread = w['std_ref']
        ok = math.isfinite(spread) and spread > 0
        w['delta_over_spread'] = w['delta'] / spread if ok else float('nan')
        w['resolution_over_spread'] = (w['ci95'][1] - w['ci95'][0]) / 2 / spread if ok else float('nan')
        w['verdict'] = verdict(w)
        out[key] = w
    return out


def plan_and_run(root, name, n_grains, seeds, relax, repo, jobs=2, log=print, grain_shape='sphere'):
    """Run (or resume) the ensemble of one setting in ``root/name`` (grains of ``grain_shape``)."""
    e = ens.Ensemble(os.path.join(root, name))
    shape = [] if grain_shape == 'sphere' else ['--grain-shape', grain_shape]
    e.plan([n_grains], seeds, relax, setting_options(name) + shape)
    return ens.run_ensemble(e.root, repo, jobs=jobs, log=log)


def wall_times(setting_dir):
    """Wall time [s] of every finished run of a setting's ensemble (from run.json; one thread each,
    two runs at a time on this machine's two cores)."""
    out = {}
    if not os.path.isdir(setting_dir):
        return out
    for name in sorted(os.listdir(setting_dir)):
        p = pa.run_parameters(os.path.join(setting_dir, name))
        if p.get('wall_time_s') is not None and ens.is_done(os.path.join(setting_dir, name)):
            out[name] = float(p['wall_time_s'])
    return out


def table_markdown(results, epoch, n_grains):
    """One table per setting: observables, means, difference, interval, verdict."""
    lines = []
    for name, res in results.items():
        wt = res['wall_s']
        lines.append('### %s (%s), %d grains, %s, %d seeds against %d; wall time per pile %s'
                     % (name, describe(name), n_grains, epoch, res['n_runs'], res['n_ref'],
                        ('%.1f min (%d runs)' % (np.mean(wt) / 60, len(wt))) if wt else 'not measured here'))
        lines.append('')
        lines.append('| observable | setting | paper | difference [95 % interval] | / seed spread | resolution / spread | verdict |')
        lines.append('| --- | --- | --- | --- | --- | --- | --- |')
        for key, w in res['compare'].items():
            label, f, unit = OBSERVABLES[key]
            u = ' [%s]' % unit if unit else ''
            lines.append('| %s%s | %.4g | %.4g | %+.3g [%+.3g, %+.3g] | %+.2f | %.2f | %s |'
                         % (label, u, w['mean_test'] * f, w['mean_ref'] * f, w['delta'] * f, w['ci95'][0] * f,
                            w['ci95'][1] * f, w['delta_over_spread'], w['resolution_over_spread'], w['verdict']))
        lines.append('')
    return '\n'.join(lines)


def figure(results, ref_records, path, epoch, n_grains, keys=('slope_deg', 'packing_fraction', 'dip_D',
                                                                   'p_ring_over_hydrostatic', 'H_m', 'law_advantage_deg'), wall_note='one thread per pile, two piles at a time on two cores'):
    """Each observable's mean and 95 % interval per setting against the wall time per pile,
    the paper's mean ± one seed spread as a band."""
    import matplotlib
    import matplotlib.ticker
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, 3, figsize=(12, 6.5))
    for ax, key in zip(axes.flat, keys):
        label, f, unit = OBSERVABLES[key]
        ref = _finite([r.get(key) for r in ref_records]) * f
        if len(ref) >= 2:
            m, s = ref.mean(), ref.std(ddof=1)
            ax.axhspan(m - s, m + s, color='0.85', label='paper: mean ± seed spread (%d seeds)' % len(ref))
            ax.axhline(m, color='0.5', lw=0.8)
        for name, res in results.items():
            w = res['compare'][key]
            x = np.mean(res['wall_s']) / 60 if res['wall_s'] else float('nan')
            if not math.isfinite(x):
                continue
            y = w['mean_test'] * f
            lo, hi = w['ci95'][0] + w['mean_ref'], w['ci95'][1] + w['mean_ref']
            yerr = [[y - lo * f], [hi * f - y]] if math.isfinite(lo) else None
            ax.errorbar([x], [y], yerr=yerr, fmt='o', capsize=3, label=name + ('' if w['verdict'] != 'differs' else ' (differs)'))
        ax.set_xscale('log')
        ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
        ax.xaxis.set_minor_formatter(matplotlib.ticker.FormatStrFormatter('%g'))
        ax.tick_params(axis='x', which='minor', labelsize=7)
        ax.set_xlabel('wall time per pile [min]')
        ax.set_ylabel('%s%s' % (label, ' [%s]' % unit if unit else ''))
        ax.set_title(label, fontsize=9)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc='lower center', ncol=4, fontsize=8)
    fig.suptitle('%d-grain piles, %s: settings against the paper\'s protocol (bars: the setting\'s mean + Welch 95 %% '
                 'interval of its difference; "differs": in the slope)\nwall time: %s' % (n_grains, epoch, wall_note), fontsize=9)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def save_json(results, path):
    """Write ``results`` to ``path`` as JSON (numpy values made plain: :func:`jsonable`), keys sorted."""
    with open(path, 'w') as fh:
        json.dump(jsonable(results), fh, indent=1, sort_keys=True)


# ---------------------------------------------------------------------------- branches

def paired(rec_ref, rec_branch, spreads, keys=None):
    """One run against its branch (:func:`yadecd.pile.branch`) at one epoch, observable by
    observable. The two share the state at the branch point and the grains fed after it, so
    their difference is the setting's effect plus the divergence that any change makes in a
    granular pile; it is read against ``spreads`` (key -> the spread between seeds of an ensemble,
    the scale on which a protocol matters). Returns {key: dict(ref, branch, delta,
    delta_over_spread, spread)}; missing or non-finite values give nan."""
    out = {}
    for key in keys or OBSERVABLES:
        ra, rb, s = (float(v[0]) if len(v) else float('nan')
                     for v in (_finite([rec_ref.get(key)]), _finite([rec_branch.get(key)]), _finite([spreads.get(key)])))
        s = s if s > 0 else float('nan')
        d = rb - ra
        out[key] = {'ref': ra, 'branch': rb, 'delta': d, 'spread': s, 'delta_over_spread': d / s}
    return out


def ensemble_spreads(summary, group):
    """key -> spread between seeds of group ``group`` (e.g. '2000_feed') of an
    ``ensemble_summary.json`` dict; KeyError naming the groups there when absent."""
    stats = summary['stats']
    if group not in stats:
        raise KeyError('no group %r in the ensemble summary (it has %s)' % (group, ', '.join(sorted(stats))))
    return {k: v['std'] for k, v in stats[group].items() if isinstance(v, dict) and 'std' in v}


def paired_markdown(rows, spread_source):
    """A markdown table of :func:`paired` results: rows is a list of (epoch label, result)."""
    lines = ['| epoch | observable | run | branch | branch − run | in seed spreads (%s) |' % spread_source,
             '| --- | --- | --- | --- | --- | --- |']
    for label, res in rows:
        for key, r in res.items():
            name, factor, unit = OBSERVABLES.get(key, (key, 1.0, ''))
            u = ' ' + unit if unit else ''
            f = (lambda x: 'n/a' if not math.isfinite(x) else '%.4g%s' % (x * factor, u))
            ratio = 'n/a' if not math.isfinite(r['delta_over_spread']) else '%+.2f' % r['delta_over_spread']
            lines.append('| %s | %s | %s | %s | %s | %s |' % (label, name, f(r['ref']), f(r['branch']),
                                                            ('%+.4g%s' % (r['delta'] * factor, u)) if math.isfinite(r['delta']) else 'n/a', ratio))
    return '\n'.join(lines) + '\n'

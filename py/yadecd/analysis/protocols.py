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
from ..pile.protocol import PROTOCOL, feed_time, upgrade
from ..runs import ensemble as ens
from .ensemble import run_record

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


def paired_markdown(rows, spread_source, other='branch'):
    """A markdown table of :func:`paired` results: rows is a list of (epoch label, result);
    ``other`` names the second run's column (a branch, or another run of the same pile)."""
    lines = ['| epoch | observable | run | {0} | {0} − run | in seed spreads ({1}) |'.format(other, spread_source),
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


#: What two runs must share to be one pile under two protocols: the same grains, fed in the same
#: order at the same places (the seed draws them), so that their difference at a shared time is
#: the protocols' effect plus the divergence any change makes in a granular pile.
PAIRED_BY = ('n_grains', 'seed', 'grain_shape', 'd_min', 'd_max', 'rate', 'feed_radius')

#: ``run.json`` entries that record how a run went or how it was kept, not what it computed.
BOOKKEEPING = frozenset(('branches', 'checkpoint_every', 'epochs', 'finished', 'n_paving', 'parallel_min_contacts',
                         'snap_every', 'stop_time', 'stopped_by', 'unconverged_steps', 'vtk', 'wall_time_s',
                         'wall_time_total_s'))


def _same(a, b):
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool) and not isinstance(b, bool):
        return math.isclose(a, b, rel_tol=1e-12, abs_tol=0.0)
    return a == b


def pairing(params_a, params_b):
    """How run b's parameters differ from run a's, for a paired comparison of one pile under two
    protocols: {key: (a's value, b's value)} over the parameters both runs record (or that have a
    protocol default, :data:`yadecd.pile.protocol.PROTOCOL`), renamed ones mapped
    (:func:`yadecd.pile.protocol.upgrade`), :data:`BOOKKEEPING` left out.

    :raises ValueError: naming the parameter, when the two are not one pile (:data:`PAIRED_BY`)."""
    a, b = upgrade(params_a), upgrade(params_b)

    def value(p, k):
        return p.get(k, PROTOCOL.get(k))
    for k in PAIRED_BY:
        if not _same(value(a, k), value(b, k)):
            raise ValueError('not one pile under two protocols: %s is %r in one run and %r in the other'
                             % (k, value(a, k), value(b, k)))
    changes = {}
    for k in sorted((set(a) | set(b)) - BOOKKEEPING - set(PAIRED_BY)):
        if (k in a and k in b) or k in PROTOCOL:
            if not _same(value(a, k), value(b, k)):
                changes[k] = (value(a, k), value(b, k))
    return changes


def compare_runs(run, other, summary, group, times=None, log=print):
    """One pile under two protocols, observable by observable, at the snapshot times the two runs
    share: ``other`` is either a branch of ``run`` (``pile.py --branch-from``, its source named as
    ``run`` is; compared after the branch point, its recorded changes named) or a run of the same
    pile from the start under other settings (:func:`pairing`; compared at every shared time). Differences are read in the
    seed spreads of the ensemble ``group`` of ``summary`` (an ``ensemble_summary.json`` dict): its
    feed-end group for snapshots up to the end of the feed, its relaxed group after it.

    :param times: snapshot times [s] to compare (default: all shared ones after the start).
    :returns: dict ``start_s`` (the branch point, or 0), ``changes`` ({key: (run, other)}),
        ``branch`` (whether ``other`` is a branch), ``epochs`` (list of dicts ``time_s``,
        ``spread_group``, ``result``: :func:`paired`) and ``text`` (a markdown report).
    :raises ValueError: when the runs are not one pile, share no snapshot, or a time is not shared."""
    pr, po = pa.run_parameters(run), pa.run_parameters(other)
    for d, p in ((run, pr), (other, po)):
        if not p:
            raise ValueError('%s holds no pile run (no run.json)' % d)
    last = (po.get('branches') or [{}])[-1]
    if os.path.basename(os.path.normpath(last.get('source', ''))) == os.path.basename(os.path.normpath(run)):
        start, changes, branch = last['time'], last['changes'], True      # other branched from run (by its name: runs are carried)
    else:
        start, changes, branch = 0.0, pairing(pr, po), False
        if not changes:
            raise ValueError('%s and %s ran the same protocol: nothing to compare' % (run, other))
    snaps_a = {round(t, 3): p for t, p in pa.list_snapshots(run)}
    snaps_b = {round(t, 3): p for t, p in pa.list_snapshots(other)}
    shared = sorted(t for t in set(snaps_a) & set(snaps_b) if t > start + 1e-9)
    if times is not None:
        wanted = [round(float(t), 3) for t in times]
        missing = [t for t in wanted if t not in shared]
        if missing:
            raise ValueError('no snapshot at %s in both runs after t = %.3f s (shared: %s)' % (missing, start, shared))
        shared = wanted
    if not shared:
        raise ValueError('the two runs share no snapshot after t = %.3f s' % start)
    t_feed = feed_time(int(po['n_grains']), po.get('rate'), po.get('dt'))
    rows, epochs = [], []
    for t in shared:
        g = '%s_%s' % (group, 'feed' if t <= t_feed + 1e-6 else 'relaxed')
        res = paired(run_record(snaps_a[t], pr), run_record(snaps_b[t], po), ensemble_spreads(summary, g))
        rows.append(('t = %g s%s' % (t, ' (end of feed)' if abs(t - t_feed) < 1e-6 else ''), res))
        epochs.append({'time_s': t, 'spread_group': g, 'result': res})
        log('compared t = %g s (spreads of %s)' % (t, g))
    how = ('Branch %s of %s at t = %.3f s' % (other, run, start) if branch
           else '%s against %s, one pile (seed %s) from the start' % (other, run, po.get('seed')))
    text = ('%s (%s); differences in seed spreads of the %s-grain ensemble.\n\n'
            % (how, ', '.join('%s %s -> %s' % (k, v[0], v[1]) for k, v in changes.items()), group)
            + paired_markdown(rows, '%s grains' % group, 'branch' if branch else 'other'))
    return {'start_s': start, 'changes': changes, 'branch': branch, 'epochs': epochs, 'text': text}

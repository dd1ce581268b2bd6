"""Statistics over an ensemble of sand piles (``scripts/pile_ensemble.py analyse``).

Every finished run of an ensemble directory (:mod:`ensemble`) is analysed at two epochs: the
end of the feed and the end of the relaxation. Per run and epoch, :func:`yadecd.analysis.report.measure`
gives every number; they are cached in ``<out>/runs/<run>_<epoch>.json`` (recomputed when the
snapshot is newer). Per grain count and epoch, every scalar becomes a mean, a spread over seeds and
a 95 % Student-t interval; the change on relaxation is measured seed by seed (paired); the
central dip is pooled over seeds (D = 1 - sum of disc pressures / sum of annulus pressures, a
jackknife over piles); the reciprocity and fossil-layer statistics are pooled over pairs, cuts
and seeds. Here: the per-run records (:func:`run_record`, :func:`collect`, :func:`stored_records`), the
statistics per size (:func:`aggregate`), their table and figures; the grain shapes are compared in
:mod:`.shapes`, the size trends fitted in :mod:`.trends`, and :func:`.ensemble_report.analyse_ensemble`
writes all of it (``ensemble_summary.json``, ``ensemble_table.md``, the figures).

numpy and matplotlib only (no YADE needed).
"""
import json
import os
import time

import numpy as np


from .. import analysis as pa
from ..io import jsonable
from ..pile.protocol import DEFAULTS, feed_time
from ..runs import ensemble as ens
from . import figures as pf, report

CM, DPA = 100.0, 10.0
CACHE_VERSION = 7

# the per-run scalars aggregated over seeds: key in the run record -> (label, unit factor, unit)
SCALARS = {
    'slope_deg': ('flank slope', 1.0, 'deg'),
    'chord_angle_deg': ('chord angle atan((H-2d)/R2)', 1.0, 'deg'),
    'slope_ls_window_deg': ('former estimator (least squares, 15-80 % of H)', 1.0, 'deg'),
    'H_m': ('apex height H', CM, 'cm'),
    'base_radius_m': ('base radius', CM, 'cm'),
    'packing_fraction': ('packing fraction (profile volume)', 1.0, ''),
    'floor_load_over_weight': ('floor load / pile weight', 1.0, ''),
    'wall_load_over_weight': ('load on the wall between paving grains / pile weight', 1.0, ''),
    'dip_D': ('central dip D', 1.0, ''),
    'p_disc_over_hydrostatic': ('p(r < 2d) / hydrostatic', 1.0, ''),
    'p_ring_over_hydrostatic': ('p(2d..4d) / hydrostatic', 1.0, ''),
    'recip_n_pairs': ('reciprocal band pairs per pile', 1.0, ''),
    'recip_rel_median': ('reciprocity |Δ|/scale, median over pairs', 1.0, ''),
    'recip_null_median': ('same, null pairing', 1.0, ''),
    'law_n_cuts': ('cylindrical cuts with a measurable layering per pile', 1.0, ''),
    'law_median_layer_deg': ('T vs local fossil layer, median angle', 1.0, 'deg'),
    'law_median_random_deg': ('T vs random layer (null), median angle', 1.0, 'deg'),
    'law_median_surface_deg': ('T vs free-surface direction (null), median angle', 1.0, 'deg'),
    'law_advantage_deg': ('random - layer, mean angle', 1.0, 'deg'),
    'vmax_m_s': ('fastest grain', CM, 'cm/s'),
    'n_contacts': ('contacts', 1.0, ''),
}
PAIRED = ('slope_deg', 'chord_angle_deg', 'H_m', 'base_radius_m', 'packing_fraction', 'dip_D')


def finite_or_nan(x):
    """``x`` as a float, NaN when it is None or not finite (a record's missing number)."""
    return float(x) if x is not None and np.isfinite(x) else float('nan')


def run_record(snap_path, params):
    """The numbers of one snapshot that the ensemble statistics use (a JSON-ready dict)."""
    snap = pa.load_snapshot(snap_path)
    m = report.measure(snap)
    prof, gp, dip, recip, law = m['prof'], m['gp'], m['dip'], m['recip'], m['law']
    hydro = gp['hydrostatic_Pa']
    free = ~snap['fixed']
    rec = {'snapshot': os.path.basename(snap_path), 'time_s': snap['time'], 'n_grains': int(params.get('n_grains', 0)),
           'grain_shape': params.get('grain_shape', 'sphere'),
           'seed': params.get('seed'), 'dt_s': float(params.get('dt', DEFAULTS['dt'])),
           'feed_radius_m': float(params.get('feed_radius', DEFAULTS['feed_radius'])), 'n_contacts': len(pa.grain_contacts(snap)['i1']),
           'slope_deg': prof['slope_deg'], 'slope_err_deg': prof['slope_err_deg'], 'slope_note': prof['slope_note'],
           'chord_angle_deg': prof['chord_angle_deg'], 'slope_ls_window_deg': prof['slope_ls_window_deg'],
           'H_m': prof['H'], 'd_m': prof['d'], 'base_radius_m': prof['profile_radius'],
           'packing_fraction': gp['rho_bulk'] / snap['rho'],
           'floor_load_over_weight': gp['total_load_N'] / gp['pile_weight_N'] if gp['pile_weight_N'] > 0 else None,
           'wall_load_over_weight': pa.wall_load(snap) / gp['pile_weight_N'] if gp['pile_weight_N'] > 0 else None,
           'hydrostatic_Pa': hydro, 'dip_D': dip['D'], 'dip_ci95': list(dip['ci95']),
           'dip_confidence': dip['confidence_positive'], 'p_disc_Pa': dip['p_disc_Pa'], 'p_ring_Pa': dip['p_ring_Pa'],
           'p_disc_over_hydrostatic': dip['p_disc_Pa'] / hydro if hydro > 0 else None,
           'p_ring_over_hydrostatic': dip['p_ring_Pa'] / hydro if hydro > 0 else None,
           'dip_n_disc': dip['n_disc'], 'dip_note': dip['note'],
           'rings_r_over_d': list(gp['r_mid'] / prof['d']), 'rings_p_over_hydrostatic': list(gp['p_over_hydrostatic']),
           'recip_n_pairs': recip['n_pairs'], 'recip_rel_median': recip['rel_median'],
           'recip_null_median': recip['rel_null_median'], 'recip_corr': recip['corr'],
           'recip_rel': list(recip['rel']), 'recip_null': list(recip['rel_null']),
           'law_n_cuts': law['n_cuts'], 'law_median_layer_deg': law['median_layer_deg'],
           'law_median_random_deg': law['median_random_deg'], 'law_median_surface_deg': law['median_surface_deg'],
           'law_advantage_deg': law['advantage_deg'], 'law_angle_layer': list(law['angle_layer_deg']),
           'law_angle_random': list(law['angle_random_layer_deg']), 'law_r_over_R': list(law['r'] / prof['profile_radius']),
           'vmax_m_s': float(np.linalg.norm(snap['vel'][free], axis=1).max()) if free.any() else 0.0}
    return jsonable(rec)


def record_file(run, epoch):
    """File name of a run's record at one epoch, ``<run>_<epoch>.json``: the name the ensemble's
    cache, the stored records (:func:`stored_records`) and finished runs use."""
    return '%s_%s.json' % (run, epoch)


def labelled_record(snap_path, params, run, epoch):
    """:func:`run_record` of one snapshot with the run's name, the epoch and :data:`CACHE_VERSION`:
    the record as it is stored."""
    rec = run_record(snap_path, params)
    rec.update(run=run, epoch=epoch, cache_version=CACHE_VERSION)
    return rec


def _epochs_of(run_dir, params):
    """(label, path) of the feed-end and relaxed snapshots of a run (those that exist)."""
    snaps = pa.list_snapshots(run_dir)
    if not snaps:
        return []
    t_feed = feed_time(int(params['n_grains']), params.get('rate', DEFAULTS['rate']), params.get('dt', DEFAULTS['dt']))
    out = []
    feed = min(snaps, key=lambda s: abs(s[0] - t_feed))
    if abs(feed[0] - t_feed) < 0.01:
        out.append(('feed', feed[1]))
    last = snaps[-1]
    if params.get('relax', 0) > 0 and last[0] > t_feed + 0.5 * params['relax']:
        out.append(('relaxed', last[1]))
    return out


def collect(root, out_dir, log=print):
    """Per-run records of every finished run, from the cache when it is fresh. Returns
    (records list, failed runs dict name -> error tail, unfinished names)."""
    e = ens.Ensemble(root)
    cache = os.path.join(out_dir, 'runs')
    os.makedirs(cache, exist_ok=True)
    records, failed, unfinished = [], {}, []
    names = sorted(os.listdir(e.root))
    for name in names:
        run_dir = os.path.join(e.root, name)
        if not os.path.isdir(run_dir) or not os.path.exists(os.path.join(run_dir, 'run.json')):
            continue
        rec_status = e.runs().get(name, {})
        if not ens.is_done(run_dir):
            if rec_status.get('state') == 'failed':
                failed[name] = (rec_status.get('error') or '').strip().splitlines()[-1:] or ['failed']
            else:
                unfinished.append(name)
            continue
        params = pa.run_parameters(run_dir)
        for label, path in _epochs_of(run_dir, params):
            cpath = os.path.join(cache, record_file(name, label))
            if os.path.exists(cpath) and os.path.getmtime(cpath) >= os.path.getmtime(path):
                with open(cpath) as f:
                    rec = json.load(f)
                if rec.get('cache_version') == CACHE_VERSION:
                    records.append(rec)
                    continue
            t0 = time.time()
            rec = labelled_record(path, params, name, label)
            with open(cpath, 'w') as f:
                json.dump(rec, f)
            records.append(rec)
            log('analysed %s at %s (t = %.2f s) in %.1f s' % (name, label, rec['time_s'], time.time() - t0))
    return records, failed, unfinished


def _dt(record):
    """The record's time step [s] (records written before it was kept are the paper's 2e-4 s)."""
    return record.get('dt_s', DEFAULTS['dt'])


def feed_radius_of(record):
    """The record's feed radius [m] (records written before it was kept used the paper's 0.8 cm)."""
    return record.get('feed_radius_m', DEFAULTS['feed_radius'])


def size_labels(records):
    """{n_grains: label}: the grain count, with the time step where a size's runs did not use the
    paper's h (the faster protocol of docs/pile.md) and the feed radius where it is not the paper's
    0.8 cm, so that no table or figure mixes them silently."""
    out = {}
    for n in sorted({r['n_grains'] for r in records}):
        mine = [r for r in records if r['n_grains'] == n]
        dts, feeds = sorted({_dt(r) for r in mine}), sorted({feed_radius_of(r) for r in mine})
        notes = [] if dts == [DEFAULTS['dt']] else ['h = %s s' % ', '.join('%g' % d for d in dts)]
        if feeds != [DEFAULTS['feed_radius']]:
            notes.append('feed radius %s cm' % ', '.join('%g' % (100 * f) for f in feeds))
        out[n] = '%d (%s)' % (n, '; '.join(notes)) if notes else str(n)
    return out


def _group(records):
    """{(n_grains, epoch): [records sorted by seed]}."""
    groups = {}
    for r in records:
        groups.setdefault((r['n_grains'], r['epoch']), []).append(r)
    for v in groups.values():
        v.sort(key=lambda r: r['seed'])
    return groups


def _pooled(values_lists):
    v = np.array([x for lst in values_lists for x in lst if x is not None and np.isfinite(x)], dtype=float)
    if not len(v):
        return {'n': 0, 'median': None, 'q25': None, 'q75': None}
    return {'n': int(len(v)), 'median': float(np.median(v)), 'q25': float(np.quantile(v, 0.25)),
            'q75': float(np.quantile(v, 0.75))}


def aggregate(records):
    """Ensemble statistics per grain count and epoch, and the paired relaxation changes."""
    groups = _group(records)
    out = {}
    for (n, epoch), recs in sorted(groups.items()):
        g = {'n_runs': len(recs), 'seeds': [r['seed'] for r in recs]}
        for key in SCALARS:
            g[key] = pa.mean_interval([finite_or_nan(r.get(key)) for r in recs])
        g['slope_measured_runs'] = int(sum(1 for r in recs if r.get('slope_deg') is not None))
        g['slope_notes'] = sorted({r['slope_note'] for r in recs if r.get('slope_note')})
        disc = np.array([finite_or_nan(r['p_disc_Pa']) for r in recs])
        ring = np.array([finite_or_nan(r['p_ring_Pa']) for r in recs])
        ok = np.isfinite(disc) & np.isfinite(ring)
        g['dip_pooled'] = pa.jackknife_ratio_dip(disc[ok], ring[ok])
        g['reciprocity_pooled'] = {'true': _pooled([r['recip_rel'] for r in recs]),
                                   'null': _pooled([r['recip_null'] for r in recs]),
                                   'pairs_per_pile': pa.mean_interval([r['recip_n_pairs'] for r in recs])}
        g['fossil_law_pooled'] = {'layer': _pooled([r['law_angle_layer'] for r in recs]),
                                  'random': _pooled([r['law_angle_random'] for r in recs]),
                                  'cuts_per_pile': pa.mean_interval([r['law_n_cuts'] for r in recs])}
        for zone, inside in (('centre', lambda x: x < 0.5), ('flank', lambda x: x >= 0.5)):
            pick = lambda key: [[a for a, x in zip(r[key], r['law_r_over_R']) if x is not None and inside(x)] for r in recs]
            lay, rnd = pick('law_angle_layer'), pick('law_angle_random')
            per_pile = [np.mean(np.array(rr, float) - np.array(ll, float)) if ll else float('nan') for ll, rr in zip(lay, rnd)]
            g['fossil_law_pooled'][zone] = {'layer': _pooled(lay), 'random': _pooled(rnd),
                                            'advantage_over_piles': pa.mean_interval(per_pile)}
        out['%d_%s' % (n, epoch)] = g
    changes = {}
    for n in sorted({k[0] for k in groups}):
        feed = {r['seed']: r for r in groups.get((n, 'feed'), [])}
        relaxed = {r['seed']: r for r in groups.get((n, 'relaxed'), [])}
        both = sorted(set(feed) & set(relaxed))
        if not both:
            continue
        changes[str(n)] = {key: pa.mean_interval([finite_or_nan(relaxed[s].get(key)) - finite_or_nan(feed[s].get(key)) for s in both])
                           for key in PAIRED}
        changes[str(n)]['seeds'] = both
    return out, changes


def _fmt(stat, factor=1.0, digits=2):
    if not stat or stat['n'] == 0 or not np.isfinite(stat['mean']):
        return 'n/a'
    if stat['n'] < 2 or not np.isfinite(stat['sem']):
        return ('%.' + str(digits) + 'f') % (stat['mean'] * factor)
    lo, hi = stat['ci95']
    return ('%.{0}f ± %.{0}f [%.{0}f, %.{0}f]'.format(digits)) % (stat['mean'] * factor, stat['std'] * factor,
                                                              lo * factor, hi * factor)


def _q(x, digits=3):
    return 'n/a' if x is None or not np.isfinite(x) else ('%.' + str(digits) + 'f') % x


def table_markdown(stats, changes, labels=None):
    """The ensemble table: one column per (size, epoch), mean ± spread over seeds [95 % interval];
    ``labels`` ({n_grains: text}, :func:`size_labels`) names the sizes."""
    cols = sorted(stats, key=lambda k: (int(k.split('_')[0]), k.split('_')[1] != 'feed'))
    name = lambda c: (labels or {}).get(int(c.split('_')[0]), c.split('_')[0])
    lines = ['| quantity | ' + ' | '.join('%s grains, %s (%d seed%s)' % (name(c), c.split('_')[1], stats[c]['n_runs'],
                                                                       '' if stats[c]['n_runs'] == 1 else 's')
                                          for c in cols) + ' |',
             '| --- |' + ' --- |' * len(cols)]
    for key, (label, factor, unit) in SCALARS.items():
        digits = 0 if key in ('n_contacts', 'recip_n_pairs', 'law_n_cuts') else (3 if unit == '' else 2)
        lines.append('| %s%s | ' % (label, ' [%s]' % unit if unit else '') +
                     ' | '.join(_fmt(stats[c][key], factor, digits) for c in cols) + ' |')
    lines.append('| pooled dip D (jackknife over piles) | ' + ' | '.join(
        '%.3f [%.3f, %.3f], confidence of a dip %.0f%%' % ((stats[c]['dip_pooled']['D'],) + tuple(stats[c]['dip_pooled']['ci95'])
                                                           + (100 * stats[c]['dip_pooled']['confidence_positive'],))
        if np.isfinite(stats[c]['dip_pooled']['se']) else 'n/a' for c in cols) + ' |')
    for c in cols:
        law, rec = stats[c]['fossil_law_pooled'], stats[c]['reciprocity_pooled']
        lines.append('')
        lines.append('%s grains, %s: reciprocity pooled over pairs: median %s (quartiles %s-%s, %d pairs), null pairing %s; '
                     % (name(c), c.split('_')[1], _q(rec['true']['median']), _q(rec['true']['q25']),
                        _q(rec['true']['q75']), rec['true']['n'], _q(rec['null']['median'])) +
                     'fossil-layer law, angle to the local layer / to a random layer (median over cuts), random - layer '
                     '(mean over piles, 95 %% interval): centre r < R/2 %s° / %s°, %s; flank %s° / %s°, %s'
                     % (_q(law['centre']['layer']['median'], 1), _q(law['centre']['random']['median'], 1),
                        _fmt(law['centre']['advantage_over_piles'], 1.0, 1),
                        _q(law['flank']['layer']['median'], 1), _q(law['flank']['random']['median'], 1),
                        _fmt(law['flank']['advantage_over_piles'], 1.0, 1)))
    lines.append('')
    if changes:
        lines.append('Change on relaxation (relaxed - end of feed, same seed): mean ± spread [95 % interval]')
        lines.append('')
        lines.append('| grains | ' + ' | '.join(PAIRED) + ' |')
        lines.append('| --- |' + ' --- |' * len(PAIRED))
        for n, ch in changes.items():
            lines.append('| %s (%d seeds) | ' % ((labels or {}).get(int(n), n), len(ch['seeds'])) + ' | '.join(
                _fmt(ch[k], CM if k in ('H_m', 'base_radius_m') else 1.0, 3 if k in ('packing_fraction', 'dip_D') else 2)
                for k in PAIRED) + ' |')
    return '\n'.join(lines) + '\n'


# ---------------------------------------------------------------------------------------------
# figures

def stat_series(stats, key, epoch, factor=1.0):
    """(grain counts, means, interval lows, interval highs) of one scalar of :func:`aggregate`'s
    statistics at ``epoch``, sorted by size, times ``factor`` (a size without a finite mean is left
    out; a missing interval bound is the mean)."""
    ns, m, lo, hi = [], [], [], []
    for k, g in stats.items():
        n, ep = int(k.split('_')[0]), k.split('_')[1]
        st = g[key] if key in g else None
        if ep != epoch or not st or st['n'] == 0 or not np.isfinite(st['mean']):
            continue
        ns.append(n)
        m.append(st['mean'] * factor)
        lo.append((st['ci95'][0] if np.isfinite(st['ci95'][0]) else st['mean']) * factor)
        hi.append((st['ci95'][1] if np.isfinite(st['ci95'][1]) else st['mean']) * factor)
    order = np.argsort(ns)
    return tuple(np.array(x)[order] for x in (ns, m, lo, hi))


def size_axis(ax, records):
    """Log x axis ticked at the ensemble's grain counts."""
    sizes = sorted({r['n_grains'] for r in records})
    ax.set_xscale('log')
    ax.set_xticks(sizes)
    labels = size_labels(records)
    # one line per item of a label, so that the labels of neighbouring sizes do not run into each other
    ax.set_xticklabels([labels[n].replace(' (', '\n(').replace(', ', ',\n').replace('; ', ';\n') for n in sizes], fontsize=8)
    ax.minorticks_off()
    if sizes:
        ax.set_xlim(sizes[0] / 1.4, sizes[-1] * 1.4)


def fig_slope(stats, records, path):
    """Slope and chord angle against pile size, end of feed and relaxed, with 95 % intervals and
    every seed's value; the paper's 26°."""
    fig = pf.new_figure(9, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    styles = {('slope_deg', 'feed'): ('tab:blue', 'o', -0.03), ('slope_deg', 'relaxed'): ('tab:orange', 's', 0.03),
              ('chord_angle_deg', 'feed'): ('tab:blue', '^', -0.015), ('chord_angle_deg', 'relaxed'): ('tab:orange', 'v', 0.015)}
    for (key, epoch), (colour, marker, shift) in styles.items():
        ns, m, lo, hi = stat_series(stats, key, epoch)
        if not len(ns):
            continue
        x = ns * (1 + shift)
        filled = key == 'slope_deg'
        ax.errorbar(x, m, yerr=[m - lo, hi - m], fmt=marker, color=colour, mfc=colour if filled else 'none', capsize=3,
                    label='%s, %s (mean, 95%% interval)' % ('flank slope' if filled else 'chord angle', epoch))
        for r in records:
            if r['epoch'] == epoch and r.get(key) is not None:
                ax.plot(r['n_grains'] * (1 + shift), r[key], '.', color=colour, ms=2, alpha=0.6)
    unmeasured = sorted({r['n_grains'] for r in records if r.get('slope_deg') is None})
    if unmeasured:
        ax.text(0.02, 0.03, 'no straight flank (too small) at %s grains: chord angle only' % ', '.join(map(str, unmeasured)),
                transform=ax.transAxes, fontsize=7)
    ax.axhline(26, color='k', ls='--', lw=0.8, label='paper (14 000 grains)')
    size_axis(ax, records)
    ax.set_xlabel('grains')
    ax.set_ylabel('angle [deg]')
    ax.set_title('free-surface slope against pile size (dots: single seeds)', fontsize=9)
    ax.legend(fontsize=6, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    return pf.save_figure(fig, path)


def single_pile_dips(records, epoch):
    """(grains, D, low, high) of the sizes that have exactly one pile at ``epoch``, with that
    pile's own 95 % interval (over sectors): no spread over seeds exists for them."""
    by_size = {}
    for r in records:
        if r['epoch'] == epoch and r.get('dip_D') is not None:
            by_size.setdefault(r['n_grains'], []).append(r)
    out = []
    for n, rs in sorted(by_size.items()):
        ci = rs[0].get('dip_ci95') if len(rs) == 1 else None
        if ci is not None and len(ci) == 2 and all(c is not None and np.isfinite(c) for c in ci):
            out.append((n, rs[0]['dip_D'], ci[0], ci[1]))
    return out


def fig_dip(stats, records, path):
    """Central dip D per pile and pooled per size with 95 % intervals; D = 0 is no dip."""
    fig = pf.new_figure(7, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    for epoch, colour, shift in (('feed', 'tab:blue', -0.03), ('relaxed', 'tab:orange', 0.03)):
        pts = [(r['n_grains'], r['dip_D']) for r in records if r['epoch'] == epoch and r.get('dip_D') is not None]
        if pts:
            ax.plot([p[0] * (1 + 2 * shift) for p in pts], [p[1] for p in pts], '.', color=colour, ms=3, alpha=0.6)
        xs, ds, los, his = [], [], [], []
        for k, g in stats.items():
            n, ep = int(k.split('_')[0]), k.split('_')[1]
            d = g['dip_pooled']
            if ep == epoch and np.isfinite(d['se']):
                xs.append(n * (1 + shift)), ds.append(d['D']), los.append(d['ci95'][0]), his.append(d['ci95'][1])
        if xs:
            xs, ds, los, his = map(np.array, (xs, ds, los, his))
            ax.errorbar(xs, ds, yerr=[ds - los, his - ds], fmt='o', color=colour, capsize=3,
                        label='%s: pooled over seeds, 95%% interval' % epoch)
        lone = single_pile_dips(records, epoch)   # a size with one pile: that pile's own interval
        if lone:
            x, d, lo, hi = map(np.array, zip(*lone))
            ax.errorbar(x * (1 + 2 * shift), d, yerr=[d - lo, hi - d], fmt='d', color=colour, mfc='none', capsize=3,
                        ls='none', elinewidth=0.8, label='%s: one pile, its own 95%% interval (sectors)' % epoch)
    ax.axhline(0, color='k', lw=0.8)
    size_axis(ax, records)
    ax.set_xlabel('grains')
    ax.set_ylabel('D = 1 - p(r < 2d) / p(2d ≤ r < 4d)')
    ax.set_title('central dip of the floor pressure (dots: single piles; D > 0 is a dip)', fontsize=9)
    ax.legend(fontsize=7)
    return pf.save_figure(fig, path)


def fig_pressure(records, path, epoch='relaxed'):
    """Floor pressure over the hydrostatic ρ_bulk·g·H per ring (rings 2 d wide, r in mean
    diameters), mean over seeds with 95 % intervals, one curve per pile size."""
    fig = pf.new_figure(7, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    sizes = sorted({r['n_grains'] for r in records if r['epoch'] == epoch})
    for k, n in enumerate(sizes):
        recs = [r for r in records if r['n_grains'] == n and r['epoch'] == epoch]
        m = min(len(r['rings_p_over_hydrostatic']) for r in recs)
        x = np.array(recs[0]['rings_r_over_d'][:m])
        rows = np.array([[finite_or_nan(v) for v in r['rings_p_over_hydrostatic'][:m]] for r in recs])
        st = [pa.mean_interval(rows[:, j]) for j in range(m)]
        mean = np.array([s_['mean'] for s_ in st])
        lo = np.array([s_['ci95'][0] for s_ in st])
        hi = np.array([s_['ci95'][1] for s_ in st])
        shift = (k - (len(sizes) - 1) / 2) * 0.12
        ax.errorbar(x + shift, mean, yerr=[mean - lo, hi - mean], fmt='o-', ms=3, capsize=2,
                    label='%d grains (%d piles)' % (n, len(recs)))
    ax.axhline(1, color='k', ls=':', lw=0.8, label='hydrostatic ρ_bulk g H')
    ax.axvspan(0, 2, color='0.9', zorder=0)
    ax.set_xlabel('distance to the axis r / d (ring centres; grey: the central disc of D)')
    ax.set_ylabel('floor pressure / (ρ_bulk g H)')
    ax.set_title('floor pressure per ring, %s piles: mean over seeds, 95 %% intervals' % epoch, fontsize=9)
    ax.legend(fontsize=7)
    return pf.save_figure(fig, path)


def fig_cuts(records, path):
    """Pooled over the largest size's relaxed piles: reciprocity relative differences (true
    pairs against the null pairing) and the fossil-layer law angles (local layer against a
    random one)."""
    fig = pf.new_figure(10, 4)
    if not records:
        ax = fig.add_subplot(1, 1, 1)
        ax.text(0.5, 0.5, 'no analysed run', ha='center', va='center')
        ax.set_axis_off()
        return pf.save_figure(fig, path)
    n = max(r['n_grains'] for r in records)
    epoch = 'relaxed' if any(r['epoch'] == 'relaxed' and r['n_grains'] == n for r in records) else 'feed'
    recs = [r for r in records if r['n_grains'] == n and r['epoch'] == epoch]
    pool = lambda key: np.array([x for r in recs for x in r[key] if x is not None and np.isfinite(x)])
    ax = fig.add_subplot(1, 2, 1)
    true, null = pool('recip_rel'), pool('recip_null')
    if len(true):
        bins = np.linspace(0, 2, 31)
        ax.hist(np.clip(true, 0, 2), bins=bins, color='k', alpha=0.7, density=True,
                label='crossing pairs (%d): median %.3f' % (len(true), np.median(true)))
        if len(null):
            ax.hist(np.clip(null, 0, 2), bins=bins, histtype='step', color='tab:red', lw=1.2, density=True,
                    label='null pairing: median %.3f' % np.median(null))
        ax.legend(fontsize=7)
    else:
        ax.text(0.5, 0.5, 'no pair of bands fits inside these piles', ha='center', va='center', transform=ax.transAxes)
    ax.set_xlabel("|n·T' - n'·T| / sqrt(|T||T'|)")
    ax.set_title('reciprocal cuts, %d piles of %d grains (%s)' % (len(recs), n, epoch), fontsize=9)
    bx = fig.add_subplot(1, 2, 2)
    lay, rnd = pool('law_angle_layer'), pool('law_angle_random')
    if len(lay):
        bins = np.linspace(0, 45, 19)
        bx.hist(np.clip(lay, 0, 45), bins=bins, color='tab:purple', alpha=0.7, density=True,
                label='local fossil layer (%d cuts): median %.0f°' % (len(lay), np.median(lay)))
        bx.hist(np.clip(rnd, 0, 45), bins=bins, histtype='step', color='k', lw=1.2, density=True,
                label='random layer (null): median %.0f°' % np.median(rnd))
        bx.legend(fontsize=7)
    else:
        bx.text(0.5, 0.5, 'no cut with a measurable layering', ha='center', va='center', transform=bx.transAxes)
    bx.set_xlabel('angle between T and the layer [deg] (45: 45 or more)')
    bx.set_title('fossil-layer law (Fig. 4)', fontsize=9)
    return pf.save_figure(fig, path)


def stored_records(directories, known):
    """Per-run records kept from earlier analyses (``<run>_<epoch>.json`` files, e.g. the ones
    committed in docs/data/ensemble_runs/) for runs not in ``known`` (a set of (run, epoch)):
    the statistics can then grow by new seeds without the old runs' snapshots."""
    out = []
    for d in directories or ():
        for name in sorted(os.listdir(d)):
            if not name.endswith('.json'):
                continue
            with open(os.path.join(d, name)) as f:
                rec = json.load(f)
            if rec.get('cache_version') != CACHE_VERSION:
                raise ValueError('%s was written by another version of the analysis (%s, now %s): re-analyse its run'
                                 % (name, rec.get('cache_version'), CACHE_VERSION))
            if (rec['run'], rec['epoch']) not in known:
                out.append(rec)
    return out


def grain_shape(record):
    """The grain shape of a record ('sphere' for records written before shapes were kept)."""
    return record.get('grain_shape', 'sphere')

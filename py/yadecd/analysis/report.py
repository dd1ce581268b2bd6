"""The whole analysis of one pile: :func:`measure` computes every observable of a snapshot,
:func:`analyse` writes the figures of a run with a ``summary.json`` of every number, and
:func:`paper_table` sets them beside the paper's.
"""

import json
import math
import os
import numpy as np

from .. import analysis as pa
from ..io import jsonable
from .figures import CM, DPA, fig_cylindrical, fig_force_chains, fig_ground_pressure, fig_orientation, fig_profile, fig_reciprocal, fig_slices, fig_speed


def _collect(source):
    """(time [s], path) of the snapshots of a run directory, a snapshot file or a list of
    files, sorted by time."""
    if isinstance(source, (str, os.PathLike)):
        if os.path.isdir(source):
            return pa.list_snapshots(source)
        source = [source]
    found = []
    for path in source:
        m = pa.SNAP_NAME.match(os.path.basename(str(path)))
        t = float(m.group(1)) if m else pa.load_snapshot(path)['time']
        found.append((t, str(path)))
    return sorted(found)


def _pick_epoch(entries, epoch):
    """Index of the snapshot nearest to ``epoch`` [s] (the last one when None)."""
    if epoch is None:
        return len(entries) - 1
    return int(np.argmin([abs(t - epoch) for t, _ in entries]))


def _default_fossils(snap, quantiles=((0.30, 0.36), (0.62, 0.68))):
    """Fossil intervals [s] between quantiles of the birth times of the snapshot's grains (the
    paper's layer, born at 15.5-18.7 s of 72 s, sits near the 0.2-0.26 fraction of the run)."""
    birth = snap['birth'][~snap['fixed']]
    if len(birth) == 0:
        return [(0.0, 0.0)]
    return [tuple(float(np.quantile(birth, q)) for q in pair) for pair in quantiles]


def _slice_epochs(entries, main, t_fossil_end, max_panels):
    """Indices of up to ``max_panels`` snapshots for Figure 2, evenly spread among those taken
    after the fossil layer was complete and not after the analysed one (always including it)."""
    after = [k for k, (t, _) in enumerate(entries) if t >= t_fossil_end and k <= main] or [main]
    pick = np.unique(np.round(np.linspace(0, len(after) - 1, min(max_panels, len(after)))).astype(int))
    return [after[k] for k in pick]


def _surface_height(prof, r):
    """Height of the free surface above the floor at radii r [m]: the median profile,
    interpolated (0 beyond it)."""
    ok = np.isfinite(prof['h'])
    if not ok.any():
        return np.zeros_like(np.asarray(r, dtype=float))
    return np.interp(r, prof['r'][ok], prof['h'][ok], right=0.0)


def _pile_grids(prof, step, inner):
    """Grid (radii, heights) [m] with spacing ``step``, radii from ``inner`` to the pile's
    radius, heights (absolute z) from ``inner`` above the floor to the apex."""
    R, H, zf = prof['profile_radius'], prof['H'], prof['z_floor']
    if not (np.isfinite(R) and R > inner):
        R = np.nanmax(prof['r'])
    radii = np.arange(inner, R, step)
    heights = zf + np.arange(inner, max(H, 2 * inner), step)
    return radii, heights


def _reciprocal_centres(prof, length, clearance):
    """Centres (r, z) [m] for the reciprocal-cut pairs, on a grid of spacing ``length``/2, where
    every band of the pair lies inside the pile: at least length/2 + ``clearance`` from the axis,
    the floor and the free surface (the median profile)."""
    margin = 0.5 * length + clearance
    radii, heights = _pile_grids(prof, length / 2, margin)
    top = _surface_height(prof, radii)
    return [(r, z) for r, hs in zip(radii, top) for z in heights
            if z - prof['z_floor'] >= margin and z - prof['z_floor'] + margin <= hs]


def measure(snap, ring_width=None, n_sectors=8, band_length=None, band_height=None, clearance=None,
            layer_radius=None):
    """Every measurement of the pile analysis on one snapshot, no figure (lengths default to
    multiples of the mean diameter d: rings 2 d, reciprocal bands 3 d long with d/2 of clearance
    inside the pile, cylindrical bands 3 d high, fossil layers fitted within 2 d).

    :returns: dict ``prof`` (:func:`yadecd.analysis.profile_and_slope`), ``gp`` (ground pressure),
        ``dip`` (:func:`yadecd.analysis.central_dip`), ``recip`` (reciprocal cuts), ``cyl``
        (cylindrical cuts with the grid ``inside``), ``law`` (:func:`yadecd.analysis.fossil_law`),
        ``hist`` (contact orientations), ``settings``."""
    d = pa.mean_diameter(snap)
    ring_width = ring_width or 2 * d
    band_length = band_length or 3 * d
    band_height = band_height or 3 * d
    clearance = 0.5 * d if clearance is None else clearance
    layer_radius = layer_radius or 2 * d
    prof = pa.profile_and_slope(snap, n_sectors=n_sectors)
    gp = pa.ground_pressure(snap, ring_width, n_sectors=n_sectors, profile=prof)
    dip = pa.central_dip(snap, n_sectors=n_sectors, d=d)
    recip = pa.reciprocal_cuts(snap, pa.reciprocal_pairs(_reciprocal_centres(prof, band_length, clearance),
                                                         length=band_length))
    # cuts one third of a band height apart (overlapping): the law is tested on all of them (more
    # cuts per pile; the ensemble's interval is over piles, which are independent), Figure 4
    # draws every other one
    radii, heights = _pile_grids(prof, band_height / 3, band_height / 2)
    fine = pa.cylindrical_cut_directions(snap, radii, heights, band_height)
    fine['inside'] = fine['z'] - prof['z_floor'] + band_height / 2 < _surface_height(prof, fine['r'])
    law = pa.fossil_law(snap, fine, layer_radius, prof['slope_deg'])
    cyl = {k: (v[::2, ::2] if isinstance(v, np.ndarray) else v) for k, v in fine.items()}
    hist = pa.contact_orientation_histogram(snap)
    return {'prof': prof, 'gp': gp, 'dip': dip, 'recip': recip, 'cyl': cyl, 'law': law, 'hist': hist,
            'settings': {'ring_width_m': ring_width, 'n_sectors': n_sectors, 'band_length_m': band_length,
                         'band_height_m': band_height, 'band_clearance_m': clearance,
                         'layer_radius_m': layer_radius}}


def analyse(source, out_dir, epoch=None, fossil=None, half_thickness=0.01, ring_width=None,
            n_sectors=8, band_length=None, band_height=None, max_panels=4):
    """Run the whole sand-pile analysis and write every figure plus ``summary.json``.

    :param source: run directory (``snap_<time>.npz`` files, optional ``run.json``), one snapshot
        file or a list of snapshot files.
    :param out_dir: output directory (created).
    :param epoch: time [s] of the snapshot analysed (nearest available; default the last).
    :param fossil: (t1, t2) [s] or a list of such intervals; the first is Figure 2's layer, all
        are outlined in Figure 4. Default: two intervals between quantiles of the birth times.
    :param half_thickness: half thickness of the slice |y| < half_thickness [m] (paper: 1 cm).
    :param ring_width: ground-pressure ring width [m] (default 2 mean diameters).
    :param n_sectors: azimuthal sectors for slope and pressure errors.
    :param band_length: reciprocal-cut band length [m] (default 3 mean diameters).
    :param band_height: cylindrical-cut band height [m] (default 3 mean diameters).
    :param max_panels: at most this many epochs in Figure 2.
    :returns: the summary dict (also written to ``out_dir/summary.json``).
    """
    entries = _collect(source)
    if not entries:
        raise FileNotFoundError('no snapshot found in %r' % (source,))
    os.makedirs(out_dir, exist_ok=True)
    main = _pick_epoch(entries, epoch)
    snap = pa.load_snapshot(entries[main][1])
    fossils = _fossil_list(fossil) or _default_fossils(snap)
    d = pa.mean_diameter(snap)
    ring_width = ring_width or 2 * d
    band_length = band_length or 3 * d
    band_height = band_height or 3 * d

    m = measure(snap, ring_width=ring_width, n_sectors=n_sectors, band_length=band_length,
                band_height=band_height)
    levels = pa.speed_levels(snap)
    panels = _slice_epochs(entries, main, fossils[0][1], max_panels)
    panel_snaps = [snap if k == main else pa.load_snapshot(entries[k][1]) for k in panels]

    out = lambda name: os.path.join(out_dir, name)
    figures = [fig_profile(m['prof'], out('fig0_profile.png')),
               fig_speed(snap, out('fig1_speed.png'), levels=levels),
               fig_slices(panel_snaps, fossils[0], out('fig2_slices.png'), half_thickness),
               fig_reciprocal(m['recip'], out('fig3_reciprocal_cuts.png')) if m['recip']['n_pairs'] else None,
               fig_cylindrical(snap, m['cyl'], fossils, out('fig4_cylindrical_cuts.png'), half_thickness,
                               law=m['law']),
               fig_ground_pressure(m['gp'], out('fig5_ground_pressure.png'), dip=m['dip']),
               fig_orientation(m['hist'], out('fig6_contact_orientations.png')),
               fig_force_chains(snap, out('fig7_force_chains.png'), half_thickness)]
    skipped = {}
    if not m['recip']['n_pairs']:
        skipped['fig3_reciprocal_cuts'] = ('no pair of bands fits inside the pile: bands %.2g cm long need a pile about '
                                           '%.1f cm thick (%d grain diameters); none written' %
                                           (m['settings']['band_length_m'] * CM,
                                            (m['settings']['band_length_m'] + 2 * m['settings']['band_clearance_m']) * CM,
                                            round((m['settings']['band_length_m'] + 2 * m['settings']['band_clearance_m'])
                                                  / m['prof']['d'])))
        stale = out('fig3_reciprocal_cuts.png')
        if os.path.exists(stale):
            os.remove(stale)
    summary = _summary(snap, m, levels, fossils, [entries[k][0] for k in panels],
                       [os.path.basename(f) for f in figures if f])
    summary['figures_skipped'] = skipped
    summary['settings'] = dict(m['settings'], half_thickness_m=half_thickness)
    if isinstance(source, (str, os.PathLike)) and os.path.isdir(source):
        summary['run_parameters'] = pa.run_parameters(source)
    summary = jsonable(summary)
    with open(out('summary.json'), 'w') as f:
        json.dump(summary, f, indent=1, sort_keys=True)
    with open(out('paper_table.md'), 'w') as f:
        f.write(paper_table(summary))
    return summary


def _fossil_list(fossil):
    """Normalise ``fossil`` (None, (t1, t2) or a list of pairs) to a list of float pairs."""
    if fossil is None:
        return []
    if np.ndim(fossil) == 1:
        fossil = [fossil]
    return [(float(a), float(b)) for a, b in fossil]


def _summary(snap, m, levels, fossils, panel_times, figures):
    """Every number of the analysis in one flat-ish dict; units are in the key names."""
    prof, gp, dip, recip, cyl, law, hist = (m[k] for k in ('prof', 'gp', 'dip', 'recip', 'cyl', 'law', 'hist'))
    p = gp['pressure_Pa']
    peak = int(np.argmax(p)) if len(p) else 0
    hydro = gp['hydrostatic_Pa']
    rho_g_H = snap['rho'] * snap['g'] * prof['H']
    n_cont = len(pa.grain_contacts(snap)['i1'])
    free = ~snap['fixed']
    speed = np.linalg.norm(snap['vel'][free], axis=1)
    s = {'snapshot': snap.get('path'), 'time_s': snap['time'], 'g_m_s2': snap['g'],
         'n_grains': len(snap['pos']), 'n_fixed_grains': int(snap['fixed'].sum()),
         'n_pile_grains': prof['n_grains'], 'n_contacts': n_cont,
         'n_contacts_loaded': int((np.linalg.norm(snap['c_force'], axis=1) > 0).sum()),
         'mean_diameter_m': prof['d'],
         'slope_deg': prof['slope_deg'], 'slope_err_deg': prof['slope_err_deg'], 'slope_note': prof['slope_note'],
         'slope_sector_deg': prof['slope_sector_deg'], 'slope_n_fit_points': prof['n_fit_points'],
         'slope_fit_r_range_m': prof['fit_r_range'], 'chord_angle_deg': prof['chord_angle_deg'],
         'R2_m': prof['R2'], 'slope_ls_window_deg': prof['slope_ls_window_deg'], 'slope_paper_deg': 26.0,
         'H_m': prof['H'], 'H_cm': prof['H'] * CM, 'H_over_d': prof['H'] / prof['d'],
         'flank_base_radius_m': prof['base_radius'],
         'base_radius_m': prof['profile_radius'], 'base_radius_cm': prof['profile_radius'] * CM,
         'z_floor_m': prof['z_floor'], 'rho_grain_kg_m3': snap['rho'],
         'rho_bulk_kg_m3': gp['rho_bulk'], 'rho_bulk_g_cm3': gp['rho_bulk'] / 1000.0,
         'packing_fraction': gp['rho_bulk'] / snap['rho'], 'pile_volume_m3': prof['volume'],
         'hydrostatic_Pa': hydro, 'hydrostatic_dPa': hydro * DPA,
         'rho_grain_g_H_Pa': rho_g_H, 'ring_width_m': float(gp['r_out'][0] - gp['r_in'][0]),
         'p_center_Pa': p[0], 'p_center_dPa': p[0] * DPA, 'p_center_err_Pa': gp['err_Pa'][0],
         'p_center_err_dPa': gp['err_Pa'][0] * DPA,
         'p_center_over_hydrostatic': p[0] / hydro if hydro > 0 else None,
         'p_center_over_rho_grain_g_H': p[0] / rho_g_H,
         'p_peak_Pa': p[peak], 'p_peak_dPa': p[peak] * DPA, 'p_peak_err_Pa': gp['err_Pa'][peak],
         'p_peak_radius_m': gp['r_mid'][peak], 'p_peak_radius_cm': gp['r_mid'][peak] * CM,
         'p_peak_over_hydrostatic': p[peak] / hydro if hydro > 0 else None,
         'p_peak_over_rho_grain_g_H': p[peak] / rho_g_H,
         'floor_load_N': gp['total_load_N'], 'pile_weight_N': gp['pile_weight_N'],
         'floor_load_over_weight': gp['total_load_N'] / gp['pile_weight_N'] if gp['pile_weight_N'] > 0 else None,
         'dip': {k: dip[k] for k in ('D', 'se', 'ci95', 'confidence_positive', 'p_disc_Pa', 'p_ring_Pa',
                                      'n_disc', 'n_ring', 'r0', 'r1', 'sector_disc_N', 'sector_ring_N', 'note')},
         'rings': {'r_mid_m': gp['r_mid'], 'pressure_Pa': p, 'err_Pa': gp['err_Pa'],
                   'pressure_dPa': p * DPA, 'err_dPa': gp['err_Pa'] * DPA,
                   'n_contacts': gp['n_contacts'], 'p_over_hydrostatic': gp['p_over_hydrostatic'],
                   'p_over_rho_grain_g_H': gp['p_over_rho_grain_g_H']},
         'reciprocity': dict({k: recip[k] for k in ('n_pairs', 'rel_mean', 'rel_std', 'rel_median', 'corr',
                                                    'rms_diff_Pa', 'rms_mean_Pa', 'rel_null_mean',
                                                    'rel_null_median')},
                             rel=recip['rel'], nT2_Pa=recip['nT2'], n2T_Pa=recip['n2T']),
         'cylindrical_cuts': _cyl_summary(cyl, prof),
         'fossil_law': {k: law[k] for k in ('n_cuts', 'n_cuts_no_layering', 'median_layer_deg',
                                            'median_surface_deg', 'median_random_deg', 'mean_layer_deg',
                                            'mean_random_deg', 'fraction_within_15deg', 'advantage_deg',
                                            'advantage_ci95', 'angle_layer_deg', 'angle_random_layer_deg',
                                            'angle_surface_deg')},
         'fabric': {'n_contacts': hist['n_contacts'], 'anisotropy': hist['anisotropy'],
                    'fabric_eigenvalues': hist['fabric_eigenvalues'], 'fabric_zz': hist['fabric_zz']},
         'speed': {'vmax_m_s': levels['vmax'], 'vmax_cm_s': levels['vmax'] * CM,
                   'median_m_s': float(np.median(speed)) if len(speed) else None,
                   'thresholds_m_s': levels['thresholds'], 'class_counts': levels['counts']},
         'fossil_layers_s': [list(f) for f in fossils],
         'fossil_counts': [int(pa.fossil_layer(snap, *f).sum()) for f in fossils],
         'fig2_times_s': panel_times, 'figures': figures,
         'conventions': {
             'units': 'SI unless the key says otherwise (_cm, _dPa, _deg, _g_cm3); 1 Pa = 10 dPa',
             'pressure': 'compression positive: vertical load of pile grains on paving grains / ring area',
             'slope_deg': 'robust (bisquare) fit of the exposed grain tops where the pile is >= 2 d thick, '
                          '>= 3 d from the axis, >= 1 d below the apex; null when the pile has no straight flank (slope_note)',
             'slope_err_deg': 'bootstrap standard error over azimuthal sectors',
             'chord_angle_deg': 'atan((H - 2 d)/R2), R2 = radius where the pile is 2 grains thick',
             'slope_ls_window_deg': 'the estimator used before (least squares, 15-80 % of H); biased low, for comparison only',
             'base_radius_m': 'outermost radius where the median profile is >= 1 mean diameter high',
             'dip': 'D = 1 - p(r < 2 d)/p(2 d <= r < 4 d); jackknife over sectors, t interval',
             'band_T': 'force of the + side (where n points) on the - side per band area; n = tangent p0->p1 turned +90 deg in (r, z)',
             'reciprocity_rel': "|n.T' - n'.T| / sqrt(|T| |T'|) per pair of crossing bands; rel_null: T' from another place",
             'fossil_law': 'angle between the force density on a cylindrical cut and the local fossil layer (birth-time level set), '
                           'against a random layer; advantage = mean(random - layer)',
             'central_pressure': 'ring 0, the disc r < ring_width'}}
    return s


# The paper's numbers for its 14 000-grain pile (Moreau, section IV; the project's digest), in
# SI. Only those the paper states as numbers; its qualitative findings are quoted in the table.
PAPER = {'slope_deg': 26.0, 'H_m': 0.055, 'rho_bulk_kg_m3': 615.0, 'hydrostatic_Pa': 332.0,
         'n_contacts': 33000, 'vmax_m_s': 0.236}


def _fmt_or_dash(value, fmt):
    return '–' if value is None or (isinstance(value, float) and not math.isfinite(value)) else fmt % value


def paper_table(s):
    """Markdown table of a pile's numbers (a ``summary.json`` dict) beside the paper's, in the
    paper's units (cm, g/cm³, dPa, cm/s). Rows the paper states only in words say so; the dip
    row gives D = 1 − p(r < 2d)/p(2d ≤ r < 4d) with its 95 % interval and the central ring's
    pressure against the hydrostatic one, the paper's own comparison."""
    P = PAPER
    dip, rec, law = s.get('dip') or {}, s.get('reciprocity') or {}, s.get('fossil_law') or {}
    ci = dip.get('ci95') or [None, None]
    if s.get('slope_deg') is None:
        slope = 'no straight flank (%s)' % (s.get('slope_note') or 'too small')
    else:
        slope = '%.1f°' % s['slope_deg'] + (' ± %.1f°' % s['slope_err_deg'] if s.get('slope_err_deg') is not None else '')
    rows = [
        ('grains (pile, without the paving)', '%d' % s['n_pile_grains'], '14 000', ''),
        ('time', '%.2f s' % s['time_s'], 'about 72 s (feed 70 s)', 'the snapshot analysed'),
        ('contacts between grains', '%d' % s['n_contacts'], 'about %d' % P['n_contacts'], 'paper: at the end'),
        ('free-surface slope', slope, '%.0f°' % P['slope_deg'], 'robust flank fit; error: spread over sectors'),
        ('apex height H', _fmt_or_dash(None if s.get('H_m') is None else s['H_m'] * CM, '%.2f cm'), '%.1f cm' % (P['H_m'] * CM), ''),
        ('bulk density (profile volume)', _fmt_or_dash(None if s.get('rho_bulk_kg_m3') is None else s['rho_bulk_kg_m3'] / 1000.0,
                                                       '%.3f g/cm³'),
         '%.3f g/cm³' % (P['rho_bulk_kg_m3'] / 1000.0), 'ours: a low estimate (the profile follows grain tops)'),
        ('hydrostatic pressure ρ_bulk g H', _fmt_or_dash(None if s.get('hydrostatic_Pa') is None else s['hydrostatic_Pa'] * DPA,
                                                         '%.0f dPa'), '%.0f dPa' % (P['hydrostatic_Pa'] * DPA), ''),
        ('central ring pressure / hydrostatic', _fmt_or_dash(s.get('p_center_over_hydrostatic'), '%.2f') +
         ' (%s ± %s dPa)' % (_fmt_or_dash(s.get('p_center_dPa'), '%.0f'), _fmt_or_dash(s.get('p_center_err_dPa'), '%.0f')),
         '"well below" 1: a local minimum at the centre', 'error: spread over 8 sectors / √8'),
        ('central dip D [95 %], confidence of a dip', '%s [%s, %s], %s' % (
            _fmt_or_dash(dip.get('D'), '%.2f'), _fmt_or_dash(ci[0], '%.2f'), _fmt_or_dash(ci[1], '%.2f'),
            _fmt_or_dash(None if dip.get('confidence_positive') is None else 100 * dip['confidence_positive'], '%.0f %%')),
         'a dip (D > 0), not quantified', 'D > 0 is a dip'),
        ('reciprocity: median |n·T′ − n′·T|/√(|T||T′|), null', '%s (%d pairs), null %s' % (
            _fmt_or_dash(rec.get('rel_median'), '%.3f'), rec.get('n_pairs') or 0, _fmt_or_dash(rec.get('rel_null_median'), '%.3f')),
         'holds despite sampling noise (Fig. 3)', 'null: T′ taken at another place'),
        ('fossil-layer law: median angle to the local / a random layer', '%s / %s (%d cuts)' % (
            _fmt_or_dash(law.get('median_layer_deg'), '%.1f°'), _fmt_or_dash(law.get('median_random_deg'), '%.1f°'),
            law.get('n_cuts') or 0), 'T along the nearby fossil layer (Fig. 4)', ''),
        ('fastest grain', '%.1f cm/s' % ((s.get('speed') or {}).get('vmax_m_s', float('nan')) * CM),
         '%.1f cm/s (Fig. 1, during the feed)' % (P['vmax_m_s'] * CM), ''),
    ]
    lines = ['| quantity | this pile | paper (14 000 grains) | note |', '| --- | --- | --- | --- |']
    lines += ['| %s |' % ' | '.join(cell.replace('|', '\\|') for cell in r) for r in rows]   # '|' inside a cell escaped
    return '\n'.join(lines) + '\n'


def _cyl_summary(cyl, prof):
    """Counts and mean inclination [deg] of the cylindrical-cut force densities inside the pile
    (band top below the surface), split at half the pile's radius (centre / flank)."""
    ok = (cyl['count'] > 0) & np.isfinite(cyl['inclination_deg']) & cyl['inside']
    R = prof['profile_radius']
    inner = ok & (cyl['r'] < R / 2)
    outer = ok & (cyl['r'] >= R / 2)
    mean = lambda m: float(np.mean(cyl['inclination_deg'][m])) if m.any() else None
    return {'band_height_m': cyl['band_height'], 'n_points': int(ok.sum()),
            'mean_inclination_inner_deg': mean(inner), 'mean_inclination_outer_deg': mean(outer)}

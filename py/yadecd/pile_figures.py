"""Figures of the sand-pile analysis (Moreau, section IV, Figures 1-5 and more) as PNG files,
and :func:`analyse`, which writes them all with a ``summary.json`` of every number.

Uses numpy and matplotlib only, through the Agg canvas directly (no pyplot, no display, the
backend of an interactive session is left alone). Figures show lengths in cm, pressures in dPa
(1 Pa = 10 dPa) and speeds in cm/s as the paper does; every number computed is SI (see
:mod:`pile_analysis`).
"""
import json
import math
import os

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PatchCollection
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Patch

from . import pile_analysis as pa

__all__ = ['fig_speed', 'fig_slices', 'fig_reciprocal', 'fig_cylindrical', 'fig_ground_pressure',
           'fig_orientation', 'fig_force_chains', 'fig_profile', 'analyse']

CM = 100.0      # m -> cm
DPA = 10.0      # Pa -> dPa
PAVING_FACE = (0.78, 0.72, 0.62)


# ---------------------------------------------------------------------------------------------
# drawing helpers

def _figure(width, height):
    """A Figure (inches) attached to an Agg canvas."""
    fig = Figure(figsize=(width, height), dpi=150)
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path):
    """Write the figure as PNG [path] and return the path."""
    fig.savefig(path, dpi=150, bbox_inches='tight')
    return path


def _circles(ax, x, y, radius, face, edge='k', lw=0.3, zorder=1):
    """Draw circles of true radius (data units) centred at (x, y); ``face`` / ``edge`` are one
    colour or one per circle."""
    patches = [Circle((a, b), r) for a, b, r in zip(x, y, radius)]
    coll = PatchCollection(patches, facecolors=face, edgecolors=edge, linewidths=lw, zorder=zorder)
    ax.add_collection(coll)
    return coll


def _slice_limits(snaps, half_thickness):
    """Common x, z limits [cm] of the slices of several snapshots."""
    xs, zs = [], []
    for s in snaps:
        m = pa.slice_mask(s, half_thickness)
        if m.any():
            xs.append(np.abs(s['pos'][m, 0]).max() + s['radius'][m].max())
            zs.append((s['pos'][m, 2] + s['radius'][m]).max())
            zs.append((s['pos'][m, 2] - s['radius'][m]).min())
    xm = max(xs) if xs else 0.1
    return (-xm * CM, xm * CM), (min(zs) * CM if zs else 0, max(zs) * CM if zs else 10)


def _draw_slice(ax, snap, half_thickness, black=None, face='white', edge='k', lw=0.3):
    """Grains of the slab |y| < half_thickness as circles in the x-z plane [cm] (true radii):
    ``black`` mask drawn black, paving grains tan, the others ``face``."""
    colours = [face] * len(snap['pos'])
    for i in np.flatnonzero(snap['fixed']):
        colours[i] = PAVING_FACE
    if black is not None:
        for i in np.flatnonzero(black):
            colours[i] = 'k'
    sel = np.flatnonzero(pa.slice_mask(snap, half_thickness))
    pos, rad = snap['pos'][sel] * CM, snap['radius'][sel] * CM
    _circles(ax, pos[:, 0], pos[:, 2], rad, [colours[i] for i in sel], edge=edge, lw=lw)


# ---------------------------------------------------------------------------------------------
# figures

def fig_speed(snap, path, elevation_deg=20.0, levels=None):
    """Figure 1: oblique orthographic view of every grain (true radii), viewed from -y and
    ``elevation_deg`` above the horizontal, grey by Moreau's speed classes (black fastest,
    thresholds vmax·0.18^k in the legend). Writes PNG ``path``."""
    levels = levels or pa.speed_levels(snap)
    e = math.radians(elevation_deg)
    p = snap['pos']
    X, Y = p[:, 0], p[:, 1] * math.sin(e) + p[:, 2] * math.cos(e)
    depth = p[:, 1] * math.cos(e) - p[:, 2] * math.sin(e)
    order = np.argsort(-depth)                     # far grains first
    grey = levels['grey']
    faces = [PAVING_FACE if snap['fixed'][i] else (grey[i],) * 3 for i in order]
    fig = _figure(8, 5)
    ax = fig.add_subplot(1, 1, 1)
    _circles(ax, X[order] * CM, Y[order] * CM, snap['radius'][order] * CM, faces, edge=(0.4,) * 3, lw=0.15)
    ax.set_aspect('equal')
    ax.autoscale_view()
    ax.set_xlabel('x [cm]')
    ax.set_ylabel('height (projected) [cm]')
    ax.set_title('t = %.2f s: grain speed, v_max = %.1f cm/s' % (snap['time'], levels['vmax'] * CM))
    ax.legend(handles=_speed_legend(levels), loc='upper right', fontsize=7, title='speed classes',
              title_fontsize=7)
    return _save(fig, path)


def _speed_legend(levels):
    """Legend patches of the speed classes with their bounds in cm/s."""
    t = levels['thresholds'] * CM
    n = len(t)
    handles = [Patch(facecolor='k', edgecolor='0.4', label='v > %.3g (max %.3g)' % (t[0], levels['vmax'] * CM))]
    for k in range(1, n):
        handles.append(Patch(facecolor=(k / n,) * 3, edgecolor='0.4', label='%.3g < v ≤ %.3g' % (t[k], t[k - 1])))
    handles.append(Patch(facecolor='w', edgecolor='0.4', label='v ≤ %.3g cm/s' % t[-1]))
    handles.append(Patch(facecolor=PAVING_FACE, edgecolor='0.4', label='paving (fixed)'))
    return handles


def fig_slices(snaps, fossil, path, half_thickness=0.01):
    """Figure 2: the slab |y| < half_thickness [m] containing Oz at several epochs side by side,
    grains as circles of true radius, the fossil layer (birth in ``fossil`` = (t1, t2) [s]) black.
    Writes PNG ``path``."""
    n = len(snaps)
    xlim, zlim = _slice_limits(snaps, half_thickness)
    aspect = (zlim[1] - zlim[0]) / max(xlim[1] - xlim[0], 1e-9)
    pw, ph = 4.0, 4.0 * aspect                      # panel size [in]
    left, gap, right, bottom, top = 0.6, 0.25, 0.15, 0.5, 0.7
    W, Hf = left + n * pw + (n - 1) * gap + right, bottom + ph + top
    fig = _figure(W, Hf)
    for k, snap in enumerate(snaps):
        ax = fig.add_axes([(left + k * (pw + gap)) / W, bottom / Hf, pw / W, ph / Hf])
        _draw_slice(ax, snap, half_thickness, black=pa.fossil_layer(snap, *fossil))
        ax.set_xlim(*xlim)
        ax.set_ylim(*zlim)
        ax.set_aspect('equal')
        ax.set_title('t = %.2f s' % snap['time'], fontsize=9)
        ax.set_xlabel('x [cm]')
        if k == 0:
            ax.set_ylabel('z [cm]')
        else:
            ax.set_yticklabels([])
    fig.suptitle('slice |y| < %.3g cm; black: born in [%.3g, %.3g] s'
                 % (half_thickness * CM, fossil[0], fossil[1]), fontsize=10, y=1 - 0.1 / Hf, va='top')
    return _save(fig, path)


def fig_reciprocal(recip, path):
    """Figure 3: reciprocal cuts, n·T' against n'·T [dPa] for every pair of bands, with the
    line of perfect reciprocity; beside it, the distribution of the relative difference for the
    true pairs and for the null pairing (T' from another place). When no pair fits inside the
    pile the figure says so instead of staying empty. Writes PNG ``path``."""
    a, b = recip['nT2'] * DPA, recip['n2T'] * DPA
    ok = np.isfinite(recip['rel'])
    fig = _figure(9, 4.2)
    ax = fig.add_subplot(1, 2, 1)
    if not ok.any():
        ax.text(0.5, 0.5, 'no pair of bands fits inside this pile\n(bands 3 grain diameters long need\n'
                'a pile at least ~5 diameters thick)', ha='center', va='center', transform=ax.transAxes, fontsize=9)
        ax.set_axis_off()
        fig.suptitle('reciprocal cuts: no data', fontsize=9)
        return _save(fig, path)
    ax.scatter(b[ok], a[ok], s=8, c='k')
    lim = [min(a[ok].min(), b[ok].min()), max(a[ok].max(), b[ok].max())]
    ax.plot(lim, lim, 'r-', lw=0.8, label="n·T' = n'·T")
    ax.legend(fontsize=8)
    ax.set_xlabel("n'·T [dPa]")
    ax.set_ylabel("n·T' [dPa]")
    ax.set_aspect('equal', adjustable='datalim')
    ax.set_title('%d pairs, correlation %.3f' % (recip['n_pairs'], recip['corr']), fontsize=9)
    hx = fig.add_subplot(1, 2, 2)
    bins = np.linspace(0, max(2.0, np.nanmax(recip['rel'])), 30)
    hx.hist(recip['rel'][ok], bins=bins, color='k', alpha=0.7, label='crossing pairs: median %.3f' % recip['rel_median'])
    null = recip['rel_null'][np.isfinite(recip['rel_null'])]
    if len(null):
        hx.hist(np.clip(null, 0, bins[-1]), bins=bins, histtype='step', color='tab:red', lw=1.2,
                label='null (T\' from elsewhere): median %.3f' % recip['rel_null_median'])
    hx.set_xlabel("|n·T' - n'·T| / sqrt(|T| |T'|)")
    hx.set_ylabel('pairs')
    hx.legend(fontsize=7)
    return _save(fig, path)


def fig_cylindrical(snap, cyl, fossils, path, half_thickness=0.01, law=None):
    """Figure 4: directions of the force density on cylindrical cuts (segments of fixed length,
    width growing with |T|), drawn at (±r, z) over the outlines of the fossil-layer grains of the
    slab |y| < half_thickness [m]. ``cyl`` is a :func:`pile_analysis.cylindrical_cut_directions`
    result, optionally with a bool grid ``inside`` selecting the points drawn; ``fossils`` is a
    list of (t1, t2) [s]. With ``law`` (:func:`pile_analysis.fossil_law`), a second panel shows
    the angle between each force density and the local fossil layer against the null model of a
    random layer. Writes PNG ``path``."""
    fig = _figure(13 if law is not None else 9, 4.5)
    ax = fig.add_axes([0.05, 0.1, 0.6, 0.8]) if law is not None else fig.add_subplot(1, 1, 1)
    _draw_slice(ax, snap, half_thickness, edge='0.85', lw=0.3)
    colours = ['k', 'tab:red', 'tab:blue', 'tab:green']
    m = pa.slice_mask(snap, half_thickness)
    for k, (t1, t2) in enumerate(fossils):
        f = pa.fossil_layer(snap, t1, t2) & m
        p, r = snap['pos'][f] * CM, snap['radius'][f] * CM
        _circles(ax, p[:, 0], p[:, 2], r, 'none', edge=colours[k % 4], lw=0.8, zorder=2)
    ax.add_collection(_direction_segments(cyl))
    handles = [Patch(facecolor='none', edgecolor=colours[k % 4], label='born %.3g-%.3g s' % f)
               for k, f in enumerate(fossils)]
    ax.legend(handles=handles, fontsize=7, loc='upper right')
    ax.set_aspect('equal')
    ax.autoscale_view()
    ax.set_xlabel('x [cm]')
    ax.set_ylabel('z [cm]')
    ax.set_title('force density on cylindrical cuts (band height %.2g cm)' % (cyl['band_height'] * CM), fontsize=9)
    if law is not None:
        hx = fig.add_axes([0.72, 0.12, 0.26, 0.74])
        bins = np.linspace(0, 90, 19)
        rand = law['angle_random_layer_deg'][np.isfinite(law['angle_random_layer_deg'])]
        if law['n_cuts'] > 1 and len(rand):
            hx.hist(law['angle_layer_deg'], bins=bins, color='tab:purple', alpha=0.7,
                    label='local fossil layer: median %.0f°' % law['median_layer_deg'])
            hx.hist(rand, bins=bins, histtype='step', color='k', lw=1.2,
                    label='random layer (null): median %.0f°' % law['median_random_deg'])
            hx.legend(fontsize=6)
            hx.set_title('%d cuts; random - layer = %.1f° [%.1f, %.1f]' % ((law['n_cuts'], law['advantage_deg'])
                         + tuple(law['advantage_ci95'])), fontsize=7)
        else:
            hx.text(0.5, 0.5, '%d cut(s) with a measurable\nlocal layering: no statistic' % law['n_cuts'],
                    ha='center', va='center', transform=hx.transAxes, fontsize=8)
        hx.set_xlabel('angle between T and the layer [deg]', fontsize=8)
        hx.set_ylabel('cuts', fontsize=8)
    return _save(fig, path)


def _direction_segments(cyl):
    """LineCollection of the cylindrical-cut directions, mirrored to both half-planes [cm]."""
    r, z, Tr, Tz = (cyl[k].ravel() for k in ('r', 'z', 'Tr', 'Tz'))
    mag = np.hypot(Tr, Tz)
    ok = (mag > 0) & (cyl['count'].ravel() > 0)
    if 'inside' in cyl:
        ok &= cyl['inside'].ravel()
    half = 0.4 * cyl['band_height']
    segs, widths = [], []
    top = mag[ok].max() if ok.any() else 1.0
    for ri, zi, tr, tz, mi in zip(r[ok], z[ok], Tr[ok], Tz[ok], mag[ok]):
        ux, uz = tr / mi * half, tz / mi * half
        for side in (1, -1):
            segs.append([((side * ri - side * ux) * CM, (zi - uz) * CM),
                         ((side * ri + side * ux) * CM, (zi + uz) * CM)])
            widths.append(0.6 + 1.8 * mi / top)
    return LineCollection(segs, linewidths=widths, colors='tab:purple', zorder=3)


def fig_ground_pressure(gp, path, dip=None):
    """Figure 5: pressure on the floor per ring [dPa] against the distance to the axis [cm],
    with sector error bars, the hydrostatic reference rho_bulk·g·H and a right axis normalised by
    it. Writes PNG ``path``."""
    fig = _figure(6.5, 4)
    ax = fig.add_subplot(1, 1, 1)
    w = (gp['r_out'] - gp['r_in']) * CM
    ax.bar(gp['r_mid'] * CM, gp['pressure_Pa'] * DPA, width=w, color='0.8', edgecolor='k', lw=0.5)
    ax.errorbar(gp['r_mid'] * CM, gp['pressure_Pa'] * DPA, yerr=gp['err_Pa'] * DPA, fmt='k.',
                capsize=2, lw=0.8)
    hydro = gp['hydrostatic_Pa'] * DPA
    ax.axhline(hydro, color='tab:red', ls='--', lw=1,
               label='hydrostatic ρ_bulk g H = %.0f dPa (ρ_bulk %.3g g/cm³, H %.3g cm)'
               % (hydro, gp['rho_bulk'] / 1000, gp['H'] * CM))
    ax.set_xlabel('distance to the axis r [cm]')
    ax.set_ylabel('pressure on the floor [dPa]')
    ax.legend(fontsize=7, loc='upper right')
    if hydro > 0:
        sec = ax.secondary_yaxis('right', functions=(lambda p: p / hydro, lambda q: q * hydro))
        sec.set_ylabel('p / (ρ_bulk g H)')
    ax.set_xlim(0, gp['r_out'][-1] * CM)
    title = 'pressure on the floor per ring (ring width %.3g cm)' % (w[0])
    if dip is not None and np.isfinite(dip['D']):
        title += ('\ncentral dip D = 1 - p(r<%.2g cm)/p(%.2g-%.2g cm) = %.2f, 95%% interval [%.2f, %.2f], '
                  'confidence of a dip %.0f%%' % (dip['r0'] * CM, dip['r0'] * CM, dip['r1'] * CM, dip['D'],
                                                 dip['ci95'][0], dip['ci95'][1], 100 * dip['confidence_positive']))
    ax.set_title(title, fontsize=8)
    return _save(fig, path)


def fig_orientation(hist, path):
    """Figure 6: contact-normal orientations: left, angle from the vertical normalised by the
    isotropic expectation; right, rose of the normal orientations in the meridian plane.
    Writes PNG ``path``."""
    fig = _figure(9, 4)
    ax = fig.add_subplot(1, 2, 1)
    e = hist['theta_edges_deg']
    ax.bar((e[:-1] + e[1:]) / 2, hist['theta_density'], width=np.diff(e), color='0.7', edgecolor='k', lw=0.5)
    ax.axhline(1, color='tab:red', ls='--', lw=0.8, label='isotropic')
    ax.set_xlabel('angle of the normal from the vertical [deg]')
    ax.set_ylabel('count / isotropic expectation')
    ax.set_title('%d contacts, anisotropy %.3f' % (hist['n_contacts'], hist['anisotropy']), fontsize=9)
    ax.legend(fontsize=8)
    polar = fig.add_subplot(1, 2, 2, projection='polar')
    pe = np.radians(hist['psi_edges_deg'])
    counts = hist['psi_counts']
    for shift in (0.0, math.pi):                   # a normal is a line: draw psi and psi + 180°
        polar.bar(pe[:-1] + shift + np.diff(pe) / 2, counts, width=np.diff(pe), color='0.6', edgecolor='k', lw=0.4)
    polar.set_title('normals in the meridian plane (0° = radial)', fontsize=9)
    return _save(fig, path)


def fig_force_chains(snap, path, half_thickness=0.01, max_width=3.0):
    """Figure 7: force chains in the slab |y| < half_thickness [m]: every contact whose point
    lies in the slab is a segment between the two centres (x-z plane, cm) of width proportional
    to |force|. Writes PNG ``path``."""
    cont = pa._grain_contacts(snap)
    mag = np.linalg.norm(cont['force'], axis=1)
    use = (np.abs(cont['point'][:, 1]) < half_thickness) & (mag > 0)
    order = np.argsort(mag[use])
    p1 = snap['pos'][cont['i1'][use]][order] * CM
    p2 = snap['pos'][cont['i2'][use]][order] * CM
    f = mag[use][order]
    fig = _figure(9, 4.5)
    ax = fig.add_subplot(1, 1, 1)
    _draw_slice(ax, snap, half_thickness, edge='0.8', lw=0.3)
    if len(f):
        segs = np.stack([p1[:, [0, 2]], p2[:, [0, 2]]], axis=1)
        ax.add_collection(LineCollection(segs, linewidths=max_width * f / f.max(), colors='k', zorder=3))
    ax.set_aspect('equal')
    ax.autoscale_view()
    ax.set_xlabel('x [cm]')
    ax.set_ylabel('z [cm]')
    ax.set_title('contact forces in the slice |y| < %.3g cm (max %.3g N)'
                 % (half_thickness * CM, f.max() if len(f) else 0), fontsize=9)
    return _save(fig, path)


def fig_profile(prof, path):
    """Free surface [cm]: every exposed grain top (grey), those in the flank window coloured by
    their weight in the robust fit, the median profile of the highest grain per sector and bin,
    and the fitted flank line (solid where it was fitted, dashed extended to the axis and the
    floor). The title gives the flank slope with its bootstrap error and the apex-to-toe chord
    angle, or says why no flank could be measured. Writes PNG ``path``."""
    fig = _figure(6.5, 4)
    ax = fig.add_subplot(1, 1, 1)
    r, h = prof['surface_r'] * CM, prof['surface_h'] * CM
    win = prof['in_window']
    ax.plot(r[~win], h[~win], '.', ms=2, color='0.7', label='exposed grain tops')
    if win.any():
        sc = ax.scatter(r[win], h[win], s=3, c=prof['weight'][win], cmap='viridis', vmin=0, vmax=1,
                        label='flank window (colour: fit weight)')
        fig.colorbar(sc, ax=ax, fraction=0.04, pad=0.01).set_label('bisquare weight', fontsize=7)
    ax.plot(prof['r'] * CM, prof['h'] * CM, 'k-', lw=1, label='median profile (highest grain per sector and bin)')
    a_, b_ = prof['fit_line']
    if np.isfinite(prof['slope_deg']):
        r0, r1 = prof['fit_r_range']
        rr = np.array([0.0, prof['base_radius']])
        ax.plot(rr * CM, (a_ + b_ * rr) * CM, 'r--', lw=0.8)
        rr = np.array([r0, r1])
        ax.plot(rr * CM, (a_ + b_ * rr) * CM, 'r-', lw=2, label='flank fit (where fitted)')
        title = ('flank slope %.1f ± %.1f° (paper 26°), chord angle %.1f°, H = %.2f cm'
                 % (prof['slope_deg'], prof['slope_err_deg'], prof['chord_angle_deg'], prof['H'] * CM))
    else:
        title = '%s; chord angle %.1f°, H = %.2f cm' % (prof['slope_note'], prof['chord_angle_deg'], prof['H'] * CM)
    ax.set_xlabel('r [cm]')
    ax.set_ylabel('height above the floor [cm]')
    ax.set_title(title, fontsize=8)
    ax.set_aspect('equal', adjustable='datalim')
    ax.legend(fontsize=6, loc='upper right')
    return _save(fig, path)


# ---------------------------------------------------------------------------------------------
# the whole analysis

def _collect(source):
    """(time [s], path) of the snapshots of a run directory, a snapshot file or a list of
    files, sorted by time."""
    if isinstance(source, (str, os.PathLike)):
        if os.path.isdir(source):
            return pa.list_snapshots(source)
        source = [source]
    found = []
    for path in source:
        m = pa._SNAP_NAME.match(os.path.basename(str(path)))
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


def _clean(value):
    """JSON-ready copy: numpy scalars/arrays to Python, nan/inf to None."""
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return _clean(value.tolist())
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    return value


def measure(snap, ring_width=None, n_sectors=8, band_length=None, band_height=None, clearance=None,
            layer_radius=None):
    """Every measurement of the pile analysis on one snapshot, no figure (lengths default to
    multiples of the mean diameter d: rings 2 d, reciprocal bands 3 d long with d/2 of clearance
    inside the pile, cylindrical bands 3 d high, fossil layers fitted within 2 d).

    :returns: dict ``prof`` (:func:`pile_analysis.profile_and_slope`), ``gp`` (ground pressure),
        ``dip`` (:func:`pile_analysis.central_dip`), ``recip`` (reciprocal cuts), ``cyl``
        (cylindrical cuts with the grid ``inside``), ``law`` (:func:`pile_analysis.fossil_law`),
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
    summary = _clean(summary)
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
    n_cont = len(pa._grain_contacts(snap)['i1'])
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
        ('apex height H', '%.2f cm' % (s['H_m'] * CM), '%.1f cm' % (P['H_m'] * CM), ''),
        ('bulk density (profile volume)', '%.3f g/cm³' % (s['rho_bulk_kg_m3'] / 1000.0),
         '%.3f g/cm³' % (P['rho_bulk_kg_m3'] / 1000.0), 'ours: a low estimate (the profile follows grain tops)'),
        ('hydrostatic pressure ρ_bulk g H', '%.0f dPa' % (s['hydrostatic_Pa'] * DPA), '%.0f dPa' % (P['hydrostatic_Pa'] * DPA), ''),
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

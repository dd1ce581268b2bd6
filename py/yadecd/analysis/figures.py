"""Figures of the sand-pile analysis (Moreau, section IV, Figures 1-5 and more) as PNG files,
and the figure helpers every plotting module shares (:func:`new_figure`, :func:`save_figure`).

Uses numpy and matplotlib only, through the Agg canvas directly (no pyplot, no display, the
backend of an interactive session is left alone). Figures show lengths in cm, pressures in dPa
(1 Pa = 10 dPa) and speeds in cm/s as the paper does; every number computed is SI.
"""

import math
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PatchCollection
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Patch

from .. import analysis as pa


CM = 100.0      # m -> cm


DPA = 10.0      # Pa -> dPa


PAVING_FACE = (0.78, 0.72, 0.62)


def new_figure(width, height):
    """A Figure (inches) attached to an Agg canvas."""
    fig = Figure(figsize=(width, height), dpi=150)
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig, path):
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


def grain_spheres(snap, rows):
    """The spheres that draw the grains ``rows`` of a snapshot: ``(centres (k, 3), radii (k,),
    row (k,))``, a grain's own sphere, or a clump's members (snapshot keys ``m_pos``, ``m_radius``,
    ``m_grain``) where the snapshot has them, each with the row of its grain."""
    rows = np.asarray(rows, dtype=int)
    if 'm_grain' not in snap or not len(snap['m_grain']):
        return snap['pos'][rows], snap['radius'][rows], rows
    member_row = pa.body_index(snap, snap['m_grain'])
    wanted = np.zeros(len(snap['pos']), dtype=bool)
    wanted[rows] = True
    has_members = np.zeros(len(snap['pos']), dtype=bool)
    has_members[member_row[member_row >= 0]] = True
    alone = rows[~has_members[rows]]
    m = (member_row >= 0) & wanted[np.clip(member_row, 0, None)]
    return (np.concatenate([snap['pos'][alone], np.asarray(snap['m_pos'], float).reshape(-1, 3)[m]]),
            np.concatenate([snap['radius'][alone], np.asarray(snap['m_radius'], float)[m]]),
            np.concatenate([alone, member_row[m]]))


def _draw_slice(ax, snap, half_thickness, black=None, face='white', edge='k', lw=0.3):
    """Grains of the slab |y| < half_thickness as circles in the x-z plane [cm] (true radii; a
    clump as its members): ``black`` mask drawn black, paving grains tan, the others ``face``."""
    colours = [face] * len(snap['pos'])
    for i in np.flatnonzero(snap['fixed']):
        colours[i] = PAVING_FACE
    if black is not None:
        for i in np.flatnonzero(black):
            colours[i] = 'k'
    centres, radii, owner = grain_spheres(snap, np.flatnonzero(pa.slice_mask(snap, half_thickness)))
    _circles(ax, centres[:, 0] * CM, centres[:, 2] * CM, radii * CM, [colours[i] for i in owner], edge=edge, lw=lw)


def fig_speed(snap, path, elevation_deg=20.0, levels=None):
    """Figure 1: oblique orthographic view of every grain (true radii), viewed from -y and
    ``elevation_deg`` above the horizontal, grey by Moreau's speed classes (black fastest,
    thresholds vmax·0.18^k in the legend). Writes PNG ``path``."""
    levels = levels or pa.speed_levels(snap)
    e = math.radians(elevation_deg)
    p, radii, owner = grain_spheres(snap, np.arange(len(snap['pos'])))   # a clump as its members
    X, Y = p[:, 0], p[:, 1] * math.sin(e) + p[:, 2] * math.cos(e)
    depth = p[:, 1] * math.cos(e) - p[:, 2] * math.sin(e)
    order = np.argsort(-depth)                     # far spheres first
    grey = levels['grey']
    faces = [PAVING_FACE if snap['fixed'][owner[i]] else (grey[owner[i]],) * 3 for i in order]
    fig = new_figure(8, 5)
    ax = fig.add_subplot(1, 1, 1)
    _circles(ax, X[order] * CM, Y[order] * CM, radii[order] * CM, faces, edge=(0.4,) * 3, lw=0.15)
    ax.set_aspect('equal')
    ax.autoscale_view()
    ax.set_xlabel('x [cm]')
    ax.set_ylabel('height (projected) [cm]')
    ax.set_title('t = %.2f s: grain speed, v_max = %.1f cm/s' % (snap['time'], levels['vmax'] * CM))
    ax.legend(handles=_speed_legend(levels), loc='upper right', fontsize=7, title='speed classes',
              title_fontsize=7)
    return save_figure(fig, path)


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
    fig = new_figure(W, Hf)
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
    return save_figure(fig, path)


def fig_reciprocal(recip, path):
    """Figure 3: reciprocal cuts, n·T' against n'·T [dPa] for every pair of bands, with the
    line of perfect reciprocity; beside it, the distribution of the relative difference for the
    true pairs and for the null pairing (T' from another place). When no pair fits inside the
    pile the figure says so instead of staying empty. Writes PNG ``path``."""
    a, b = recip['nT2'] * DPA, recip['n2T'] * DPA
    ok = np.isfinite(recip['rel'])
    fig = new_figure(9, 4.2)
    ax = fig.add_subplot(1, 2, 1)
    if not ok.any():
        ax.text(0.5, 0.5, 'no pair of bands fits inside this pile\n(bands 3 grain diameters long need\n'
                'a pile at least ~5 diameters thick)', ha='center', va='center', transform=ax.transAxes, fontsize=9)
        ax.set_axis_off()
        fig.suptitle('reciprocal cuts: no data', fontsize=9)
        return save_figure(fig, path)
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
    return save_figure(fig, path)


def fig_cylindrical(snap, cyl, fossils, path, half_thickness=0.01, law=None):
    """Figure 4: directions of the force density on cylindrical cuts (segments of fixed length,
    width growing with |T|), drawn at (±r, z) over the outlines of the fossil-layer grains of the
    slab |y| < half_thickness [m]. ``cyl`` is a :func:`yadecd.analysis.cylindrical_cut_directions`
    result, optionally with a bool grid ``inside`` selecting the points drawn; ``fossils`` is a
    list of (t1, t2) [s]. With ``law`` (:func:`yadecd.analysis.fossil_law`), a second panel shows
    the angle between each force density and the local fossil layer against the null model of a
    random layer. Writes PNG ``path``."""
    fig = new_figure(13 if law is not None else 9, 4.5)
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
    return save_figure(fig, path)


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
    fig = new_figure(6.5, 4)
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
    return save_figure(fig, path)


def fig_orientation(hist, path):
    """Figure 6: contact-normal orientations: left, angle from the vertical normalised by the
    isotropic expectation; right, rose of the normal orientations in the meridian plane.
    Writes PNG ``path``."""
    fig = new_figure(9, 4)
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
    return save_figure(fig, path)


def fig_force_chains(snap, path, half_thickness=0.01, max_width=3.0):
    """Figure 7: force chains in the slab |y| < half_thickness [m]: every contact whose point
    lies in the slab is a segment between the two centres (x-z plane, cm) of width proportional
    to |force|. Writes PNG ``path``."""
    cont = pa.grain_contacts(snap)
    mag = np.linalg.norm(cont['force'], axis=1)
    use = (np.abs(cont['point'][:, 1]) < half_thickness) & (mag > 0)
    order = np.argsort(mag[use])
    p1 = snap['pos'][cont['i1'][use]][order] * CM
    p2 = snap['pos'][cont['i2'][use]][order] * CM
    f = mag[use][order]
    fig = new_figure(9, 4.5)
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
    return save_figure(fig, path)


def fig_profile(prof, path):
    """Free surface [cm]: every exposed grain top (grey), those in the flank window coloured by
    their weight in the robust fit, the median profile of the highest grain per sector and bin,
    and the fitted flank line (solid where it was fitted, dashed extended to the axis and the
    floor). The title gives the flank slope with its bootstrap error and the apex-to-toe chord
    angle, or says why no flank could be measured. Writes PNG ``path``."""
    fig = new_figure(6.5, 4)
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
    return save_figure(fig, path)

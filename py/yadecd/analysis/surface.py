"""The free surface of a pile: surface grains, the radial profile, the flank slope (robust fits
on the upper envelope, with bootstrap intervals) and the bulk density under the profile.
"""

import math
import numpy as np

from .snapshots import as_snapshot, floor_level, grain_masses, mean_diameter, pile_mask
from .stats import linear_fit, robust_line


def _highest_per_cell(cell, top):
    """For integer cell labels and heights, the index of the highest element of each occupied
    cell. Returns (cells, indices)."""
    order = np.lexsort((top, cell))
    cs = cell[order]
    last = np.r_[cs[1:] != cs[:-1], True] if len(cs) else np.zeros(0, dtype=bool)
    return cs[last], order[last]


def _sector_profiles(r, phi, top, bin_width, n_bins, n_sectors):
    """Highest grain top of every (sector, radial bin) cell: arrays (n_sectors, n_bins) of its
    r and top [m] (nan where the cell is empty)."""
    b = np.minimum((r / bin_width).astype(int), n_bins - 1)
    s = np.minimum((phi / (2 * math.pi / n_sectors)).astype(int), n_sectors - 1)
    cells, idx = _highest_per_cell(s * n_bins + b, top)
    r_sb = np.full((n_sectors, n_bins), np.nan)
    h_sb = np.full((n_sectors, n_bins), np.nan)
    r_sb.flat[cells] = r[idx]
    h_sb.flat[cells] = top[idx]
    return r_sb, h_sb


def _column_median(a):
    """Median of each column of a 2-D array ignoring nan (nan for an all-nan column)."""
    out = np.full(a.shape[1], np.nan)
    for j in range(a.shape[1]):
        col = a[:, j][~np.isnan(a[:, j])]
        if len(col):
            out[j] = np.median(col)
    return out


def _cone_volume(r_prof, h_prof, base_radius):
    """Volume [m³] under the axisymmetric profile h(r) ≥ 0 from r = 0 to ``base_radius``
    (trapezoid rule on 2·pi·r·h; the profile is extended flat to r = 0 and closed at
    (base_radius, 0))."""
    use = ~np.isnan(h_prof) & (r_prof < base_radius)
    r = np.r_[0.0, r_prof[use], base_radius]
    h = np.clip(np.r_[h_prof[use][:1] if use.any() else [0.0], h_prof[use], 0.0], 0, None)
    f = 2 * math.pi * r * h
    return float(((f[1:] + f[:-1]) * np.diff(r)).sum() / 2)


def _pile_and_floor(snap, mask, z_floor, caller):
    """The normalised snapshot, the pile mask (default :func:`pile_mask`) and the floor height
    (default :func:`floor_level`); ValueError naming ``caller`` when no grain is in the pile."""
    snap = as_snapshot(snap)
    if mask is None:
        mask = pile_mask(snap)
    if not mask.any():
        raise ValueError('%s: no pile grain' % caller)
    return snap, mask, (floor_level(snap) if z_floor is None else float(z_floor))


def horizontal_pairs(xy, cutoff):
    """All ordered pairs (i, j), i != j, of points ``xy`` (n, 2) [m] closer than ``cutoff`` [m]
    horizontally, found through a square grid of cell ``cutoff`` (no O(n²) step). Returns two
    int arrays."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    n = len(xy)
    if n < 2 or not cutoff > 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    ij = np.floor(xy / cutoff).astype(np.int64)
    ij -= ij.min(axis=0) - 1
    width = int(ij[:, 1].max()) + 2
    key = ij[:, 0] * width + ij[:, 1]
    order = np.argsort(key, kind='stable')
    skey = key[order]
    out_i, out_j = [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            k2 = (ij[:, 0] + dx) * width + ij[:, 1] + dy
            lo = np.searchsorted(skey, k2, 'left')
            cnt = np.searchsorted(skey, k2, 'right') - lo
            total = int(cnt.sum())
            if total == 0:
                continue
            first = np.repeat(np.cumsum(cnt) - cnt, cnt)
            out_i.append(np.repeat(np.arange(n), cnt))
            out_j.append(order[np.repeat(lo, cnt) + np.arange(total) - first])
    i, j = np.concatenate(out_i), np.concatenate(out_j)
    d2 = ((xy[i] - xy[j]) ** 2).sum(axis=1)
    keep = (i != j) & (d2 < cutoff * cutoff)
    return i[keep], j[keep]


def surface_grains(snap, mask=None):
    """Grains of the free surface: those (among ``mask``, default :func:`pile_mask`) whose top
    point (x, y, z + radius) sees the sky, i.e. the vertical ray going up from it meets no other
    grain of the pile (``mask``) or of the paving (grains in flight are not obstacles). A sphere j hides grain i when the horizontal distance ρ between their
    centres is below r_j and its upper surface there, z_j + sqrt(r_j² - ρ²), is above i's top.
    Unlike the highest grain of a cell, the exposed grains have the same statistics everywhere
    on a uniform surface (their number does not grow with a cell's area), so fitting them is
    free of the cell-size bias near the axis. Returns a bool array (N,)."""
    snap = as_snapshot(snap)
    if mask is None:
        mask = pile_mask(snap)
    pos, rad = snap['pos'], snap['radius']
    visible = np.asarray(mask, dtype=bool).copy()
    if len(pos) < 2:
        return visible
    i, j = horizontal_pairs(pos[:, :2], float(rad.max()))
    rho2 = ((pos[i, :2] - pos[j, :2]) ** 2).sum(axis=1)
    occluder = np.asarray(mask, dtype=bool) | snap['fixed']      # a grain in flight hides nothing
    over = (rho2 < rad[j] ** 2) & occluder[j]
    i, j, rho2 = i[over], j[over], rho2[over]
    hidden = pos[j, 2] + np.sqrt(rad[j] ** 2 - rho2) > pos[i, 2] + rad[i]
    visible[i[hidden]] = False
    return visible


# rules of the flank window, in mean grain diameters d (see flank_slope)
FLANK_MIN_THICKNESS_D = 2.0     # the pile is at least two grains thick: leaves out the foot


FLANK_CAP_RADIUS_D = 3.0        # no point nearer the axis than this: leaves out the cap and the


FLANK_CAP_DROP_D = 1.0          # axis cells; and none within this of the apex height


FLANK_MIN_SPAN_D = 2.0          # the window must span at least this much height


FLANK_MIN_POINTS = 12


def flank_slope(snap, mask=None, z_floor=None, n_sectors=8, n_boot=200, seed=0):
    """Slope of the straight flank of the free surface, robust to the cap, the foot, sparse cells
    near the axis and stray grains.

    What it measures: the exposed grains (:func:`surface_grains`) give surface points
    (r of the centre, height of the top above the floor). The flank window is a range of r
    (:func:`_flank_range`): from 3 d from the axis, where the surface is at least 1 d under the
    apex (no cap), to where the pile becomes thinner than ``FLANK_MIN_THICKNESS_D`` = 2 mean
    diameters d (no foot of single grains): rules in grain diameters, not fractions of H, so they
    mean the same on piles of every size. In that range the highest exposed grain of every cell
    of equal area (:func:`_envelope_points`, about 2 d² each) is a surface point, and a bisquare
    line (:func:`robust_line`) is fitted to them; the slope is atan(-b). (All exposed grains
    would include grains seen deep in holes, whose depth shrinks where the pile thins; the
    highest grain of equal-area cells has the same statistics everywhere.)
    Its uncertainty is the bootstrap standard error over ``n_sectors`` azimuthal sectors
    (sectors resampled with replacement, ``n_boot`` times, fixed ``seed``): it measures how much
    the answer depends on which part of the pile one looks at.

    Beside it, the overall angle atan((H - 2d)/R2): the chord from the apex to the toe, where R2
    is the radius at which the pile is two grains thick (median over sectors of the outermost
    exposed grain at least 2 d high). On a perfect cone both read the cone's angle; a rounded
    cap lowers the chord angle only.

    A pile whose flank would span less than ``FLANK_MIN_SPAN_D`` = 2 d of height (the surface
    where the window starts less than 4 d above the floor: piles below about 2 cm with the
    paper's grains), or holds too few points, has no straight flank: the slope is nan and
    ``slope_note`` says why (it starts with 'no straight flank' or reads 'no descending flank in
    the window'). The same holds wherever no window can start at all (no surface point 3 d from
    the axis and 1 d under the apex: a flat layer, a handful of grains).

    Degenerate data never raise. On exact surfaces (grains placed with their tops on a cone,
    plus exposed grains under it) the residuals' MAD collapses to round-off and the bisquare
    alone would give every point zero weight (an empty fit range): :func:`robust_line` then
    moves the line onto the bulk of the points (their median residual) and goes on: on the
    exact cones of tests/analysis/test_flank_fit.py, with or without a foot, the slope comes
    back to round-off. Were a fit still to keep no point, the result would be the no-slope one
    with the note 'no straight flank: the robust fit gave no weight ...'.

    :returns: dict ``slope_deg``, ``slope_err_deg``, ``slope_sector_deg`` (per-sector fits),
        ``slope_note`` ('' when measured), ``fit_line`` (a, b) of h = a + b·r, ``fit_r_range``
        [m], ``n_fit_points``, ``n_surface``, ``surface_r``, ``surface_h`` [m] (all exposed
        grains), ``in_window``, ``weight`` (per exposed grain), ``H`` [m], ``d`` [m],
        ``R2`` [m], ``chord_angle_deg``, ``base_radius`` [m] (where the fitted line meets the
        floor), ``H_cone`` [m] (the line at r = 0).
    """
    snap, mask, z_floor = _pile_and_floor(snap, mask, z_floor, 'flank_slope')
    d = mean_diameter(snap)
    pos, rad = snap['pos'], snap['radius']
    H = float((pos[mask, 2] + rad[mask]).max() - z_floor)
    vis = surface_grains(snap, mask)
    r = np.hypot(pos[vis, 0], pos[vis, 1])
    h = pos[vis, 2] + rad[vis] - z_floor
    phi = np.mod(np.arctan2(pos[vis, 1], pos[vis, 0]), 2 * math.pi)
    sector = np.minimum((phi / (2 * math.pi / n_sectors)).astype(int), n_sectors - 1)
    r_lo, r_hi, h_start = _flank_range(r, h, phi, d, H, n_sectors)
    window = _envelope_points(r, phi, h, d) & (r >= r_lo) & (r < r_hi)
    nan = float('nan')
    out = {'slope_deg': nan, 'slope_err_deg': nan, 'slope_sector_deg': np.zeros(0), 'slope_note': '',
           'fit_line': (nan, nan), 'fit_r_range': (nan, nan), 'n_fit_points': int(window.sum()),
           'n_surface': int(vis.sum()), 'surface_r': r, 'surface_h': h, 'in_window': window,
           'weight': np.zeros(len(r)), 'H': H, 'd': d, 'base_radius': nan, 'H_cone': nan,
           'window_r': (r_lo, r_hi)}
    out.update(_chord(r, h, sector, n_sectors, H, d))
    if not np.isfinite(h_start):      # a flat layer, a handful of grains: nowhere for a flank to start
        out['slope_note'] = ('no straight flank: no surface point is %.0f d or more from the axis and %.0f d or more '
                             'under the apex (%.1f d high)' % (FLANK_CAP_RADIUS_D, FLANK_CAP_DROP_D, H / d))
        return out
    if not (h_start - FLANK_MIN_THICKNESS_D * d >= FLANK_MIN_SPAN_D * d * (1 - 1e-9)):   # round-off slack
        out['slope_note'] = ('no straight flank: the surface is %.1f grain diameters high where a flank could start '
                             '(3 d from the axis, 1 d under the apex at %.1f d), a flank needs %.1f'
                             % (h_start / d, H / d, FLANK_MIN_THICKNESS_D + FLANK_MIN_SPAN_D))
        return out
    if window.sum() < FLANK_MIN_POINTS:
        out['slope_note'] = 'no straight flank: %d surface points in the flank window' % window.sum()
        return out
    x, y, sec = r[window], h[window], sector[window]
    a, b, w = robust_line(x, y, d)
    if not (np.isfinite(b) and b < 0):
        out['slope_note'] = 'no descending flank in the window'
        return out
    used = w > 0
    if not used.any():    # robust_line never returns this with a finite line; kept so that no data can crash here
        out['slope_note'] = 'no straight flank: the robust fit gave no weight to any of the %d window points' % len(x)
        return out
    weight = np.zeros(len(r))
    weight[window] = w
    per_sector = []
    for s in range(n_sectors):
        m = sec == s
        if m.sum() >= 6 and len(np.unique(np.floor(x[m] / d))) >= 3:
            _, bs, _ = robust_line(x[m], y[m], d, start=(a, b))
            if np.isfinite(bs):
                per_sector.append(math.degrees(math.atan(-bs)))
    rng = np.random.default_rng(seed)
    boots = []
    members = [np.flatnonzero(sec == s) for s in range(n_sectors)]
    for _ in range(n_boot):
        pick = np.concatenate([members[s] for s in rng.integers(0, n_sectors, n_sectors)])
        if len(pick) < FLANK_MIN_POINTS:
            continue
        _, bb, _ = robust_line(x[pick], y[pick], d, start=(a, b))
        if np.isfinite(bb):
            boots.append(math.degrees(math.atan(-bb)))
    out.update(slope_deg=math.degrees(math.atan(-b)), fit_line=(a, b),
               slope_err_deg=float(np.std(boots, ddof=1)) if len(boots) > 1 else nan,
               slope_sector_deg=np.array(per_sector), weight=weight,
               fit_r_range=(float(x[used].min()), float(x[used].max())),
               base_radius=a / -b, H_cone=a)
    return out


FLANK_CELL_ARC_D = 2.0           # envelope cells: radial width d, arc length about 2 d


def _envelope_points(r, phi, h, d):
    """The highest exposed grain of every cell of (nearly) equal area: radial bins of width d,
    each cut into max(1, floor(2·pi·r_mid/(2 d))) azimuthal cells of arc length about 2 d. Every
    cell holds about as many surface grains as any other, so the highest one sits at the same
    depth under the envelope everywhere (cells of equal angle hold more grains far from the axis,
    whose highest grain then reads higher: a slope bias). Returns a bool mask."""
    sel = np.zeros(len(r), dtype=bool)
    if len(r) == 0:
        return sel
    j = (r / d).astype(np.int64)
    n_az = np.maximum(1, np.floor(2 * math.pi * (j + 0.5) / FLANK_CELL_ARC_D)).astype(np.int64)
    k = np.minimum((phi / (2 * math.pi) * n_az).astype(np.int64), n_az - 1)
    _, idx = _highest_per_cell(j * (int(n_az.max()) + 1) + k, h)
    sel[idx] = True
    return sel


def _flank_range(r, h, phi, d, H, n_sectors):
    """Radial range [r_lo, r_hi) of the flank and the surface height at its start [m].

    The envelope E(r) is the median over sectors of the highest exposed top per (sector, radial
    bin of width d). r_lo is the first bin at least 3 d from the axis where E is at least 1 d
    under the apex H (no cap); r_hi the first bin beyond it where E falls below 2 d (the pile is
    thinner than two grains: the foot). The window is chosen on r only, never on the height the
    line is fitted to (a cut on h would keep only the upper part of the scatter near the toe and
    flatten the line)."""
    nan = float('nan')
    if len(r) == 0:
        return nan, nan, nan
    n_bins = int(r.max() // d) + 1
    _, e_sb = _sector_profiles(r, phi, h, d, n_bins, n_sectors)
    env = _column_median(e_sb)
    centre = (np.arange(n_bins) + 0.5) * d
    with np.errstate(invalid='ignore'):
        ok_lo = (centre >= FLANK_CAP_RADIUS_D * d) & (env <= H - FLANK_CAP_DROP_D * d)
    if not ok_lo.any():
        return nan, nan, nan
    k_lo = int(np.flatnonzero(ok_lo)[0])
    with np.errstate(invalid='ignore'):
        thin = np.flatnonzero((np.arange(n_bins) > k_lo) & ~(env >= FLANK_MIN_THICKNESS_D * d))
    k_hi = int(thin[0]) if len(thin) else n_bins
    return k_lo * d, k_hi * d, float(env[k_lo])


def _chord(r, h, sector, n_sectors, H, d):
    """R2 (median over sectors of the outermost exposed grain at least 2 d high) and the chord
    angle atan((H - 2 d)/R2) [deg]."""
    thick = h >= FLANK_MIN_THICKNESS_D * d
    edges = [float(r[thick & (sector == s)].max()) for s in range(n_sectors) if (thick & (sector == s)).any()]
    R2 = float(np.median(edges)) if edges else float('nan')
    ok = R2 > 0 and H > FLANK_MIN_THICKNESS_D * d
    return {'R2': R2, 'chord_angle_deg': math.degrees(math.atan((H - FLANK_MIN_THICKNESS_D * d) / R2))
            if ok else float('nan')}


def profile_and_slope(snap, bin_width=None, n_sectors=8, z_floor=None, mask=None, n_boot=200):
    """Free surface of the pile: its profile, the flank slope, the apex height and the bulk
    density.

    The slope and its uncertainty are :func:`flank_slope`'s (exposed grains, a window in grain
    diameters, a bisquare fit, a bootstrap over sectors). For the figure and the volume, the
    plane is also cut in ``n_sectors`` azimuthal sectors and radial bins of width ``bin_width``
    [m] (default one mean diameter); in every (sector, bin) cell the highest grain top gives a
    point, and the profile h(r) is their median over sectors. ``slope_ls_window_deg`` keeps the
    estimator used before (least squares on those cell points between 15 % and 80 % of H): it
    reads several degrees low on cones of known slope (cell-size bias near the axis, foot layer,
    strays; docs/pile.md) and is reported only to compare with earlier numbers.

    :param z_floor: floor height [m]; default :func:`floor_level`.
    :returns: :func:`flank_slope`'s dict plus, lengths in m: ``r``, ``h`` median profile (h above
        the floor, nan where empty), ``bin_width``, ``r_sector``, ``h_sector`` (n_sectors,
        n_bins), ``z_floor``, ``slope_ls_window_deg``, ``profile_radius`` (outermost bin where
        the median profile is at least one mean diameter high), ``volume`` [m³] under the profile
        up to it, ``pile_mass`` [kg] of the pile grains inside it, ``rho_bulk`` [kg/m³] =
        pile_mass/volume (an estimate: the profile follows grain tops), ``n_grains``.
    """
    snap, mask, z_floor = _pile_and_floor(snap, mask, z_floor, 'profile_and_slope')
    result = flank_slope(snap, mask=mask, z_floor=z_floor, n_sectors=n_sectors, n_boot=n_boot)
    w = float(bin_width) if bin_width is not None else mean_diameter(snap)
    pos, rad = snap['pos'][mask], snap['radius'][mask]
    r = np.hypot(pos[:, 0], pos[:, 1])
    phi = np.mod(np.arctan2(pos[:, 1], pos[:, 0]), 2 * math.pi)
    top = pos[:, 2] + rad - z_floor
    n_bins = int(r.max() // w) + 1
    r_sb, h_sb = _sector_profiles(r, phi, top, w, n_bins, n_sectors)
    H = result['H']
    with np.errstate(invalid='ignore'):
        legacy = (h_sb >= 0.15 * H) & (h_sb <= 0.8 * H)
    _, b_ls, _ = linear_fit(r_sb[legacy], h_sb[legacy])
    r_prof, h_prof = _column_median(r_sb), _column_median(h_sb)
    d = result['d']
    with np.errstate(invalid='ignore'):
        high = np.flatnonzero(h_prof >= d)
    edge = float(r_prof[high[-1]] + 0.5 * w) if len(high) else float('nan')
    result.update({'r': r_prof, 'h': h_prof, 'bin_width': w, 'r_sector': r_sb, 'h_sector': h_sb,
                   'z_floor': z_floor, 'profile_radius': edge,
                   'slope_ls_window_deg': math.degrees(math.atan(-b_ls)) if np.isfinite(b_ls) else float('nan'),
                   'n_grains': int(mask.sum())})
    result.update(_bulk_density(snap, mask, r_prof, h_prof, edge))
    return result


def _bulk_density(snap, mask, r_prof, h_prof, base):
    """Volume under the profile, mass of the pile grains whose centre is inside the base radius,
    and their ratio (dict ``volume`` [m³], ``pile_mass`` [kg], ``rho_bulk`` [kg/m³])."""
    if not base > 0:
        return {'volume': float('nan'), 'pile_mass': float('nan'), 'rho_bulk': float('nan')}
    r = np.hypot(snap['pos'][:, 0], snap['pos'][:, 1])
    mass = float(grain_masses(snap)[mask & (r < base)].sum())
    volume = _cone_volume(r_prof, h_prof, base)
    return {'volume': volume, 'pile_mass': mass,
            'rho_bulk': mass / volume if volume > 0 else float('nan')}

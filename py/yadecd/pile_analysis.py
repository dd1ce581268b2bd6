"""Analysis of a sand pile built by Contact Dynamics (Moreau, section IV): free surface,
force transmission across revolved bands, ground pressure, fabric, speed classes, fossil layers.

Pure numpy: nothing here needs YADE, so ``yadecd.pile_analysis`` imports under Debian's
``/usr/bin/python3`` as well (see ``scripts/pile_figures.py``). Everything is SI inside: metres, seconds,
kilograms, newtons, pascals, radians (angles *returned* in degrees say so in their name).

Snapshot format (one ``.npz`` per epoch, written by the deposition script)::

    time, g (>0), rho                 scalars [s], [m/s²], grain density [kg/m³]
    pos (N,3), radius (N,), vel (N,3) [m], [m], [m/s]
    fixed (N,) bool                   paving grains of the floor
    birth (N,)                        creation time [s], -1 for paving grains
    ids (N,)                          YADE body ids
    c_id1, c_id2 (M,)                 body ids of each contact
    c_point (M,3), c_normal (M,3)     contact point [m], unit normal from body 1 to body 2
    c_force (M,3)                     total force exerted ON body 2 BY body 1 [N]

The pile axis Oz is the vertical line x = y = 0. A contact whose body id is not among ``ids``
(a wall, say) is ignored everywhere.

Meridian coordinates. A point (x, y, z) has r = sqrt(x² + y²) and e_r = (x, y, 0)/r, the unit
radial (axifugal) vector of its meridian half-plane; on the axis (r = 0) e_r is taken as 0, so a
force applied there contributes nothing radial. Vectors "in the meridian plane" are pairs (r, z).

Band convention (used by :func:`band_force_density` and everything built on it). A band is the
surface swept by the segment p0 -> p1 = (r0, z0) -> (r1, z1) turned about Oz. Its unit tangent is
d = (p1 - p0)/|p1 - p0| and its unit normal is d turned by +90° in the (r, z) plane,
n = (-d_z, d_r). So a horizontal annulus drawn outward (r0 < r1) has n = +e_z (up), a cylinder
drawn downward (z0 > z1) has n = +e_r (outward), a cone drawn from the apex side down the flank
has n pointing up and out of the pile. The "+ side" is the side n points to. The force density is

    T = (sum of forces exerted by the grains on the + side on the grains on the - side) / area,

i.e. the Cauchy traction on the - side material, T = sigma·n with sigma counted positive in
tension. In a pile under compression T·n < 0 (a horizontal cut with n up gets T_z < 0, the weight
of what lies above). Reversing the segment reverses both n and T. Pressure (compression positive,
the geomechanics convention) is -T.
"""
import json
import math
import os
import re
from typing import NamedTuple

import numpy as np

__all__ = ['load_snapshot', 'list_snapshots', 'run_parameters', 'grain_masses', 'pile_mask',
           'floor_level', 'mean_diameter', 'slice_mask', 'profile_and_slope', 'flank_slope',
           'surface_grains', 'robust_line', 'horizontal_pairs', 'band_segment',
           'band_force_density', 'BandDensity', 'reciprocal_cuts', 'reciprocal_pairs',
           'cylindrical_cut_directions', 'ground_pressure', 'contact_orientation_histogram',
           'speed_levels', 'fossil_layer', 'central_dip', 'mean_interval',
           'jackknife_ratio_dip', 't_quantile_975', 't_cdf', 'layer_directions',
           'line_angle_between', 'fossil_law']

REQUIRED_KEYS = ('time', 'g', 'rho', 'pos', 'radius', 'vel', 'fixed', 'birth', 'ids',
                 'c_id1', 'c_id2', 'c_point', 'c_normal', 'c_force')
_SNAP_NAME = re.compile(r'^snap_([-+0-9.eE]+)\.npz$')


# ---------------------------------------------------------------------------------------------
# loading

def _normalise(snap):
    """Return a new dict with every snapshot array at its documented dtype and shape
    (float64 vectors as (n, 3), bool ``fixed``, int64 ids; ``g`` made positive). Raises
    KeyError for a missing key and ValueError for inconsistent lengths."""
    missing = [k for k in REQUIRED_KEYS if k not in snap]
    if missing:
        raise KeyError('snapshot lacks %s' % ', '.join(missing))
    out = dict(snap)
    for k in ('time', 'g', 'rho'):
        out[k] = float(np.asarray(snap[k]).reshape(()))
    out['g'] = abs(out['g'])
    for k in ('pos', 'vel', 'c_point', 'c_normal', 'c_force'):
        out[k] = np.asarray(snap[k], dtype=float).reshape(-1, 3)
    out['radius'] = np.asarray(snap['radius'], dtype=float).reshape(-1)
    out['birth'] = np.asarray(snap['birth'], dtype=float).reshape(-1)
    out['fixed'] = np.asarray(snap['fixed']).astype(bool).reshape(-1)
    for k in ('ids', 'c_id1', 'c_id2'):
        out[k] = np.asarray(snap[k]).astype(np.int64).reshape(-1)
    n, m = len(out['pos']), len(out['c_id1'])
    for k in ('radius', 'vel', 'fixed', 'birth', 'ids'):
        if len(out[k]) != n:
            raise ValueError('snapshot: %s has %d rows, pos has %d' % (k, len(out[k]), n))
    for k in ('c_id2', 'c_point', 'c_normal', 'c_force'):
        if len(out[k]) != m:
            raise ValueError('snapshot: %s has %d rows, c_id1 has %d' % (k, len(out[k]), m))
    if len(np.unique(out['ids'])) != n:
        raise ValueError('snapshot: body ids are not unique')
    return out


def load_snapshot(path):
    """Read one snapshot ``.npz`` file (format in the module docstring, SI units).

    :param path: file name.
    :returns: dict with the arrays of the file (float64 / bool / int64, vectors as (n, 3)) and
        ``'path'``. ``g`` is returned as a positive magnitude [m/s²].
    """
    with np.load(path, allow_pickle=False) as data:
        raw = {k: data[k] for k in data.files}
    snap = _normalise(raw)
    snap['path'] = str(path)
    return snap


def list_snapshots(run_dir):
    """Snapshots of a run directory, sorted by time.

    :param run_dir: directory holding ``snap_<time>.npz`` files (time in seconds in the name).
    :returns: list of ``(time [s], path)``.
    """
    found = []
    for name in os.listdir(run_dir):
        m = _SNAP_NAME.match(name)
        if m:
            try:
                t = float(m.group(1))
            except ValueError:
                continue
            found.append((t, os.path.join(run_dir, name)))
    return sorted(found)


def run_parameters(run_dir):
    """The ``run.json`` of a run directory as a dict ({} when absent)."""
    path = os.path.join(run_dir, 'run.json')
    if not os.path.exists(path):
        return {}
    with open(path) as f:
        return json.load(f)


# ---------------------------------------------------------------------------------------------
# grains

def grain_masses(snap):
    """Mass of every grain [kg]: rho·(4/3)·pi·radius³."""
    snap = _normalise(snap)
    return snap['rho'] * 4.0 / 3.0 * math.pi * snap['radius'] ** 3


def body_index(snap, body_ids):
    """Row index in the grain arrays of each YADE body id of ``body_ids``; -1 where the id is not
    a grain of the snapshot (e.g. a wall)."""
    ids = np.asarray(snap['ids'], dtype=np.int64)
    body_ids = np.asarray(body_ids, dtype=np.int64)
    order = np.argsort(ids, kind='stable')
    sorted_ids = ids[order]
    if len(ids) == 0:
        return np.full(body_ids.shape, -1, dtype=np.int64)
    at = np.clip(np.searchsorted(sorted_ids, body_ids), 0, len(ids) - 1)
    return np.where(sorted_ids[at] == body_ids, order[at], -1)


def pile_mask(snap):
    """Grains that belong to the pile: not fixed and carrying at least one contact with a
    non-zero force (grains in free flight are left out). When the snapshot holds no loaded
    contact at all, every non-fixed grain counts. Returns a bool array (N,)."""
    snap = _normalise(snap)
    free = ~snap['fixed']
    loaded = np.linalg.norm(snap['c_force'], axis=1) > 0
    if not loaded.any():
        return free
    touched = np.zeros(len(free), dtype=bool)
    for key in ('c_id1', 'c_id2'):
        idx = body_index(snap, snap[key][loaded])
        touched[idx[idx >= 0]] = True
    return free & touched


def wall_only_grains(snap):
    """Grains (not fixed) whose every loaded contact is with a body that is not a grain of the
    snapshot (the floor wall), and that have at least one: grains standing alone on the flat
    wall, between paving grains. Rolling there is a neutral equilibrium (CD has no rolling
    resistance), so such a grain may keep a horizontal velocity in a pile that is otherwise at
    rest. Returns a bool array (N,)."""
    snap = _normalise(snap)
    loaded = np.linalg.norm(snap['c_force'], axis=1) > 0
    i1, i2 = body_index(snap, snap['c_id1'][loaded]), body_index(snap, snap['c_id2'][loaded])
    on_wall = np.zeros(len(snap['pos']), dtype=bool)
    on_grain = np.zeros(len(snap['pos']), dtype=bool)
    for a, b in ((i1, i2), (i2, i1)):
        on_wall[a[(a >= 0) & (b < 0)]] = True
        on_grain[a[(a >= 0) & (b >= 0)]] = True
    return ~snap['fixed'] & on_wall & ~on_grain


def rest_speed(snap):
    """How far a pile is from rest [m/s]: the largest speed of a free grain, where grains standing
    alone on the floor wall (:func:`wall_only_grains`) count with their vertical speed only (they
    may roll); grains in flight count in full. 0 for a snapshot without free grains."""
    snap = _normalise(snap)
    free = ~snap['fixed']
    speed = np.linalg.norm(snap['vel'], axis=1)
    rolling = wall_only_grains(snap)
    speed[rolling] = np.abs(snap['vel'][rolling, 2])
    return float(speed[free].max()) if free.any() else 0.0


def floor_level(snap):
    """Height of the floor [m]: median height of the tops (z + radius) of the fixed paving grains,
    or 0 when there is none."""
    snap = _normalise(snap)
    fixed = snap['fixed']
    if not fixed.any():
        return 0.0
    return float(np.median(snap['pos'][fixed, 2] + snap['radius'][fixed]))


def mean_diameter(snap):
    """Mean diameter of the non-fixed grains [m] (of all grains if all are fixed)."""
    snap = _normalise(snap)
    free = ~snap['fixed']
    radii = snap['radius'][free] if free.any() else snap['radius']
    return float(2.0 * radii.mean()) if len(radii) else float('nan')


def slice_mask(snap, half_thickness=0.01):
    """Grains whose centre lies in the slab |y| < half_thickness [m] (the slab contains Oz).
    Returns a bool array (N,)."""
    snap = _normalise(snap)
    return np.abs(snap['pos'][:, 1]) < half_thickness


def fossil_layer(snap, t1, t2):
    """Fossil layer: non-fixed grains born in [t1, t2] [s] (bounds included). Returns a bool
    array (N,)."""
    snap = _normalise(snap)
    birth = snap['birth']
    return (~snap['fixed']) & (birth >= t1) & (birth <= t2)


def speed_levels(snap, vmax=None, factor=0.18, n_thresholds=4):
    """Moreau's Figure 1 grey levels.

    Thresholds are ``vmax·factor**k`` for k = 1..n_thresholds [m/s]; ``vmax`` defaults to the
    largest speed of a non-fixed grain. Class 0 (black) holds speeds above the first threshold,
    class k speeds in (threshold k+1, threshold k], and the last class (white, number
    n_thresholds) speeds at or below the smallest threshold.

    :returns: dict ``vmax`` [m/s], ``thresholds`` [m/s] (decreasing), ``speed`` (N,) [m/s],
        ``level`` (N,) int class, ``grey`` (N,) float in [0, 1] (0 black, 1 white),
        ``counts`` per class.
    """
    snap = _normalise(snap)
    speed = np.linalg.norm(snap['vel'], axis=1)
    free = ~snap['fixed']
    if vmax is None:
        vmax = float(speed[free].max()) if free.any() else 0.0
    thresholds = vmax * factor ** np.arange(1, n_thresholds + 1, dtype=float)
    level = (speed[:, None] <= thresholds[None, :]).sum(axis=1)
    return {'vmax': float(vmax), 'thresholds': thresholds, 'speed': speed, 'level': level,
            'grey': level / float(n_thresholds),
            'counts': np.bincount(level, minlength=n_thresholds + 1)}


# ---------------------------------------------------------------------------------------------
# geometry helpers

def meridian(points):
    """Meridian coordinates of points (n, 3) [m]: returns ``(rz, e_r)`` with rz (n, 2) = (r, z)
    and e_r (n, 3) the unit radial vector (0 on the axis)."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    r = np.hypot(points[:, 0], points[:, 1])
    e_r = np.zeros_like(points)
    off = r > 0
    e_r[off, 0] = points[off, 0] / r[off]
    e_r[off, 1] = points[off, 1] / r[off]
    return np.column_stack([r, points[:, 2]]), e_r


def _linear_fit(x, y):
    """Least-squares line y = a + b·x. Returns (a, b, standard error of b); the error is nan
    with fewer than 3 points."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if len(x) < 2:
        return float('nan'), float('nan'), float('nan')
    xm, ym = x.mean(), y.mean()
    sxx = ((x - xm) ** 2).sum()
    if sxx == 0:
        return float('nan'), float('nan'), float('nan')
    b = ((x - xm) * (y - ym)).sum() / sxx
    a = ym - b * xm
    if len(x) < 3:
        return float(a), float(b), float('nan')
    resid = y - a - b * x
    se_b = math.sqrt((resid ** 2).sum() / (len(x) - 2) / sxx)
    return float(a), float(b), se_b


def _grain_contacts(snap):
    """Contacts between two grains of the snapshot (ids not found are dropped), as a dict:
    ``i1``, ``i2`` grain row indices; ``point`` (K,3); ``normal`` (K,3); ``force`` (K,3) on body 2
    by body 1 [N]; ``pt_rz`` (K,2) meridian coordinates of the contact point; ``e_r`` (K,3);
    ``rz1``, ``rz2`` meridian coordinates of the two centres; ``force_rz`` (K,2) = (F·e_r, F_z)
    of the force on body 2 at the contact point."""
    i1 = body_index(snap, snap['c_id1'])
    i2 = body_index(snap, snap['c_id2'])
    ok = (i1 >= 0) & (i2 >= 0)
    i1, i2 = i1[ok], i2[ok]
    point, force = snap['c_point'][ok], snap['c_force'][ok]
    pt_rz, e_r = meridian(point)
    rz1, _ = meridian(snap['pos'][i1])
    rz2, _ = meridian(snap['pos'][i2])
    force_rz = np.column_stack([(force * e_r).sum(axis=1), force[:, 2]])
    return {'i1': i1, 'i2': i2, 'point': point, 'normal': snap['c_normal'][ok], 'force': force,
            'pt_rz': pt_rz, 'e_r': e_r, 'rz1': rz1, 'rz2': rz2, 'force_rz': force_rz}


# ---------------------------------------------------------------------------------------------
# free surface

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
    snap = _normalise(snap)
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
    snap = _normalise(snap)
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


def _weighted_line(x, y, w):
    """Weighted least-squares line y = a + b·x; (nan, nan) when degenerate."""
    sw = w.sum()
    if sw <= 0:
        return float('nan'), float('nan')
    xm, ym = (w * x).sum() / sw, (w * y).sum() / sw
    sxx = (w * (x - xm) ** 2).sum()
    if sxx <= 0:
        return float('nan'), float('nan')
    b = (w * (x - xm) * (y - ym)).sum() / sxx
    return float(ym - b * xm), float(b)


def _theil_sen(x, y):
    """Theil–Sen line: b = median of the pairwise slopes (distinct x), a = median(y - b·x)."""
    i, j = np.triu_indices(len(x), 1)
    dx = x[j] - x[i]
    ok = dx != 0
    if not ok.any():
        return float('nan'), float('nan')
    b = float(np.median((y[j] - y[i])[ok] / dx[ok]))
    return float(np.median(y - b * x)), b


def robust_line(x, y, bin_width, c=4.685, max_iter=50, start=None):
    """Line y = a + b·x resistant to outliers (stray grains, a foot, a cap left in the window).

    Start: the Theil–Sen line through the medians of y in bins of x of width ``bin_width`` (or
    ``start`` = (a, b)), refined by 10 Huber iterations (weights min(1, 1.345 s/|residual|),
    never zero). Then Tukey's bisquare, iteratively reweighted: weights
    (1 - u²)² for |u| < 1, u = residual/(c·s), s = 1.4826·MAD of the residuals; points farther
    than c·s get no weight. Returns (a, b, weights); (nan, nan, zeros) with fewer than two
    distinct bins."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    w = np.zeros(len(x))
    if start is None:
        k = np.floor(x / bin_width).astype(np.int64)
        cells = np.unique(k)
        if len(cells) < 2:
            return float('nan'), float('nan'), w
        xb = np.array([np.median(x[k == c_]) for c_ in cells])
        yb = np.array([np.median(y[k == c_]) for c_ in cells])
        a, b = _theil_sen(xb, yb)
    else:
        a, b = start
    if not np.isfinite(b):
        return float('nan'), float('nan'), w
    w = np.ones(len(x))
    s_floor = 1e-9 * max(float(np.ptp(y)), 1e-300)   # exact data: the scale never reaches 0
    for it in range(max_iter + 10):
        e = y - a - b * x
        s = max(1.4826 * float(np.median(np.abs(e - np.median(e)))), s_floor)
        if it < 10:      # Huber first: never a zero weight, so a rough start cannot lose every point
            w = np.minimum(1.0, 1.345 * s / np.maximum(np.abs(e), 1e-300))
            a, b = _weighted_line(x, y, w)
            continue
        u = e / (c * s)
        w = np.where(np.abs(u) < 1, (1 - u * u) ** 2, 0.0)
        a2, b2 = _weighted_line(x, y, w)
        if not np.isfinite(b2):
            break
        done = abs(b2 - b) <= 1e-12 * max(1.0, abs(b)) and abs(a2 - a) <= 1e-12 * max(1.0, abs(a))
        a, b = a2, b2
        if done:
            break
    return float(a), float(b), w


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
    ``slope_note`` says why.

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
    weight = np.zeros(len(r))
    weight[window] = w
    used = w > 0
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
    _, b_ls, _ = _linear_fit(r_sb[legacy], h_sb[legacy])
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


# ---------------------------------------------------------------------------------------------
# bands

class BandDensity(NamedTuple):
    """Meridian force density through a revolved band (see the module docstring for signs).

    ``T`` = (T_r, T_z) [Pa]; ``n`` = (n_r, n_z) unit normal; ``area`` [m²]; ``count`` contacts
    kept; ``force`` = (sum R_r, sum R_z) [N]; ``p0``, ``p1`` the segment [m]."""
    T: np.ndarray
    n: np.ndarray
    area: float
    count: int
    force: np.ndarray
    p0: np.ndarray
    p1: np.ndarray


def band_geometry(p0, p1):
    """Tangent d, normal n = d turned by +90° in (r, z), length L [m] and area [m²] of the band
    swept by segment p0 -> p1 (points (r, z) [m], r ≥ 0) about Oz. The area is the lateral area
    pi·(r0 + r1)·L (for a horizontal annulus this is pi·|r1² - r0²|)."""
    p0 = np.asarray(p0, dtype=float).reshape(2)
    p1 = np.asarray(p1, dtype=float).reshape(2)
    if min(p0[0], p1[0]) < 0:
        raise ValueError('band: the segment must lie in the half-plane r >= 0')
    length = float(np.hypot(*(p1 - p0)))
    if length == 0:
        raise ValueError('band: p0 and p1 coincide')
    d = (p1 - p0) / length
    n = np.array([-d[1], d[0]])
    area = math.pi * (p0[0] + p1[0]) * length
    if area <= 0:
        raise ValueError('band: a segment on the axis sweeps no area')
    return d, n, length, area


def band_segment(centre, angle_deg, length):
    """Segment (p0, p1) [m] of given length centred on ``centre`` = (r, z) whose direction makes
    ``angle_deg`` with +e_r, counter-clockwise towards +e_z. Its band normal is
    n = (-sin angle, cos angle): angle 0 gives a horizontal cut with n up, angle -90 a
    cylindrical cut with n outward."""
    c = np.asarray(centre, dtype=float).reshape(2)
    a = math.radians(angle_deg)
    u = np.array([math.cos(a), math.sin(a)])
    return c - 0.5 * length * u, c + 0.5 * length * u


def _band_from_contacts(cont, p0, p1):
    """:func:`band_force_density` on a precomputed :func:`_grain_contacts` table."""
    d, n, length, area = band_geometry(p0, p1)
    p0 = np.asarray(p0, dtype=float)
    plus1 = (cont['rz1'] - p0) @ n > 0
    plus2 = (cont['rz2'] - p0) @ n > 0
    t = (cont['pt_rz'] - p0) @ d
    keep = (plus1 != plus2) & (t >= 0) & (t <= length)
    # c_force acts on body 2: it is the force on the - side grain when body 1 is on the + side
    sign = np.where(plus1[keep], 1.0, -1.0)
    total = (sign[:, None] * cont['force_rz'][keep]).sum(axis=0)
    return BandDensity(T=total / area, n=n, area=area, count=int(keep.sum()), force=total,
                       p0=p0, p1=np.asarray(p1, dtype=float))


def band_force_density(snap, p0, p1):
    """Moreau's meridian force density through the band swept about Oz by segment p0 -> p1.

    :param p0, p1: (r, z) [m], r ≥ 0.
    Kept contacts: the two grain centres lie strictly on opposite sides of the surface of
    revolution of the line (p0, p1) (a centre on it counts as - side), and the contact point,
    projected orthogonally in its meridian half-plane onto that line, falls within the segment.
    Fixed grains are treated like any other grain. Each kept force (the one exerted by the + side
    grain on the - side grain) is split at the contact point into R_r (along e_r) and R_z; the
    azimuthal part is ignored. T = (sum R_r, sum R_z)/area.

    :returns: :class:`BandDensity` (T [Pa], n, area [m²], count, force [N], p0, p1).
    """
    return _band_from_contacts(_grain_contacts(_normalise(snap)), p0, p1)


def reciprocal_pairs(centres, angles_deg=(-90.0, -45.0, 0.0, 45.0), length=0.015):
    """Pairs of bands crossing at each centre (r, z) [m]: every pair of distinct directions of
    ``angles_deg`` (see :func:`band_segment`), segments of ``length`` [m]. Centres too close to
    the axis for a segment are skipped. Returns a list of ``((p0, p1), (p0', p1'))``."""
    pairs = []
    angles = list(angles_deg)
    for c in centres:
        segs = [band_segment(c, a, length) for a in angles]
        if min(min(s[0][0], s[1][0]) for s in segs) < 0:
            continue
        for i in range(len(segs)):
            for j in range(i + 1, len(segs)):
                pairs.append((segs[i], segs[j]))
    return pairs


def reciprocal_cuts(snap, pairs):
    """Reciprocal-cuts check (Moreau's Fig. 3): for each pair of bands (n, T), (n', T'),
    ``a`` = n·T' and ``b`` = n'·T [Pa], equal for a symmetric Cauchy stress.

    :param pairs: sequence of ``((p0, p1), (p0', p1'))`` segments (see :func:`band_segment`).
    :returns: dict of arrays per pair: ``nT2`` = n·T', ``n2T`` = n'·T [Pa], ``rel`` =
        |a - b|/sqrt(|T||T'|) (nan if a band is empty), ``count``, ``count2``, ``centre``
        (mean of the four end points), and statistics over the pairs with a finite ``rel``:
        ``rel_mean``, ``rel_std``, ``rel_median``, ``n_pairs``, ``corr`` (Pearson correlation of
        a and b), ``rms_diff_Pa`` = rms(a - b), ``rms_mean_Pa`` = rms((a + b)/2).
    """
    cont = _grain_contacts(_normalise(snap))
    bands1 = [_band_from_contacts(cont, *seg) for seg, _ in pairs]
    bands2 = [_band_from_contacts(cont, *seg2) for _, seg2 in pairs]
    out = {k: [] for k in ('nT2', 'n2T', 'rel', 'count', 'count2', 'centre')}
    for b1, b2 in zip(bands1, bands2):
        a, b, rel = _reciprocity(b1, b2)
        out['nT2'].append(a)
        out['n2T'].append(b)
        out['rel'].append(rel)
        out['count'].append(b1.count)
        out['count2'].append(b2.count)
        out['centre'].append((b1.p0 + b1.p1 + b2.p0 + b2.p1) / 4)
    out = {k: np.array(v, dtype=float) for k, v in out.items()}
    out['centre'] = out['centre'].reshape(-1, 2)
    out.update(_reciprocity_stats(out['nT2'], out['n2T'], out['rel']))
    out['rel_null'] = _reciprocity_null(bands1, bands2)
    ok = np.isfinite(out['rel_null'])
    out['rel_null_mean'] = float(out['rel_null'][ok].mean()) if ok.any() else float('nan')
    out['rel_null_median'] = float(np.median(out['rel_null'][ok])) if ok.any() else float('nan')
    return out


def _reciprocity(b1, b2):
    """n·T', n'·T [Pa] and |n·T' - n'·T|/sqrt(|T||T'|) (nan for an empty band) of two bands."""
    a, b = float(b1.n @ b2.T), float(b2.n @ b1.T)
    scale = math.sqrt(np.linalg.norm(b1.T) * np.linalg.norm(b2.T))
    return a, b, (abs(a - b) / scale if scale > 0 else float('nan'))


def _reciprocity_null(bands1, bands2):
    """The reciprocity statistic with no reason to hold: each pair's second band is replaced by
    the second band of the pair half the list further on (rounded to a multiple of six, the
    pairs per centre, so the orientations match), i.e. T' is measured at a distant place of the
    pile. Its spread is the scale against which the true pairs' agreement is read."""
    k = len(bands1)
    shift = 6 * max(1, (k // 6) // 2)
    if k < 7 or shift >= k:
        return np.full(k, np.nan)
    return np.array([_reciprocity(bands1[i], bands2[(i + shift) % k])[2] for i in range(k)])


def _reciprocity_stats(a, b, rel):
    """Summary statistics of the reciprocity check over pairs with a finite relative
    difference."""
    ok = np.isfinite(rel)
    n = int(ok.sum())
    nan = float('nan')
    if n == 0:
        return {'n_pairs': 0, 'rel_mean': nan, 'rel_std': nan, 'rel_median': nan, 'corr': nan,
                'rms_diff_Pa': nan, 'rms_mean_Pa': nan}
    a, b, rel = a[ok], b[ok], rel[ok]
    corr = float(np.corrcoef(a, b)[0, 1]) if n > 1 and a.std() > 0 and b.std() > 0 else nan
    return {'n_pairs': n, 'rel_mean': float(rel.mean()),
            'rel_std': float(rel.std(ddof=1)) if n > 1 else nan,
            'rel_median': float(np.median(rel)), 'corr': corr,
            'rms_diff_Pa': float(np.sqrt(((a - b) ** 2).mean())),
            'rms_mean_Pa': float(np.sqrt((((a + b) / 2) ** 2).mean()))}


def _line_angles(Tr, Tz):
    """Direction of force densities taken as lines: angle from the vertical in [0, 90] and
    inclination on the horizontal in [-90, 90] (positive when the line rises outward) [deg];
    nan for a zero vector."""
    Tr, Tz = np.asarray(Tr, dtype=float), np.asarray(Tz, dtype=float)
    zero = (Tr == 0) & (Tz == 0)
    flip = np.where(Tr < 0, -1.0, 1.0)          # orient the line outward (radial part >= 0)
    incl = np.degrees(np.arctan2(flip * Tz, np.abs(Tr)))
    from_vertical = np.degrees(np.arctan2(np.abs(Tr), np.abs(Tz)))
    return np.where(zero, np.nan, from_vertical), np.where(zero, np.nan, incl)


def cylindrical_cut_directions(snap, radii, heights, band_height):
    """Force density on small cylindrical bands about Oz (Moreau's Fig. 4).

    At every (r, z) of the grid ``radii`` x ``heights`` [m] the band is the vertical segment from
    (r, z + band_height/2) down to (r, z - band_height/2), so n = +e_r (outward) and T is the force
    per area exerted by the outer grains on the inner ones [Pa].

    :returns: dict of arrays shaped (len(radii), len(heights)): ``r``, ``z`` [m], ``Tr``, ``Tz``
        [Pa], ``magnitude`` [Pa], ``count``, ``angle_from_vertical_deg`` in [0, 90] and
        ``inclination_deg`` in [-90, 90] (positive when the line of T rises outward; a layer
        parallel to a 26° flank gives -26), both for T taken as a line (nan where T = 0);
        ``band_height`` [m].
    """
    cont = _grain_contacts(_normalise(snap))
    radii = np.asarray(radii, dtype=float)
    heights = np.asarray(heights, dtype=float)
    shape = (len(radii), len(heights))
    Tr, Tz, count = np.zeros(shape), np.zeros(shape), np.zeros(shape, dtype=int)
    for i, r in enumerate(radii):
        for j, z in enumerate(heights):
            band = _band_from_contacts(cont, (r, z + band_height / 2), (r, z - band_height / 2))
            Tr[i, j], Tz[i, j] = band.T
            count[i, j] = band.count
    from_vertical, incl = _line_angles(Tr, Tz)
    rr, zz = np.meshgrid(radii, heights, indexing='ij')
    return {'r': rr, 'z': zz, 'Tr': Tr, 'Tz': Tz, 'magnitude': np.hypot(Tr, Tz), 'count': count,
            'angle_from_vertical_deg': from_vertical, 'inclination_deg': incl,
            'band_height': float(band_height)}


def layer_directions(snap, points_rz, radius, mask=None, min_grains=12):
    """Local direction of the fossil layers at meridian points.

    The layers are the level sets of the birth time. At each point (r, z) [m] of ``points_rz``,
    a linear birth time t = c + g_r·(r' - r) + g_z·(z' - z) is fitted by least squares to the
    pile grains (``mask``, default :func:`pile_mask`, born at t >= 0) whose meridian coordinates
    (r', z') lie within ``radius`` [m] of it, all azimuths pooled. The layer through the point runs
    perpendicular to the gradient (g_r, g_z).

    :returns: dict of arrays (one per point): ``inclination_deg`` of the layer as a line in
        [-90, 90] (positive when it rises outward, a layer parallel to a 26° flank gives -26),
        ``r2`` the fit's coefficient of determination (how much of the birth-time spread the
        layering explains), ``n`` grains used, ``gradient_s_m`` |g| [s/m]; nan where fewer than
        ``min_grains`` grains are near.
    """
    snap = _normalise(snap)
    if mask is None:
        mask = pile_mask(snap)
    use = mask & (snap['birth'] >= 0)
    rz, _ = meridian(snap['pos'][use])
    birth = snap['birth'][use]
    pts = np.asarray(points_rz, dtype=float).reshape(-1, 2)
    k = len(pts)
    incl, r2, count, grad = (np.full(k, np.nan) for _ in range(4))
    for i, p in enumerate(pts):
        near = ((rz - p) ** 2).sum(axis=1) < radius * radius
        n = int(near.sum())
        count[i] = n
        if n < min_grains:
            continue
        X = np.column_stack([np.ones(n), rz[near] - p])
        y = birth[near]
        coef, *_ = np.linalg.lstsq(X, y, rcond=None)
        resid = y - X @ coef
        sst = ((y - y.mean()) ** 2).sum()
        r2[i] = 1 - (resid ** 2).sum() / sst if sst > 0 else 0.0
        gr, gz = coef[1], coef[2]
        grad[i] = math.hypot(gr, gz)
        if grad[i] > 0:
            incl[i] = _line_angles(np.array([gz]), np.array([-gr]))[1][0]
    return {'inclination_deg': incl, 'r2': r2, 'n': count, 'gradient_s_m': grad}


def line_angle_between(incl1_deg, incl2_deg):
    """Angle [deg] in [0, 90] between lines of inclinations ``incl1_deg`` and ``incl2_deg``."""
    diff = np.mod(np.asarray(incl1_deg, dtype=float) - np.asarray(incl2_deg, dtype=float), 180.0)
    return np.minimum(diff, 180.0 - diff)


def fossil_law(snap, cyl, layer_radius, surface_slope_deg, min_r2=0.3, n_perm=50, seed=0):
    """Moreau's empirical law for cylindrical cuts, tested: the force density on a cylindrical
    cut points along the meridian section of a nearby fossil layer.

    For every cut of ``cyl`` (:func:`cylindrical_cut_directions`, with an optional bool grid
    ``inside``) carrying contacts, the angle between the line of T and the local layer
    (:func:`layer_directions` with ``layer_radius`` [m]) is measured, where the layering explains
    at least ``min_r2`` of the birth-time spread. Two null models give the angles the law would
    have by chance: the free surface's direction (a line of inclination -``surface_slope_deg``;
    nan skips it) and a random layer (the layer direction of another cut, ``n_perm``
    permutations with a fixed ``seed``). Uniformly random lines would give 45° on average.

    :returns: dict ``angle_layer_deg`` (per cut used), ``angle_surface_deg``,
        ``angle_random_layer_deg`` (mean over permutations, per cut), ``r``, ``z`` [m],
        ``n_cuts``, ``median_layer_deg``, ``median_surface_deg``, ``median_random_deg``,
        ``mean_layer_deg``, ``mean_random_deg``, ``fraction_within_15deg``, ``advantage_deg`` =
        mean(random - layer) with ``advantage_ci95`` (t interval over cuts; cuts overlap, so
        this interval is optimistic and the ensemble's interval over piles is the one to read).
    """
    ok = (cyl['count'] > 0) & np.isfinite(cyl['inclination_deg'])
    if 'inside' in cyl:
        ok &= cyl['inside']
    r, z = cyl['r'][ok], cyl['z'][ok]
    lay = layer_directions(snap, np.column_stack([r, z]), layer_radius)
    good = np.isfinite(lay['inclination_deg']) & (lay['r2'] >= min_r2)
    t_incl = cyl['inclination_deg'][ok][good]
    l_incl = lay['inclination_deg'][good]
    a_layer = line_angle_between(t_incl, l_incl)
    a_surf = line_angle_between(t_incl, -surface_slope_deg) if math.isfinite(surface_slope_deg) \
        else np.full(len(t_incl), np.nan)
    rng = np.random.default_rng(seed)
    if len(l_incl) > 1:
        a_rand = np.mean([line_angle_between(t_incl, rng.permutation(l_incl)) for _ in range(n_perm)], axis=0)
    else:
        a_rand = np.full(len(l_incl), np.nan)
    nan = float('nan')
    med = lambda a: float(np.nanmedian(a)) if len(a) and np.isfinite(a).any() else nan
    adv = mean_interval(a_rand - a_layer) if len(a_layer) else mean_interval([])
    return {'angle_layer_deg': a_layer, 'angle_surface_deg': a_surf, 'angle_random_layer_deg': a_rand,
            'r': r[good], 'z': z[good], 'n_cuts': int(good.sum()), 'n_cuts_no_layering': int((~good).sum()),
            'median_layer_deg': med(a_layer), 'median_surface_deg': med(a_surf), 'median_random_deg': med(a_rand),
            'mean_layer_deg': float(a_layer.mean()) if len(a_layer) else nan,
            'mean_random_deg': float(a_rand.mean()) if len(a_rand) else nan,
            'fraction_within_15deg': float((a_layer < 15).mean()) if len(a_layer) else nan,
            'advantage_deg': adv['mean'], 'advantage_ci95': adv['ci95']}


# ---------------------------------------------------------------------------------------------
# ground pressure

def _floor_loads(snap):
    """Contacts between a pile grain (not fixed) and a paving grain (fixed): contact point
    (K,3) [m] and the downward vertical load on the paving grain, -F_z of the force exerted on it
    by the pile grain [N] (positive when pressing)."""
    cont = _grain_contacts(snap)
    f1, f2 = snap['fixed'][cont['i1']], snap['fixed'][cont['i2']]
    mixed = f1 != f2
    # c_force acts on body 2: on the paving grain when body 2 is the fixed one
    on_paving = np.where(f2[mixed][:, None], cont['force'][mixed], -cont['force'][mixed])
    return cont['point'][mixed], -on_paving[:, 2]


def _ring_sums(r, phi, load, ring_width, n_rings, n_sectors):
    """Sum of loads per (ring, sector): array (n_rings, n_sectors) [N], and contacts per ring."""
    k = (r / ring_width).astype(int)
    s = np.minimum((phi / (2 * math.pi / n_sectors)).astype(int), n_sectors - 1)
    inside = k < n_rings
    sums = np.zeros((n_rings, n_sectors))
    np.add.at(sums, (k[inside], s[inside]), load[inside])
    return sums, np.bincount(k[inside], minlength=n_rings)


def ground_pressure(snap, ring_width, r_max=None, n_sectors=8, rho_bulk=None, H=None,
                    profile=None):
    """Pressure of the pile on the floor per concentric ring (Moreau's Fig. 5).

    Ring k covers k·w ≤ r < (k+1)·w about Oz (w = ``ring_width`` [m]); ring 0 is a disc. Its
    pressure is the sum, over contacts between a non-fixed grain and a fixed paving grain whose
    contact point lies (in plan view) in the ring, of the vertical force pressing on the paving
    grain, divided by the ring area pi·w²·((k+1)² - k²). The error of a ring is the standard
    error over ``n_sectors`` equal azimuthal sectors: std(sector pressures, ddof=1)/sqrt(n_sectors),
    each sector pressure being its load over its area (ring area/n_sectors).

    :param r_max: outer radius covered [m]; default: just beyond the farthest floor contact.
    :param rho_bulk, H: bulk density [kg/m³] and pile height [m] of the hydrostatic reference
        rho_bulk·g·H; measured by :func:`profile_and_slope` (or taken from ``profile``) when None.
    :returns: dict ``r_in``, ``r_out``, ``r_mid`` [m], ``area`` [m²], ``pressure_Pa``,
        ``err_Pa``, ``sector_pressure_Pa`` (n_rings, n_sectors), ``n_contacts`` per ring,
        ``hydrostatic_Pa``, ``rho_bulk`` [kg/m³], ``H`` [m], ``rho_grain`` [kg/m³],
        ``p_over_rho_grain_g_H`` and ``p_over_hydrostatic`` (pressure fractions),
        ``total_load_N`` on the floor, ``pile_weight_N`` (weight of all non-fixed grains).
    """
    snap = _normalise(snap)
    if (rho_bulk is None or H is None) and profile is None:
        profile = profile_and_slope(snap)
    rho_bulk = profile['rho_bulk'] if rho_bulk is None else float(rho_bulk)
    H = profile['H'] if H is None else float(H)
    point, load = _floor_loads(snap)
    r = np.hypot(point[:, 0], point[:, 1])
    phi = np.mod(np.arctan2(point[:, 1], point[:, 0]), 2 * math.pi)
    if r_max is None:
        n_rings = int(r.max() // ring_width) + 1 if len(r) else 1
    else:
        n_rings = max(1, int(math.ceil(r_max / ring_width - 1e-12)))
    sums, counts = _ring_sums(r, phi, load, ring_width, n_rings, n_sectors)
    edges = ring_width * np.arange(n_rings + 1, dtype=float)
    area = math.pi * (edges[1:] ** 2 - edges[:-1] ** 2)
    pressure = sums.sum(axis=1) / area
    sector_p = sums / (area[:, None] / n_sectors)
    err = sector_p.std(axis=1, ddof=1) / math.sqrt(n_sectors) if n_sectors > 1 \
        else np.full(n_rings, np.nan)
    g, rho = snap['g'], snap['rho']
    hydro = rho_bulk * g * H
    return {'r_in': edges[:-1], 'r_out': edges[1:], 'r_mid': (edges[:-1] + edges[1:]) / 2,
            'area': area, 'pressure_Pa': pressure, 'err_Pa': err, 'sector_pressure_Pa': sector_p,
            'n_contacts': counts, 'hydrostatic_Pa': hydro, 'rho_bulk': rho_bulk, 'H': H,
            'rho_grain': rho, 'p_over_rho_grain_g_H': pressure / (rho * g * H),
            'p_over_hydrostatic': pressure / hydro if hydro > 0 else np.full(n_rings, np.nan),
            'total_load_N': float(load.sum()),
            'pile_weight_N': float(grain_masses(snap)[~snap['fixed']].sum() * g)}


# ---------------------------------------------------------------------------------------------
# small-sample statistics (numpy only)

_T975 = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
         2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
         2.052, 2.048, 2.045, 2.042)


def t_quantile_975(df):
    """0.975 quantile of Student's t with ``df`` degrees of freedom (table to 30, then the
    normal's 1.960 corrected by 2.4/df, within 0.002 of the exact value)."""
    df = int(df)
    if df < 1:
        return float('nan')
    return _T975[df - 1] if df <= 30 else 1.960 + 2.4 / df


def t_cdf(t, df):
    """Cumulative distribution of Student's t (``df`` > 0) at ``t``, by Simpson's rule on the
    density from 0 to |t| (2000 panels: error below 1e-9 for |t| < 50)."""
    if not math.isfinite(t):
        return 0.0 if t < 0 else 1.0
    x = np.linspace(0.0, min(abs(t), 1e3), 4001)
    logc = math.lgamma((df + 1) / 2) - math.lgamma(df / 2) - 0.5 * math.log(df * math.pi)
    f = np.exp(logc - (df + 1) / 2 * np.log1p(x * x / df))
    h = x[1] - x[0]
    half = h / 3 * (f[0] + f[-1] + 4 * f[1:-1:2].sum() + 2 * f[2:-1:2].sum())
    return 0.5 + half if t >= 0 else 0.5 - half


def mean_interval(values):
    """Mean of the finite ``values``, their standard deviation (ddof 1), the standard error and
    the 95 % Student-t interval. Returns a dict (nan entries with fewer than two values)."""
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=float)
    nan = float('nan')
    if len(v) == 0:
        return {'n': 0, 'mean': nan, 'std': nan, 'sem': nan, 'ci95': (nan, nan)}
    m = float(v.mean())
    if len(v) < 2:
        return {'n': 1, 'mean': m, 'std': nan, 'sem': nan, 'ci95': (nan, nan)}
    sd = float(v.std(ddof=1))
    se = sd / math.sqrt(len(v))
    q = t_quantile_975(len(v) - 1)
    return {'n': int(len(v)), 'mean': m, 'std': sd, 'sem': se, 'ci95': (m - q * se, m + q * se)}


def jackknife_ratio_dip(num, den, w_num=1.0, w_den=1.0):
    """D = 1 - (w_num·sum num)/(w_den·sum den) over groups (sectors or piles), with its
    delete-one jackknife standard error, the 95 % Student-t interval (groups - 1 degrees of
    freedom) and the one-sided confidence that D > 0 from the t statistic D/se.

    :param num, den: per-group totals (the central and the reference loads).
    :returns: dict ``D``, ``se``, ``ci95``, ``confidence_positive``, ``groups``."""
    num, den = np.asarray(num, dtype=float), np.asarray(den, dtype=float)
    k = len(num)
    nan = float('nan')
    if k == 0 or den.sum() <= 0:
        return {'D': nan, 'se': nan, 'ci95': (nan, nan), 'confidence_positive': nan, 'groups': k}
    D = 1 - (w_num * num.sum()) / (w_den * den.sum())
    if k < 2:
        return {'D': float(D), 'se': nan, 'ci95': (nan, nan), 'confidence_positive': nan, 'groups': k}
    den_minus = den.sum() - den
    with np.errstate(divide='ignore', invalid='ignore'):
        loo = 1 - (w_num * (num.sum() - num)) / (w_den * den_minus)
    loo = loo[np.isfinite(loo)]
    if len(loo) < 2:
        return {'D': float(D), 'se': nan, 'ci95': (nan, nan), 'confidence_positive': nan, 'groups': k}
    se = math.sqrt((len(loo) - 1) / len(loo) * ((loo - loo.mean()) ** 2).sum())
    q = t_quantile_975(k - 1)
    conf = t_cdf(D / se, k - 1) if se > 0 else (1.0 if D > 0 else 0.0)
    return {'D': float(D), 'se': se, 'ci95': (D - q * se, D + q * se), 'confidence_positive': conf,
            'groups': k}


DIP_DISC_D = 2.0        # the central disc: r < 2 mean diameters (0.75 cm, the feed's radius)
DIP_RING_D = 4.0        # the reference annulus: 2 d <= r < 4 d


def central_dip(snap, r0_d=DIP_DISC_D, r1_d=DIP_RING_D, n_sectors=8, d=None):
    """The central dip of the floor pressure as a statistic:

        D = 1 - p(r < r0) / p(r0 <= r < r1),

    the mean pressure on the central disc over the mean pressure on the annulus around it, with
    r0 = ``r0_d``·d and r1 = ``r1_d``·d in mean grain diameters d (so piles of every size compare:
    the disc is the feed zone, 0.75 cm with the paper's grains). D > 0 is a dip, D = 0 none. A fixed
    reference annulus, not the largest ring: the largest of several noisy rings is biased high
    and would find a dip in a flat floor.

    The uncertainty is the delete-one-sector jackknife over ``n_sectors`` azimuthal sectors
    (paired: a sector's disc and annulus loads leave together), with a Student-t interval of
    n_sectors - 1 degrees of freedom, and ``confidence_positive`` the one-sided confidence that
    D > 0. Pressures use the floor loads of :func:`ground_pressure` (pile grains on paving grains).

    :returns: dict ``D``, ``se``, ``ci95``, ``confidence_positive``, ``p_disc_Pa``, ``p_ring_Pa``,
        ``n_disc``, ``n_ring`` (contacts), ``r0``, ``r1`` [m], ``sector_disc_N``,
        ``sector_ring_N`` (loads per sector), ``note`` (why D is nan, if it is).
    """
    snap = _normalise(snap)
    d = mean_diameter(snap) if d is None else float(d)
    r0, r1 = r0_d * d, r1_d * d
    point, load = _floor_loads(snap)
    r = np.hypot(point[:, 0], point[:, 1])
    phi = np.mod(np.arctan2(point[:, 1], point[:, 0]), 2 * math.pi)
    s = np.minimum((phi / (2 * math.pi / n_sectors)).astype(int), n_sectors - 1)
    disc, ring = r < r0, (r >= r0) & (r < r1)
    a_disc, a_ring = math.pi * r0 ** 2, math.pi * (r1 ** 2 - r0 ** 2)
    num = np.bincount(s[disc], weights=load[disc], minlength=n_sectors)
    den = np.bincount(s[ring], weights=load[ring], minlength=n_sectors)
    res = jackknife_ratio_dip(num, den, 1.0 / a_disc, 1.0 / a_ring)
    note = ''
    if den.sum() <= 0:
        note = 'no load on the reference annulus'
    elif disc.sum() == 0:
        note = 'no floor contact in the central disc (D = 1 by definition, no interval)'
        res.update(se=float('nan'), ci95=(float('nan'), float('nan')), confidence_positive=float('nan'))
    res.update(p_disc_Pa=float(num.sum() / a_disc), p_ring_Pa=float(den.sum() / a_ring),
               n_disc=int(disc.sum()), n_ring=int(ring.sum()), r0=r0, r1=r1,
               sector_disc_N=num, sector_ring_N=den, note=note)
    return res


# ---------------------------------------------------------------------------------------------
# fabric

def contact_orientation_histogram(snap, n_bins=18, include_floor=False, include_zero=False):
    """Orientation of the contact normals (equivalently of the contact planes, which are normal
    to them), for contacts between two non-fixed grains (plus pile-floor ones if
    ``include_floor``; zero-force contacts only if ``include_zero``).

    Normals are lines (n and -n are the same). ``theta`` = angle of the normal from the vertical
    in [0, 90] deg (= angle of the contact plane on the horizontal). ``psi`` = orientation of the
    normal projected in the meridian plane of the contact point, angle from +e_r towards +e_z
    folded into (-90, 90] deg (unweighted; for a contact on the axis e_r = 0 and psi = ±90).

    :returns: dict ``theta_edges_deg``, ``theta_counts``, ``theta_density`` (counts divided by
        the isotropic expectation N·(cos θa - cos θb): 1 everywhere for isotropy),
        ``psi_edges_deg`` (2·n_bins bins over [-90, 90]), ``psi_counts``, ``n_contacts``,
        ``fabric`` = mean n⊗n (3x3, trace 1), ``fabric_eigenvalues`` (decreasing),
        ``anisotropy`` = sqrt(3/2 · D:D) with D = fabric - I/3 (0 isotropic, 1 all parallel),
        ``fabric_zz``.
    """
    snap = _normalise(snap)
    cont = _grain_contacts(snap)
    f1, f2 = snap['fixed'][cont['i1']], snap['fixed'][cont['i2']]
    use = ~f1 & ~f2
    if include_floor:
        use |= f1 != f2
    if not include_zero:
        use &= np.linalg.norm(cont['force'], axis=1) > 0
    normal = cont['normal'][use]
    normal = normal / np.linalg.norm(normal, axis=1)[:, None] if len(normal) else normal
    theta = np.degrees(np.arccos(np.clip(np.abs(normal[:, 2]), 0, 1)))
    edges = np.linspace(0, 90, n_bins + 1)
    counts, _ = np.histogram(theta, bins=edges)
    expect = len(normal) * (np.cos(np.radians(edges[:-1])) - np.cos(np.radians(edges[1:])))
    n_r = (normal * cont['e_r'][use]).sum(axis=1)
    psi = np.degrees(np.arctan2(normal[:, 2], n_r))
    psi = np.where(psi > 90, psi - 180, np.where(psi <= -90, psi + 180, psi))
    psi_edges = np.linspace(-90, 90, 2 * n_bins + 1)
    psi_counts, _ = np.histogram(psi, bins=psi_edges)
    out = {'theta_edges_deg': edges, 'theta_counts': counts,
           'theta_density': np.where(expect > 0, counts / np.where(expect > 0, expect, 1), np.nan),
           'psi_edges_deg': psi_edges, 'psi_counts': psi_counts, 'n_contacts': int(len(normal))}
    out.update(fabric_tensor(normal))
    return out


def fabric_tensor(normals):
    """Fabric tensor F = mean of n⊗n over unit normals (n, 3), its eigenvalues (decreasing),
    the scalar anisotropy sqrt(3/2 · D:D) with D = F - I/3 (0 isotropic, 1 all parallel) and
    F_zz. Returns a dict (nan entries when there is no normal)."""
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    if len(normals) == 0:
        nan = float('nan')
        return {'fabric': np.full((3, 3), nan), 'fabric_eigenvalues': np.full(3, nan),
                'anisotropy': nan, 'fabric_zz': nan}
    F = normals.T @ normals / len(normals)
    D = F - np.eye(3) / 3
    return {'fabric': F, 'fabric_eigenvalues': np.sort(np.linalg.eigvalsh(F))[::-1],
            'anisotropy': float(math.sqrt(1.5 * (D * D).sum())), 'fabric_zz': float(F[2, 2])}


def force_change(a, b, top=(10, 100, 1000, 5000)):
    """How the contact forces of two solves of the same step differ, and where (the drift of an
    unconverged solve: ``scripts/bench/force_drift.py``).

    Contacts are matched by their body pair; the change of one is the norm of its force
    difference. Returns the contacts matched and unmatched, the relative total change
    Σ|ΔF| / Σ|F_b|, the share of Σ|ΔF| carried by the ``top`` contacts that change most (a
    change spread over the pile gives small shares, a few culprits large ones), the largest
    single share, and quartiles of the contact points' height and distance to the axis for the
    1000 that change most (or all, if fewer) against all matched contacts [m].

    :param a, b: snapshots (dicts with ``c_id1``, ``c_id2``, ``c_force``, ``c_point``).
    """
    def index(s):
        return {(int(i), int(j)): k for k, (i, j) in enumerate(zip(s['c_id1'], s['c_id2']))}
    ka, kb = index(a), index(b)
    common = [k for k in ka if k in kb]
    if not common:
        raise ValueError('force_change: the two solves share no contact')
    ia, ib = np.array([ka[k] for k in common]), np.array([kb[k] for k in common])
    d = np.linalg.norm(np.asarray(a['c_force'])[ia] - np.asarray(b['c_force'])[ib], axis=1)
    total, mag = d.sum(), np.linalg.norm(np.asarray(b['c_force'])[ib], axis=1).sum()
    order = np.argsort(-d, kind='stable')
    shares = np.cumsum(d[order]) / total if total > 0 else np.zeros(len(d))
    pts = np.asarray(a['c_point'])[ia]
    r, z = np.hypot(pts[:, 0], pts[:, 1]), pts[:, 2]
    worst = order[:min(1000, len(order))]
    quart = lambda x: [float(v) for v in np.percentile(x, [25, 50, 75])]  # noqa: E731
    return dict(matched=len(common), only_a=len(ka) - len(common), only_b=len(kb) - len(common),
                rel_total=float(total / mag) if mag > 0 else float('nan'),
                top_share={int(n): float(shares[min(n, len(d)) - 1]) for n in top},
                largest_share=float(shares[0]),
                worst_z_m=quart(z[worst]), worst_r_m=quart(r[worst]), all_z_m=quart(z), all_r_m=quart(r))

"""Analysis of a sand pile built by Contact Dynamics (Moreau, section IV): free surface,
force transmission across revolved bands, ground pressure, fabric, speed classes, fossil layers.

Pure numpy: nothing here needs YADE, so the module can be loaded by Debian's ``/usr/bin/python3``
from its file path (see ``scripts/pile_figures.py``). Everything is SI inside: metres, seconds,
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
           'floor_level', 'mean_diameter', 'slice_mask', 'profile_and_slope', 'band_segment',
           'band_force_density', 'BandDensity', 'reciprocal_cuts', 'reciprocal_pairs',
           'cylindrical_cut_directions', 'ground_pressure', 'contact_orientation_histogram',
           'speed_levels', 'fossil_layer']

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


def _slope_deg(b, se_b):
    """Slope angle [deg] of a descending line of gradient b, and its standard error [deg]."""
    return math.degrees(math.atan(-b)), math.degrees(se_b / (1.0 + b * b))


def _max_finite(*values):
    """Largest finite value among ``values`` (nan if none is finite)."""
    finite = [v for v in values if math.isfinite(v)]
    return max(finite) if finite else float('nan')


def _sector_slopes(r_sb, h_sb, in_window):
    """Slope [deg] fitted separately in each azimuthal sector (sectors with < 3 points in the
    window are skipped)."""
    slopes = []
    for s in range(r_sb.shape[0]):
        use = in_window[s]
        if use.sum() >= 3:
            _, b, se = _linear_fit(r_sb[s, use], h_sb[s, use])
            slopes.append(_slope_deg(b, se)[0])
    return np.array(slopes)


def _cone_volume(r_prof, h_prof, base_radius):
    """Volume [m³] under the axisymmetric profile h(r) ≥ 0 from r = 0 to ``base_radius``
    (trapezoid rule on 2·pi·r·h; the profile is extended flat to r = 0 and closed at
    (base_radius, 0))."""
    use = ~np.isnan(h_prof) & (r_prof < base_radius)
    r = np.r_[0.0, r_prof[use], base_radius]
    h = np.clip(np.r_[h_prof[use][:1] if use.any() else [0.0], h_prof[use], 0.0], 0, None)
    f = 2 * math.pi * r * h
    return float(((f[1:] + f[:-1]) * np.diff(r)).sum() / 2)


def profile_and_slope(snap, bin_width=None, n_sectors=8, fit_window=(0.15, 0.8), z_floor=None,
                      mask=None):
    """Free surface of the pile, its slope and its size.

    The grains are those of :func:`pile_mask` (or ``mask``). The plane is cut in ``n_sectors``
    azimuthal sectors and radial bins of width ``bin_width`` [m] (default: one mean diameter);
    in every (sector, bin) cell the highest grain gives a surface point (r of its centre, z of
    its top = z + radius). The profile h(r) is, per bin, the median over sectors of these points.
    The apex height H is the highest grain top above the floor. The flank is fitted by least
    squares on every sector point whose height above the floor lies within
    ``fit_window`` = (lo, hi) fractions of H (so the rounded apex and the foot are left out).

    :param z_floor: floor height [m]; default :func:`floor_level`.
    :returns: dict with, lengths in m and angles in degrees:
        ``r``, ``h`` profile (bin-wise, h above the floor, nan where empty), ``bin_width``,
        ``r_sector``, ``h_sector`` (n_sectors, n_bins) sector points (h above the floor),
        ``z_floor``, ``H`` apex height above floor, ``H_cone`` height at r = 0 of the fitted line,
        ``base_radius`` where the fitted line meets the floor,
        ``slope_deg`` pooled fit, ``slope_fit_err_deg`` its standard error,
        ``slope_sector_deg`` per-sector slopes, ``slope_sector_std_deg`` their spread,
        ``slope_sector_err_deg`` = spread/sqrt(number of sectors),
        ``slope_err_deg`` = max(fit error, sector error), ``n_fit_points``,
        ``fit_line`` = (a, b) of z - z_floor = a + b·r, ``volume`` [m³] under the profile,
        ``pile_mass`` [kg] of the pile grains inside the base radius, ``rho_bulk`` [kg/m³] =
        pile_mass/volume (an estimate: the profile follows grain tops), ``n_grains``.
    """
    snap = _normalise(snap)
    if mask is None:
        mask = pile_mask(snap)
    if not mask.any():
        raise ValueError('profile_and_slope: no pile grain')
    z_floor = floor_level(snap) if z_floor is None else float(z_floor)
    w = float(bin_width) if bin_width is not None else mean_diameter(snap)
    pos, rad = snap['pos'][mask], snap['radius'][mask]
    r = np.hypot(pos[:, 0], pos[:, 1])
    phi = np.mod(np.arctan2(pos[:, 1], pos[:, 0]), 2 * math.pi)
    top = pos[:, 2] + rad - z_floor
    n_bins = int(r.max() // w) + 1
    r_sb, h_sb = _sector_profiles(r, phi, top, w, n_bins, n_sectors)
    H = float(top.max())
    lo, hi = fit_window
    with np.errstate(invalid='ignore'):
        in_window = (h_sb >= lo * H) & (h_sb <= hi * H)
    a, b, se_b = _linear_fit(r_sb[in_window], h_sb[in_window])
    slope, slope_err = _slope_deg(b, se_b) if not math.isnan(b) else (float('nan'),) * 2
    sectors = _sector_slopes(r_sb, h_sb, in_window)
    sec_std = float(sectors.std(ddof=1)) if len(sectors) > 1 else float('nan')
    sec_err = sec_std / math.sqrt(len(sectors)) if len(sectors) > 1 else float('nan')
    base = a / -b if b < 0 else float('nan')
    r_prof, h_prof = _column_median(r_sb), _column_median(h_sb)
    result = {'r': r_prof, 'h': h_prof, 'bin_width': w, 'r_sector': r_sb, 'h_sector': h_sb,
              'z_floor': z_floor, 'H': H, 'H_cone': a, 'base_radius': base,
              'slope_deg': slope, 'slope_fit_err_deg': slope_err, 'slope_sector_deg': sectors,
              'slope_sector_std_deg': sec_std, 'slope_sector_err_deg': sec_err,
              'slope_err_deg': _max_finite(slope_err, sec_err),
              'n_fit_points': int(in_window.sum()), 'fit_line': (a, b), 'n_grains': int(mask.sum())}
    result.update(_bulk_density(snap, mask, r_prof, h_prof, base))
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
    out = {k: [] for k in ('nT2', 'n2T', 'rel', 'count', 'count2', 'centre')}
    for seg, seg2 in pairs:
        b1 = _band_from_contacts(cont, *seg)
        b2 = _band_from_contacts(cont, *seg2)
        a, b = float(b1.n @ b2.T), float(b2.n @ b1.T)
        scale = math.sqrt(np.linalg.norm(b1.T) * np.linalg.norm(b2.T))
        out['nT2'].append(a)
        out['n2T'].append(b)
        out['rel'].append(abs(a - b) / scale if scale > 0 else float('nan'))
        out['count'].append(b1.count)
        out['count2'].append(b2.count)
        out['centre'].append((b1.p0 + b1.p1 + b2.p0 + b2.p1) / 4)
    out = {k: np.array(v, dtype=float) for k, v in out.items()}
    out['centre'] = out['centre'].reshape(-1, 2)
    out.update(_reciprocity_stats(out['nT2'], out['n2T'], out['rel']))
    return out


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

"""Pile snapshots: reading them, and the grain sets every analysis starts from (the pile,
the floor, slices, fossil layers, speed classes), with the meridian coordinates and the
grain-to-grain contacts.

Pure numpy, like all of :mod:`yadecd.analysis`: SI units inside (metres, seconds, kilograms,
newtons, pascals, radians; angles returned in degrees say so in their name).

Snapshot format (one ``.npz`` per epoch, written by :func:`yadecd.pile.snapshot.snapshot`)::

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
"""

import json
import math
import os
import re
import numpy as np


REQUIRED_KEYS = ('time', 'g', 'rho', 'pos', 'radius', 'vel', 'fixed', 'birth', 'ids',
                 'c_id1', 'c_id2', 'c_point', 'c_normal', 'c_force')


SNAP_NAME = re.compile(r'^snap_([-+0-9.eE]+)\.npz$')


def as_snapshot(snap):
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
    snap = as_snapshot(raw)
    snap['path'] = str(path)
    return snap


def list_snapshots(run_dir):
    """Snapshots of a run directory, sorted by time.

    :param run_dir: directory holding ``snap_<time>.npz`` files (time in seconds in the name).
    :returns: list of ``(time [s], path)``.
    """
    found = []
    for name in os.listdir(run_dir):
        m = SNAP_NAME.match(name)
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


def grain_masses(snap):
    """Mass of every grain [kg]: rho·(4/3)·pi·radius³."""
    snap = as_snapshot(snap)
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
    snap = as_snapshot(snap)
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
    snap = as_snapshot(snap)
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
    snap = as_snapshot(snap)
    free = ~snap['fixed']
    speed = np.linalg.norm(snap['vel'], axis=1)
    rolling = wall_only_grains(snap)
    speed[rolling] = np.abs(snap['vel'][rolling, 2])
    return float(speed[free].max()) if free.any() else 0.0


def floor_level(snap):
    """Height of the floor [m]: median height of the tops (z + radius) of the fixed paving grains,
    or 0 when there is none."""
    snap = as_snapshot(snap)
    fixed = snap['fixed']
    if not fixed.any():
        return 0.0
    return float(np.median(snap['pos'][fixed, 2] + snap['radius'][fixed]))


def mean_diameter(snap):
    """Mean diameter of the non-fixed grains [m] (of all grains if all are fixed)."""
    snap = as_snapshot(snap)
    free = ~snap['fixed']
    radii = snap['radius'][free] if free.any() else snap['radius']
    return float(2.0 * radii.mean()) if len(radii) else float('nan')


def slice_mask(snap, half_thickness=0.01):
    """Grains whose centre lies in the slab |y| < half_thickness [m] (the slab contains Oz).
    Returns a bool array (N,)."""
    snap = as_snapshot(snap)
    return np.abs(snap['pos'][:, 1]) < half_thickness


def fossil_layer(snap, t1, t2):
    """Fossil layer: non-fixed grains born in [t1, t2] [s] (bounds included). Returns a bool
    array (N,)."""
    snap = as_snapshot(snap)
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
    snap = as_snapshot(snap)
    speed = np.linalg.norm(snap['vel'], axis=1)
    free = ~snap['fixed']
    if vmax is None:
        vmax = float(speed[free].max()) if free.any() else 0.0
    thresholds = vmax * factor ** np.arange(1, n_thresholds + 1, dtype=float)
    level = (speed[:, None] <= thresholds[None, :]).sum(axis=1)
    return {'vmax': float(vmax), 'thresholds': thresholds, 'speed': speed, 'level': level,
            'grey': level / float(n_thresholds),
            'counts': np.bincount(level, minlength=n_thresholds + 1)}


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


def grain_contacts(snap):
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

"""Constructed piles and floor loads with known answers, to test the pile estimators.

Pure numpy, snapshots in the format of :mod:`yadecd.analysis.snapshots` (SI units). Used by the tests
(``tests/analysis/test_pile_estimators.py``) and by ``scripts/estimator_check.py``, which prints how the
estimators read these cases (docs/pile.md).

:func:`constructed_pile` builds what a deposited pile looks like to the free-surface estimator:
grains of the protocol's sizes filling a cone of known slope (centres random, overlaps allowed:
only geometry matters here), a surface layer of grains whose tops lie on the cone up to a
roughness, a paving of fixed grains below, and, on demand, the features that bias a naive fit:
a rounded cap, a sparse axis, a foot of single grains beyond the toe and stray grains.

:func:`constructed_floor` builds a floor load with a known central dip: contacts between pile
grains and paving grains at random places, loads drawn around a chosen pressure profile with
exponentially distributed magnitudes (the force distribution of granular packings).
"""
import math

import numpy as np

D_MIN, D_MAX = 0.0025, 0.0050     # the paper's diameters [m]
D_MEAN = 0.5 * (D_MIN + D_MAX)


def _empty_snapshot(time=1.0, g=9.81, rho=1000.0):
    return {'time': time, 'g': g, 'rho': rho}


def _finish(snap, pos, radius, fixed, c_id1=(), c_id2=(), c_point=(), c_force=(), birth=None):
    """Fill a snapshot dict with grains and contacts (ids = row numbers)."""
    n = len(radius)
    snap.update(pos=np.asarray(pos, float).reshape(-1, 3), radius=np.asarray(radius, float),
                vel=np.zeros((n, 3)), fixed=np.asarray(fixed, bool),
                birth=np.where(np.asarray(fixed, bool), -1.0, 0.0) if birth is None else np.asarray(birth, float),
                ids=np.arange(n, dtype=np.int64),
                c_id1=np.asarray(c_id1, np.int64), c_id2=np.asarray(c_id2, np.int64),
                c_point=np.asarray(c_point, float).reshape(-1, 3),
                c_normal=np.tile([0.0, 0.0, 1.0], (len(c_id1), 1)),
                c_force=np.asarray(c_force, float).reshape(-1, 3))
    return snap


def paving_grains(rng, radius, d_min=D_MIN, d_max=D_MAX):
    """A floor of fixed grains on z = 0 over the disc ``radius`` [m]: one grain per square cell
    of side d_max, jittered inside its cell so that no two overlap. Returns (xyz, r)."""
    k = int(math.ceil(radius / d_max))
    ix, iy = np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1))
    centre = np.column_stack([ix.ravel(), iy.ravel()]) * d_max
    centre = centre[np.hypot(centre[:, 0], centre[:, 1]) <= radius]
    r = 0.5 * rng.uniform(d_min, d_max, len(centre))
    jitter = (rng.random((len(centre), 2)) - 0.5) * (d_max - 2 * r)[:, None]
    xy = centre + jitter
    return np.column_stack([xy, r]), r


def cone_height(r, slope_deg, H, cap_radius=0.0):
    """Height of the constructed surface above the floor at distance r [m]: the cone
    H - r·tan(slope), or, within ``cap_radius`` of the axis, the parabola tangent to it there
    (a rounded cap). Never below 0."""
    t = math.tan(math.radians(slope_deg))
    r = np.asarray(r, dtype=float)
    h = H - r * t
    if cap_radius > 0:
        inner = r < cap_radius
        h = np.where(inner, H - cap_radius * t + t * (cap_radius ** 2 - r ** 2) / (2 * cap_radius), h)
    return np.maximum(h, 0.0)


def constructed_pile(slope_deg=26.0, H=0.03, cap_radius=0.0, sparse_axis=False, foot=False, strays=0,
                     roughness=0.3, packing=0.55, seed=0, d_min=D_MIN, d_max=D_MAX):
    """A pile whose free surface is known: see the module docstring.

    :param slope_deg: angle of the cone's straight flank [deg] (the answer).
    :param H: height of the cone (of its straight line at r = 0) above the floor [m].
    :param cap_radius: radius of the rounded cap [m] (0: a sharp apex).
    :param sparse_axis: leave no surface grain within one mean diameter of the axis, so the
        highest grains there are buried ones (as when a cell near r = 0 is smaller than a grain).
    :param foot: a sparse layer of single grains on the floor from the toe to 3 cm beyond it.
    :param strays: that many stray grains 1–4 cm beyond the toe, every other one with a second
        grain on top of it.
    :param roughness: surface grains sit up to roughness·d_mean below the cone.
    :param packing: volume fraction of the buried grains.
    :returns: (snapshot dict, info dict with ``slope_deg``, ``H``, ``R`` = H/tan(slope),
        ``z_floor``)."""
    rng = np.random.default_rng(seed)
    t = math.tan(math.radians(slope_deg))
    R = H / t
    d = 0.5 * (d_min + d_max)
    pave, pr = paving_grains(rng, R + 0.05, d_min, d_max)
    z_floor = float(np.median(2 * pr))
    pos = [np.column_stack([pave[:, :2], pr])]
    rad = [pr]
    fixed = [np.ones(len(pr), bool)]

    def radii(n):
        return 0.5 * rng.uniform(d_min, d_max, n)

    def disc(n, rmax, rmin=0.0):
        rr = np.sqrt(rng.uniform(rmin ** 2, rmax ** 2, n))
        a = rng.uniform(0, 2 * math.pi, n)
        return rr * np.cos(a), rr * np.sin(a), rr

    # surface layer: about 1.3 grains per d² of plan area, tops on the cone up to the roughness
    n_surf = int(1.3 * math.pi * R ** 2 / d ** 2)
    x, y, rr = disc(n_surf, R)
    rs = radii(n_surf)
    h = cone_height(rr, slope_deg, H, cap_radius)
    top = z_floor + h - rng.uniform(0, roughness * d, n_surf)
    z = np.maximum(top - rs, z_floor + rs)          # where the cone is thinner than a grain: on the floor
    keep = ~(sparse_axis & (rr < d)) if sparse_axis else np.ones(n_surf, bool)
    pos.append(np.column_stack([x, y, z])[keep])
    rad.append(rs[keep])
    fixed.append(np.zeros(keep.sum(), bool))
    # buried grains filling the cone, tops at least half a diameter under the surface
    v_grain = math.pi / 6 * (d_max ** 4 - d_min ** 4) / (4 * (d_max - d_min))
    n_fill = int(packing * math.pi * R ** 2 * H / 3 / v_grain)
    x, y, rr = disc(4 * n_fill, R)
    rb = radii(4 * n_fill)
    hb = cone_height(rr, slope_deg, H, cap_radius)
    zb = z_floor + rb + rng.random(4 * n_fill) * hb
    ok = (zb + rb <= z_floor + hb - 0.5 * d) & (zb - rb >= z_floor - 0.2 * d)
    sel = np.flatnonzero(ok)[:n_fill]
    pos.append(np.column_stack([x, y, zb])[sel])
    rad.append(rb[sel])
    fixed.append(np.zeros(len(sel), bool))
    if foot:
        n_foot = int(0.35 * math.pi * ((R + 0.03) ** 2 - R ** 2) / d ** 2)
        x, y, _ = disc(n_foot, R + 0.03, R)
        rf = radii(n_foot)
        pos.append(np.column_stack([x, y, z_floor + rf - 0.1 * d]))
        rad.append(rf)
        fixed.append(np.zeros(n_foot, bool))
    if strays:
        x, y, _ = disc(strays, R + 0.04, R + 0.01)
        rsg = radii(strays)
        zs = z_floor + rsg - 0.1 * d
        pos.append(np.column_stack([x, y, zs]))
        rad.append(rsg)
        top_r = radii(strays)
        stacked = np.arange(strays) % 2 == 0
        pos.append(np.column_stack([x, y, zs + rsg + top_r])[stacked])
        rad.append(top_r[stacked])
        fixed.append(np.zeros(strays, bool))
        fixed.append(np.zeros(stacked.sum(), bool))
    snap = _finish(_empty_snapshot(), np.concatenate(pos), np.concatenate(rad), np.concatenate(fixed))
    return snap, {'slope_deg': slope_deg, 'H': H, 'R': R, 'z_floor': z_floor}


def dip_profile(r, p_max, R, dip, r0):
    """The constructed floor pressure [Pa]: p_max·(1 - r/R) outside the central disc r < r0,
    (1 - dip)·p_max·(1 - r/R) inside it; 0 beyond R."""
    r = np.asarray(r, dtype=float)
    base = p_max * np.clip(1 - r / R, 0, None)
    return np.where(r < r0, (1 - dip) * base, base)


def dip_value(dip, R, r0, r1):
    """Exact D = 1 - mean pressure over the disc r < r0 / mean over the annulus r0 ≤ r < r1 of
    :func:`dip_profile` (r1 ≤ R): the means of 1 - r/R over a disc and an annulus are
    1 - 2 r0/(3R) and 1 - 2 (r1³ - r0³)/(3R (r1² - r0²))."""
    disc = (1 - dip) * (1 - 2 * r0 / (3 * R))
    ring = 1 - 2 * (r1 ** 3 - r0 ** 3) / (3 * R * (r1 ** 2 - r0 ** 2))
    return 1 - disc / ring


def constructed_floor(dip=0.3, r0=0.0075, R=0.06, p_max=1500.0, density=None, seed=0, noise='exp',
                      outliers=0, empty_disc=False, flat=False):
    """Floor contacts with a known central dip (see :func:`dip_profile`; the answer is
    :func:`dip_value`).

    Contacts fall uniformly at random in the disc R (``density`` per m², default one per
    paving grain area d_mean²·0.9). Each carries the load p(r)·(area per contact)·X with X ~
    Exp(1) (``noise='exp'``) or X = 1 (``noise=None``). ``outliers`` contacts anywhere get
    20 times their load (the rare very strong chain). ``empty_disc`` removes every contact
    within r0 (a sparse centre). ``flat`` makes the pressure uniform outside the disc
    (:func:`dip_profile` with an infinite R; the answer is then ``dip`` itself). Every contact joins a non-fixed grain (body 1) above a fixed
    paving grain (body 2); the force on body 2 is (0, 0, -load).

    :returns: (snapshot, info dict with ``D`` (exact), ``dip``, ``r0``, ``R``)."""
    rng = np.random.default_rng(seed)
    density = density or 1.0 / (0.9 * D_MEAN ** 2)
    n = rng.poisson(density * math.pi * R ** 2)
    rr = R * np.sqrt(rng.random(n))
    a = rng.uniform(0, 2 * math.pi, n)
    if empty_disc:
        keep = rr >= r0
        rr, a = rr[keep], a[keep]
        n = len(rr)
    load = dip_profile(rr, p_max, math.inf if flat else R, dip, r0) / density
    if noise == 'exp':
        load = load * rng.exponential(1.0, n)
    if outliers:
        load[rng.choice(n, outliers, replace=False)] *= 20.0
    xy = np.column_stack([rr * np.cos(a), rr * np.sin(a)])
    r_g = 0.5 * D_MEAN
    pave = np.column_stack([xy, np.full(n, r_g)])
    grain = np.column_stack([xy, np.full(n, 3 * r_g)])
    pos = np.concatenate([grain, pave])
    radius = np.full(2 * n, r_g)
    fixed = np.r_[np.zeros(n, bool), np.ones(n, bool)]
    point = np.column_stack([xy, np.full(n, 2 * r_g)])
    force = np.column_stack([np.zeros(n), np.zeros(n), -load])
    snap = _finish(_empty_snapshot(), pos, radius, fixed, c_id1=np.arange(n), c_id2=np.arange(n, 2 * n),
                   c_point=point, c_force=force)
    return snap, {'dip': dip, 'r0': r0, 'R': R, 'profile_R': math.inf if flat else R}

"""The pressure a pile exerts on its floor (Moreau, Figure 5): ring and sector averages of the
paving's loads, and the central dip with its interval.
"""

import math
import numpy as np

from .snapshots import as_snapshot, body_index, grain_contacts, grain_masses, mean_diameter
from .stats import jackknife_ratio_dip
from .surface import profile_and_slope


def paving_loads(snap):
    """Contacts between a pile grain (not fixed) and a paving grain (fixed): contact point
    (K,3) [m] and the downward vertical load on the paving grain, -F_z of the force exerted on it
    by the pile grain [N] (positive when pressing)."""
    cont = grain_contacts(snap)
    f1, f2 = snap['fixed'][cont['i1']], snap['fixed'][cont['i2']]
    mixed = f1 != f2
    # c_force acts on body 2: on the paving grain when body 2 is the fixed one
    on_paving = np.where(f2[mixed][:, None], cont['force'][mixed], -cont['force'][mixed])
    return cont['point'][mixed], -on_paving[:, 2]


def plane_loads(snap):
    """Contacts between a pile grain (not fixed) and a body that is not a grain of the snapshot
    (the floor wall under the paving): contact point (K,3) [m] and the downward vertical load on
    that body [N] (positive when pressing)."""
    i1, i2 = body_index(snap, snap['c_id1']), body_index(snap, snap['c_id2'])
    points, loads = [], []
    for grain, other, sign in ((i1, i2, 1.0), (i2, i1, -1.0)):
        pick = (grain >= 0) & (other < 0)
        pick[pick] = ~snap['fixed'][grain[pick]]
        # c_force acts on body 2: on the wall when the wall is body 2 (sign +1 here: grain is body 1)
        points.append(snap['c_point'][pick])
        loads.append(-sign * snap['c_force'][pick, 2])
    return np.concatenate(points), np.concatenate(loads)


def _floor_loads(snap, plane=False):
    """Contact points (K,3) [m] and downward loads [N] of the pile on its floor: on the paving
    grains (the paper's floor), and with ``plane`` also on the plane between them
    (:func:`wall_load`)."""
    point, load = paving_loads(snap)
    if plane:
        wp, wl = plane_loads(snap)
        point, load = np.concatenate([point, wp]), np.concatenate([load, wl])
    return point, load


def wall_load(snap):
    """Downward load [N] of the pile grains on bodies that are not grains of the snapshot (the
    floor wall under the paving): the sum over contacts between a non-fixed grain and such a body
    of the vertical force pressing on that body. :func:`ground_pressure` and :func:`central_dip`
    count the paving grains only unless given ``plane=True``; this is what reaches the plane
    between them (more for clumps, whose members are smaller than the paving grains)."""
    return float(plane_loads(as_snapshot(snap))[1].sum())


def _ring_sums(r, phi, load, ring_width, n_rings, n_sectors):
    """Sum of loads per (ring, sector): array (n_rings, n_sectors) [N], and contacts per ring."""
    k = (r / ring_width).astype(int)
    s = np.minimum((phi / (2 * math.pi / n_sectors)).astype(int), n_sectors - 1)
    inside = k < n_rings
    sums = np.zeros((n_rings, n_sectors))
    np.add.at(sums, (k[inside], s[inside]), load[inside])
    return sums, np.bincount(k[inside], minlength=n_rings)


def ground_pressure(snap, ring_width, r_max=None, n_sectors=8, rho_bulk=None, H=None,
                    profile=None, plane=False):
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
    :param plane: also count the loads on the plane between the paving grains (the floor wall;
        :func:`wall_load`), at their contact points.
    :returns: dict ``r_in``, ``r_out``, ``r_mid`` [m], ``area`` [m²], ``pressure_Pa``,
        ``err_Pa``, ``sector_pressure_Pa`` (n_rings, n_sectors), ``n_contacts`` per ring,
        ``hydrostatic_Pa``, ``rho_bulk`` [kg/m³], ``H`` [m], ``rho_grain`` [kg/m³],
        ``p_over_rho_grain_g_H`` and ``p_over_hydrostatic`` (pressure fractions),
        ``total_load_N`` on the floor, ``pile_weight_N`` (weight of all non-fixed grains).
    """
    snap = as_snapshot(snap)
    if (rho_bulk is None or H is None) and profile is None:
        profile = profile_and_slope(snap)
    rho_bulk = profile['rho_bulk'] if rho_bulk is None else float(rho_bulk)
    H = profile['H'] if H is None else float(H)
    point, load = _floor_loads(snap, plane)
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


DIP_DISC_D = 2.0        # the central disc: r < 2 mean diameters (0.75 cm, the feed's radius)


DIP_RING_D = 4.0        # the reference annulus: 2 d <= r < 4 d


def central_dip(snap, r0_d=DIP_DISC_D, r1_d=DIP_RING_D, n_sectors=8, d=None, plane=False):
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
    D > 0. Pressures use the floor loads of :func:`ground_pressure` (pile grains on paving grains,
    and with ``plane`` also on the plane between them).

    :returns: dict ``D``, ``se``, ``ci95``, ``confidence_positive``, ``p_disc_Pa``, ``p_ring_Pa``,
        ``n_disc``, ``n_ring`` (contacts), ``r0``, ``r1`` [m], ``sector_disc_N``,
        ``sector_ring_N`` (loads per sector), ``note`` (why D is nan, if it is).
    """
    snap = as_snapshot(snap)
    d = mean_diameter(snap) if d is None else float(d)
    r0, r1 = r0_d * d, r1_d * d
    point, load = _floor_loads(snap, plane)
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

"""Force transmission across revolved bands (Moreau, Figures 3 and 4): force densities on cuts,
reciprocal pairs of cuts, the directions of cylindrical cuts, and the fossil-layer law.

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

import math
from typing import NamedTuple
import numpy as np

from .snapshots import as_snapshot, grain_contacts, meridian, pile_mask
from .stats import mean_interval


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
    """:func:`band_force_density` on a precomputed :func:`grain_contacts` table."""
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
    return _band_from_contacts(grain_contacts(as_snapshot(snap)), p0, p1)


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
    cont = grain_contacts(as_snapshot(snap))
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


def line_angles(Tr, Tz):
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
    cont = grain_contacts(as_snapshot(snap))
    radii = np.asarray(radii, dtype=float)
    heights = np.asarray(heights, dtype=float)
    shape = (len(radii), len(heights))
    Tr, Tz, count = np.zeros(shape), np.zeros(shape), np.zeros(shape, dtype=int)
    for i, r in enumerate(radii):
        for j, z in enumerate(heights):
            band = _band_from_contacts(cont, (r, z + band_height / 2), (r, z - band_height / 2))
            Tr[i, j], Tz[i, j] = band.T
            count[i, j] = band.count
    from_vertical, incl = line_angles(Tr, Tz)
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
    snap = as_snapshot(snap)
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
            incl[i] = line_angles(np.array([gz]), np.array([-gr]))[1][0]
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

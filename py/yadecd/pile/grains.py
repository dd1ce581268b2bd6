"""Grain shapes of a pile: spheres, and rigid clumps of equal overlapping spheres (YADE clumps),
each sized to the volume of the paper's sphere it replaces.

Pure numpy (imports without YADE): the shapes' geometry, their exact volume and inertia
(:func:`union_moments`), a uniformly random orientation (:func:`random_rotation`) and the lowest
resting height of a set of spheres dropped on a vertical (:func:`resting_height`, the paper's
creation rule for a grain of any shape).

A shape is a template of ``k`` equal spheres of radius 1 whose centres (``offsets``) are placed
about the template's centre of mass, in its principal frame. A grain of the pile draws the
paper's diameter ``d`` and becomes the template scaled so that its volume is that of the sphere
of diameter ``d`` (``d`` is its volume-equivalent diameter): the member radius is
``a = (d/2) / req`` with ``req`` the template's equivalent radius. Its mass and inertia are those of
the union of the members (overlaps counted once): ``rho·volume·a³`` and
``rho·inertia·a⁵``, from the constants of :data:`SHAPES`, which the tests check against
:func:`union_moments`.

===========  ===============================================================================
``sphere``   the paper's grain: one sphere
``dimer``    two spheres whose centres are one radius apart: aspect ratio (length over width)
             1.5, an axisymmetric elongated grain
``tetra``    four spheres at the vertices of a regular tetrahedron of edge 1.5 radii: a compact,
             angular grain with four bumps (aspect ratio near 1, isotropic inertia)
===========  ===============================================================================
"""

import math

import numpy as np


def _tetra_offsets(edge):
    s = edge / (2 * math.sqrt(2))
    return s * np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float)


#: Each shape: member centres for members of radius 1 (about the centre of mass, principal
#: frame), and the union's volume and principal moments of inertia per unit density, for members
#: of radius 1 (7 significant digits, from :func:`union_moments` with n = 4096, whose error there is
#: below 1e-6 relative; the tests check them). ``axis``: the index of the symmetry axis in ``inertia`` (-1: isotropic).
SHAPES = {
    'sphere': dict(offsets=np.zeros((1, 3)), volume=4 * math.pi / 3, inertia=(8 * math.pi / 15,) * 3, axis=-1),
    'dimer': dict(offsets=np.array([[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0]]), volume=9 * math.pi / 4,
                  inertia=(3.004148, 5.213081, 5.213081), axis=0),
    'tetra': dict(offsets=_tetra_offsets(1.5), volume=14.77313, inertia=(15.50861,) * 3, axis=-1),
}


def shape(name):
    """The template of the shape ``name`` (:data:`SHAPES`); ValueError names the known ones."""
    if name not in SHAPES:
        raise ValueError('grain shape %r is not known: use one of %s' % (name, ', '.join(sorted(SHAPES))))
    return SHAPES[name]


def equivalent_radius(name):
    """Radius of the sphere of the same volume as the template (members of radius 1)."""
    return (3 * shape(name)['volume'] / (4 * math.pi)) ** (1 / 3)


def member_radius(name, d):
    """Member radius [m] of a grain of shape ``name`` whose volume is that of a sphere of diameter ``d``."""
    return 0.5 * d / equivalent_radius(name)


def mass_properties(name, a, rho):
    """(mass [kg], principal inertia (3,) [kg·m²]) of a grain of shape ``name`` with members of
    radius ``a`` [m] and density ``rho``: the union's, overlaps counted once."""
    s = shape(name)
    return rho * s['volume'] * a ** 3, rho * np.asarray(s['inertia'], float) * a ** 5


def circumradius(name):
    """Radius of the smallest sphere about the template's centre of mass that holds it (members of
    radius 1)."""
    return float(np.linalg.norm(shape(name)['offsets'], axis=1).max() + 1)


def aspect_ratio(name, n_dirs=2000):
    """Length over width of the template: its largest extent along a direction over the smallest
    (extents over ``n_dirs`` directions of a Fibonacci sphere; 1 for a sphere)."""
    off = shape(name)['offsets']
    k = np.arange(n_dirs) + 0.5
    polar, azim = np.arccos(1 - 2 * k / n_dirs), math.pi * (1 + 5 ** 0.5) * k
    dirs = np.column_stack([np.sin(polar) * np.cos(azim), np.sin(polar) * np.sin(azim), np.cos(polar)])
    proj = off @ dirs.T
    extent = proj.max(axis=0) - proj.min(axis=0) + 2
    return float(extent.max() / extent.min())


def union_moments(centres, radii, n=1024):
    """Volume, centre of mass and inertia tensor (about the centre of mass, unit density) of the
    union of spheres, overlaps counted once.

    Integrates along vertical lines: on a line through (x, y) each sphere covers an interval of z
    known in closed form; the union of the intervals and the integrals of 1, z and z² over it are
    exact, and the lines sit at the midpoints of an n × n grid over the union's horizontal extent
    (about 1e-6 relative at n = 1024 on the templates, less at larger n). Returns
    ``(volume, centre (3,), tensor (3, 3))``."""
    c, r = np.asarray(centres, float).reshape(-1, 3), np.asarray(radii, float).reshape(-1)
    lo, hi = (c[:, :2] - r[:, None]).min(axis=0), (c[:, :2] + r[:, None]).max(axis=0)
    h = (hi - lo) / n
    xs = lo[0] + h[0] * (np.arange(n) + 0.5)
    ys = lo[1] + h[1] * (np.arange(n) + 0.5)
    X, Y = np.meshgrid(xs, ys, indexing='ij')
    X, Y = X.ravel(), Y.ravel()
    half2 = r[None, :] ** 2 - (X[:, None] - c[None, :, 0]) ** 2 - (Y[:, None] - c[None, :, 1]) ** 2
    inside = half2 > 0
    half = np.sqrt(np.where(inside, half2, 0.0))
    z0 = np.where(inside, c[None, :, 2] - half, np.inf)
    z1 = np.where(inside, c[None, :, 2] + half, -np.inf)
    order = np.argsort(z0, axis=1)
    z0, z1 = np.take_along_axis(z0, order, axis=1), np.take_along_axis(z1, order, axis=1)
    m0 = m1 = m2 = np.zeros(len(X))
    top = np.full(len(X), -np.inf)               # the top of the union of the intervals so far
    for k in range(len(r)):                      # intervals by their lower end: each adds its uncovered part
        a, b = np.maximum(z0[:, k], top), z1[:, k]
        add = b > a
        a, b = np.where(add, a, 0.0), np.where(add, b, 0.0)
        m0, m1, m2 = m0 + (b - a), m1 + (b ** 2 - a ** 2) / 2, m2 + (b ** 3 - a ** 3) / 3
        top = np.maximum(top, z1[:, k])
    dA = h[0] * h[1]
    vol = m0.sum() * dA
    sx, sy, sz = (X * m0).sum() * dA, (Y * m0).sum() * dA, m1.sum() * dA
    com = np.array([sx, sy, sz]) / vol
    Sxx, Syy, Szz = (X * X * m0).sum() * dA, (Y * Y * m0).sum() * dA, m2.sum() * dA
    Sxy, Sxz, Syz = (X * Y * m0).sum() * dA, (X * m1).sum() * dA, (Y * m1).sum() * dA
    second = np.array([[Sxx, Sxy, Sxz], [Sxy, Syy, Syz], [Sxz, Syz, Szz]]) - vol * np.outer(com, com)
    tensor = np.trace(second) * np.eye(3) - second
    return float(vol), com, tensor


def random_rotation(rng):
    """A rotation matrix uniformly distributed over SO(3), from four normal draws of ``rng``
    (a normalised Gaussian quaternion)."""
    q = rng.standard_normal(4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def resting_height(x, y, offsets, radii, centres, obstacle_radii):
    """Lowest height z of a rigid set of spheres (centres ``(x, y, z) + offsets[i]``, radii
    ``radii[i]``), moved down the vertical through (x, y), at which it rests on a sphere of
    ``centres`` / ``obstacle_radii`` or on the plane z = 0 without overlapping any of them.

    Member i meets sphere j when their horizontal distance d_ij < r_i + r_j; they overlap for
    heights within s_ij = sqrt((r_i + r_j)² − d_ij²) of z_j − o_iz. The candidates are the
    resting heights z_j − o_iz + s_ij and the plane's max_i(r_i − o_iz); the lowest candidate
    outside every open overlap interval is returned, so that a grain in flight above the pile does
    not lift the new grain above itself. One sphere at offset 0 is the paper's rule for spheres."""
    off = np.asarray(offsets, float).reshape(-1, 3)
    rad = np.asarray(radii, float).reshape(-1)
    z_plane = float(np.max(rad - off[:, 2]))
    if len(obstacle_radii) == 0:
        return z_plane
    cen = np.asarray(centres, float).reshape(-1, 3)
    d2 = (cen[None, :, 0] - x - off[:, None, 0]) ** 2 + (cen[None, :, 1] - y - off[:, None, 1]) ** 2
    reach = (rad[:, None] + np.asarray(obstacle_radii, float)[None, :]) ** 2 - d2
    hit = reach > 0
    if not hit.any():
        return z_plane
    i, j = np.nonzero(hit)
    zc, s = cen[j, 2] - off[i, 2], np.sqrt(reach[i, j])
    candidates = np.sort(np.concatenate(([z_plane], zc + s)))
    candidates = candidates[candidates >= z_plane]
    # free: outside every open interval (zc − s, zc + s); a relative margin absorbs round-off
    free = np.all(np.abs(candidates[:, None] - zc[None, :]) >= s[None, :] * (1 - 1e-12), axis=1)
    return float(candidates[np.argmax(free)])  # the highest candidate is always free

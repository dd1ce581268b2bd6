"""Building a pile scene: the paving of the floor, the grains' creation (:class:`Feeder`, at the
lowest height where each rests), the engines of a run, and a large cone state for benchmarks.
"""

import json
import math
import os
import time
import numpy as np
from yade import O, utils, Vector3
from yade.wrapper import Sphere, ContactDynamicsIntegrator

from .. import engines
from ..scenes import material
from . import grains
from .protocol import defaults, engine_options, expected_base_radius, read_run_json
from .write import snapshot


def paving(rng, radius, d_min, d_max, attempts_per_grain=60):
    """Random sequential addition of discs on the plane: (x, y, r) of non-overlapping grains
    whose centres lie within ``radius`` of the axis; ends after ``attempts_per_grain`` failed
    attempts in a row per placed grain on average. Returns an array (k, 3)."""
    cell = d_max
    grid = {}
    placed = []
    failures = 0
    target_fail = attempts_per_grain * 50
    while failures < target_fail:
        rr = radius * math.sqrt(rng.random())
        a = 2 * math.pi * rng.random()
        x, y, r = rr * math.cos(a), rr * math.sin(a), 0.5 * rng.uniform(d_min, d_max)
        i, j = int(math.floor(x / cell)), int(math.floor(y / cell))
        ok = True
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                for (px, py, pr) in grid.get((i + di, j + dj), ()):
                    if (px - x) ** 2 + (py - y) ** 2 < (pr + r) ** 2:
                        ok = False
                        break
                if not ok:
                    break
            if not ok:
                break
        if ok:
            grid.setdefault((i, j), []).append((x, y, r))
            placed.append((x, y, r))
            failures = 0
        else:
            failures += 1
    return np.array(placed)


def build_scene(p, floor=None):
    """Reset O and create the floor (wall + paving) and the engines. Returns the number of
    paving grains. ``floor``: the paving's (x, y, r) rows to place instead of drawing a new one
    (a run rebuilt from its saved state)."""
    O.reset()
    mat = material(p['mu'], p['rho'])
    O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
    if floor is None:
        rng = np.random.default_rng(p['seed'] + 1_000_003)  # the paving has its own stream
        floor_radius = p['floor_radius'] or 1.4 * expected_base_radius(p['n_grains'], p['d_min'], p['d_max'])
        floor = paving(rng, floor_radius, p['d_min'], p['d_max'])
    for x, y, r in floor:
        O.bodies.append(utils.sphere((x, y, r), r, fixed=True, material=mat, color=(0.5, 0.5, 0.5)))
    set_engines(p)
    return len(O.bodies) - 1


def add_grain(x, y, z, r):
    """Append one sphere grain (the run's material, at rest); returns its id. A clump grain:
    :func:`add_clump`."""
    return O.bodies.append(utils.sphere((x, y, z), r, material=O.materials[0]))


def add_clump(centres, a, grain_shape):
    """Append a clump of spheres of radius ``a`` at ``centres`` (the shape ``grain_shape``'s members,
    placed) with the union's mass and inertia (overlaps counted once: :func:`grains.mass_properties`;
    YADE's own sum would count them twice). Returns the clump's id."""
    mat = O.materials[0]
    cid, ids = O.bodies.appendClumped([utils.sphere(tuple(c), a, material=mat) for c in centres])
    set_clump_mass(O.bodies[cid], grain_shape, a)
    return cid


def set_clump_mass(clump, grain_shape, a):
    """Give the clump body the mass and principal inertia of the union of its members (shape
    ``grain_shape``, member radius ``a``). YADE puts the clump's frame on the principal axes of its
    own inertia estimate, which shares the template's symmetry axis: the template's axial moment
    goes to the frame axis along which the members lie."""
    mass, inertia = grains.mass_properties(grain_shape, a, O.materials[0].density)
    axis = grains.shape(grain_shape)['axis']
    if axis >= 0:   # axisymmetric: the transverse moment everywhere, the axial one along the members
        rel = np.array([tuple(pos) for pos, _ in clump.shape.members.values()])
        along = int(np.argmax(np.abs(rel).max(axis=0)))
        axial, transverse = inertia[axis], inertia[(axis + 1) % 3]
        inertia = np.full(3, transverse)
        inertia[along] = axial
    clump.state.mass = float(mass)
    clump.state.inertia = Vector3(*[float(v) for v in inertia])


def set_engines(p):
    """The run's engines and time step: the CD engine list, or (``method='MD'``) YADE's linear
    soft-contact list with ``O.dt = md_safety·PWaveTimeStep()`` (then written back to p['dt'])."""
    method = p.get('method', 'CD')
    if method == 'CD':
        O.engines = engines(gravity=(0, 0, -p['g']), en=p['en'], warnUnconverged=False, **engine_options(p))
        O.dt = p['dt']
    elif method == 'MD':
        from ..compare.md import md_engines
        for m in O.materials:
            m.young = p['young']
        O.engines = md_engines(gravity=(0, 0, -p['g']), law='linear', damping=p['md_damping'])
        O.dt = p['md_safety'] * utils.PWaveTimeStep()
        p['dt'] = O.dt
    else:
        raise ValueError("method must be 'CD' or 'MD', not %r" % (method,))


def solver_stats():
    """(contacts, sweeps, residual) of the last step; MD has no sweeps (0, 0.0)."""
    e = O.engines[-1]
    if isinstance(e, ContactDynamicsIntegrator):
        return e.nContacts, e.iterations, e.residual
    return O.interactions.countReal(), 0, 0.0


def scene_from_snapshot(path, **overrides):
    """Rebuild a pile scene from a snapshot ``.npz`` (positions, radii, velocities, fixed
    flags; the run's parameters from the ``run.json`` beside it when present, ``overrides``
    on top). Angular velocities and impulses are not in snapshots: they restart at zero.
    Returns the parameter dict (the snapshot time is in its ``time``; O.time restarts at 0)."""
    p = defaults()
    run_json = os.path.join(os.path.dirname(os.path.abspath(path)), 'run.json')
    if os.path.exists(run_json):
        p.update({k: v for k, v in read_run_json(run_json).items() if k in p})
    p.update(overrides)
    snap = np.load(path)
    if 'm_grain' in snap.files or p.get('grain_shape', 'sphere') != 'sphere':
        raise ValueError('%s is a snapshot of clump grains: a scene is rebuilt from it for sphere grains only (resume or '
                         'load the run from its checkpoint instead: PileRun.load)' % path)
    O.reset()
    mat = material(p['mu'], p['rho'])
    O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
    for x, r, v, fixed in zip(snap['pos'], snap['radius'], snap['vel'], snap['fixed']):
        b = utils.sphere(tuple(x), float(r), fixed=bool(fixed), material=mat)
        b.state.vel = Vector3(*v)
        O.bodies.append(b)
    set_engines(p)
    return p


def cone_state(run_dir, n_grains=14000, slope_deg=28.0, settle=0.1, cell_grains=2000, log=print, separate=False, **overrides):
    """A large pile state for solver benchmarks, built in minutes instead of by deposition.

    Grains of the protocol's diameter law in a dense random packing (YADE's
    ``pack.randomDensePack``, periodic compression of ``cell_grains`` spheres, tiled) are cut to a cone of
    slope ``slope_deg`` and base radius sized for about ``n_grains`` grains, set on the paving
    (base at z = d_max, just above it) and settled by the CD engine for ``settle`` seconds of
    simulated time. Writes ``run.json`` and ``snap_<t>.npz`` in ``run_dir`` (the format of
    :func:`run`'s snapshots, so ``scripts/bench/solver_bench.py --snapshot`` takes it) and returns
    the snapshot's path.

    The dense packing's compression leaves overlaps (up to 2.6e-3 d at 14 000 grains), which CD
    keeps as overlap allowances. With ``separate=True`` the kept grains are first spread apart
    about the base centre by the factor :func:`separating_dilation` gives (the cone keeps its
    slope and grows by that factor, about 0.3 %), so that no two grains overlap and the state
    settles under gravity like a deposited one: the state to start soft-contact MD from.

    It stands in for the end state of the paper's deposition (14 000 grains), which deposition
    takes hours to reach (docs/performance.md). Its history differs (no layers, no feeding, a
    denser start): a benchmark state, not a result."""
    from yade import pack
    p = defaults()
    p.update({k: v for k, v in overrides.items() if v is not None})
    unknown = set(p) - set(defaults())
    if unknown:
        raise ValueError('unknown pile parameters: %s' % ', '.join(sorted(unknown)))
    if p['grain_shape'] != 'sphere':
        raise ValueError('cone_state builds piles of spheres only, not grain_shape=%r' % (p['grain_shape'],))
    if n_grains < 10 or not (5.0 <= slope_deg <= 40.0) or settle < 0:
        raise ValueError('cone_state needs n_grains >= 10, 5 <= slope_deg <= 40 and settle >= 0 (got %r, %r, %r)'
                         % (n_grains, slope_deg, settle))
    p['n_grains'] = n_grains
    os.makedirs(run_dir, exist_ok=True)
    tan_s, cos_s = math.tan(math.radians(slope_deg)), math.cos(math.radians(slope_deg))
    guess = expected_base_radius(n_grains, p['d_min'], p['d_max'], slope_deg, packing=0.62)
    r_mean, fuzz = (p['d_min'] + p['d_max']) / 4, (p['d_max'] - p['d_min']) / (p['d_max'] + p['d_min'])
    t0 = time.time()
    side = 1.8 * guess  # a box with room for the cone: small cones lose many grains at their surface
    packing = pack.randomDensePack(pack.inAlignedBox((-side, -side, 0), (side, side, side * tan_s)), radius=r_mean,
                                   rRelFuzz=fuzz, spheresInCell=cell_grains, returnSpherePack=True, seed=p['seed'])
    centres = np.array([tuple(c) for c, r in packing])
    radii = np.array([r for c, r in packing])

    def inside(radius):  # grains wholly inside the cone of base radius `radius` standing on z = 0
        rho = np.hypot(centres[:, 0], centres[:, 1])
        return (centres[:, 2] >= radii) & (rho <= (radius * tan_s - centres[:, 2] - radii / cos_s) / tan_s)

    if inside(side).sum() < n_grains:
        raise RuntimeError('cone_state: the dense packing holds fewer than %d grains in the largest cone (radius %g m)' % (n_grains, side))
    lo, hi = 0.2 * guess, side  # the smallest base radius that holds n_grains grains, by bisection
    for _ in range(40):
        radius = 0.5 * (lo + hi)
        lo, hi = (radius, hi) if inside(radius).sum() < n_grains else (lo, radius)
    radius = hi
    # bottom-up, as a deposition creates them: body ids then follow height as in a deposited
    # pile, and a sweep in height order visits bodies close in memory
    kept = np.flatnonzero(inside(radius))
    kept = kept[np.argsort(centres[kept, 2], kind='stable')]
    scale = separating_dilation(centres[kept], radii[kept]) if separate else 1.0
    grains = [(scale * centres[k], radii[k]) for k in kept]
    if separate:
        log('cone_state: grains spread apart by a factor %.6f (largest overlap removed)' % scale)
    log('cone_state: %d grains in a cone of radius %.2f cm, height %.2f cm (dense packing of %d grains: %.0f s)'
        % (len(grains), 100 * radius, 100 * radius * tan_s, len(radii), time.time() - t0))
    z0 = p['d_max']  # the paving's grains reach z = 2 r ≤ d_max
    p['floor_radius'] = p['floor_radius'] or 1.3 * radius
    p['n_paving'] = build_scene(p)
    mat = O.materials[0]
    for c, r in grains:
        O.bodies.append(utils.sphere((c[0], c[1], c[2] + z0), r, material=mat))
    p.update(n_grains=len(grains), cone_slope_deg=slope_deg, cone_settle_s=settle, cone_separated=bool(separate))
    with open(os.path.join(run_dir, 'run.json'), 'w') as f:
        json.dump(p, f, indent=1)
    steps, t1 = int(round(settle / p['dt'])), time.time()
    chunk = max(1, steps // 20)
    while O.iter < steps:
        O.run(min(chunk, steps - O.iter), True)
        contacts, sweeps, residual = solver_stats()
        speed = max(b.state.vel.norm() for b in O.bodies if b.dynamic)
        log('cone_state: t=%.4f s  contacts %d  sweeps %d  residual %.1e  %.2f s/step  fastest grain %.2e m/s'
            % (O.time, contacts, sweeps, residual, (time.time() - t1) / O.iter, speed))
    path = os.path.join(run_dir, 'snap_%08.3f.npz' % O.time)
    snapshot(path, {}, p)
    return path


def separating_dilation(centres, radii, margin=1e-9):
    """The factor s >= 1 by which spreading the spheres' centres apart about the origin (x -> s x)
    leaves no two of them overlapping: max over touching pairs of (r_i + r_j) / |x_i - x_j|, times
    1 + ``margin``; 1.0 when none overlaps. Every distance grows by the same factor, so the largest
    relative overlap sets it."""
    from scipy.spatial import cKDTree
    centres, radii = np.asarray(centres, float), np.asarray(radii, float)
    if len(radii) < 2:
        return 1.0
    pairs = cKDTree(centres).query_pairs(2 * radii.max(), output_type='ndarray')
    if len(pairs) == 0:
        return 1.0
    dist = np.linalg.norm(centres[pairs[:, 0]] - centres[pairs[:, 1]], axis=1)
    if (dist <= 0).any():
        raise ValueError('separating_dilation: two spheres share a centre; no dilation separates them')
    worst = ((radii[pairs[:, 0]] + radii[pairs[:, 1]]) / dist).max()
    return float(worst) * (1 + margin) if worst > 1 else 1.0


def creation_height(x, y, r, centres, radii):
    """Lowest height of a sphere (radius ``r``) centred on the vertical through (x, y) at which
    it rests on one of the spheres (``centres``, ``radii``) met on that vertical, or on the
    plane z = 0, without overlapping any of them: :func:`grains.resting_height` for one sphere.

    Sphere j is met when its horizontal distance d_j < r + r_j; the new sphere then overlaps it
    for heights within s_j = sqrt((r + r_j)² − d_j²) of z_j and rests on it at z_j + s_j. The
    candidates are these resting heights and r (the plane); the lowest free one is returned, so
    a grain in flight above the pile does not lift the new grain above itself."""
    return grains.resting_height(x, y, np.zeros((1, 3)), [r], centres, radii)


class Feeder:
    """Creates grains by the paper's rule (a clump, for ``grain_shape`` other than a sphere, in a
    uniformly random orientation drawn after its position and size, so that sphere runs draw the
    same numbers as before clumps). Keeps the list of spheres (grains or clump members) near the
    axis, the only ones a new grain can touch, refreshed from all of them every 20 creations."""

    def __init__(self, p, rng, births, clock=None):
        self.p, self.rng, self.births = p, rng, births
        self.clock = clock or Clock()    # the run's clock (birth times); default: YADE's
        self.shape = p.get('grain_shape', 'sphere')
        if self.shape == 'sphere':
            self.reach = p['feed_radius'] + p['d_max']  # a sphere outside this cylinder is never touched
        else:   # the largest grain's circumscribed radius and the largest sphere it may touch
            a_max = grains.member_radius(self.shape, p['d_max'])
            self.reach = p['feed_radius'] + grains.circumradius(self.shape) * a_max + max(0.5 * p['d_max'], a_max)
        self.near = []
        self.count = 0

    def refresh(self):
        """Rebuild the list of spheres near the axis (within reach of a new grain) from all bodies."""
        self.near = [b.id for b in O.bodies if isinstance(b.shape, Sphere)
                     and (b.state.pos[0] ** 2 + b.state.pos[1] ** 2) < (self.reach + 2 * self.p['d_max']) ** 2]

    def create(self):
        """Create the next grain: its centre drawn uniformly over the feed disc, its diameter
        uniformly in [d_min, d_max], placed at the lowest height on that vertical where it rests on
        a sphere or the floor without overlapping any (:func:`creation_height`; a clump turned at
        random, :func:`grains.resting_height`); records its birth time; returns its body id."""
        if self.count % 20 == 0 or not self.near:
            self.refresh()
        p, rng = self.p, self.rng
        rr = p['feed_radius'] * math.sqrt(rng.random())
        a = 2 * math.pi * rng.random()
        x, y = rr * math.cos(a), rr * math.sin(a)
        r = 0.5 * rng.uniform(p['d_min'], p['d_max'])
        states = [O.bodies[i].state for i in self.near]
        centres = np.array([tuple(s.pos) for s in states]) if states else np.zeros((0, 3))
        radii = np.array([O.bodies[i].shape.radius for i in self.near])
        if self.shape == 'sphere':
            z = creation_height(x, y, r, centres, radii)
            bid = add_grain(x, y, z, r)
            members = [bid]
        else:   # the template scaled to the drawn volume, turned at random
            rotation = grains.random_rotation(rng)
            am = grains.member_radius(self.shape, 2 * r)
            offsets = grains.shape(self.shape)['offsets'] * am @ rotation.T
            z = grains.resting_height(x, y, offsets, np.full(len(offsets), am), centres, radii)
            bid = add_clump(np.array([x, y, z]) + offsets, am, self.shape)
            members = sorted(O.bodies[bid].shape.members)
        self.births[bid] = self.clock.time()
        self.near.extend(members)
        self.count += 1
        return bid


class Clock:
    """The run's time and step count: O.time and O.iter plus the offsets of a run rebuilt from
    its saved state (YADE's clock restarts at 0 in a new scene). 0 + x == x, so a run that never
    was rebuilt keeps O.time's exact values."""

    def __init__(self, t0=0.0, i0=0):
        self.t0, self.i0 = t0, i0

    def time(self):
        """The run's simulated time [s]."""
        return self.t0 + O.time

    def iter(self):
        """The run's step count."""
        return self.i0 + O.iter

"""Moreau's 3D sand pile (paper §IV.2), built with the Contact Dynamics engine.

Protocol (defaults are the paper's; SI units inside, the paper's cm in comments):

- grains: spheres with diameters uniform in [0.25, 0.5] cm, density 1000 kg/m³ (inferred from
  the paper's bulk density 0.615 g/cm³ at a packing fraction near 0.6);
- floor: a random paving of fixed grains of the same size distribution, resting on the plane
  z = 0 (a wall at z = 0 under it catches grains that slip between paving grains);
- friction 0.4 everywhere, restitution 0, gravity 9.81 m/s², time step 2e-4 s;
- creation: one grain at a time, 200 per second, at zero velocity, its centre on a vertical
  through a uniformly random point of the disc of radius 0.8 cm about the axis Oz, at the
  lowest height at which it rests, without overlap, on a grain met on that vertical (in flight
  or not), on the paving or on the plane (see :func:`creation_height`).

``method='MD'`` runs the same protocol with YADE's soft contacts instead (linear spring–slider,
Young's modulus ``young``, Cundall damping ``md_damping``, ``O.dt = md_safety·PWaveTimeStep()``):
the CD-versus-MD comparison of a pile (``scripts/compare_pile.py``).

A run directory holds ``run.json`` (the parameters), ``snap_<time>.npz`` snapshots (the data
every analysis needs, see :func:`snapshot`), ``ckpt/`` (verified checkpoint units to ``resume``
from, see :class:`PileRun` and docs/reliability.md) and ``progress.csv``.
"""
import json
import math
import os
import signal
import time

import numpy as np

from yade import O, utils, Vector3
from yade.wrapper import Sphere, ContactDynamicsIntegrator

from . import engines, runcost, runstate
from .ensemble import creation_period, feed_time
from .checkpoint import CheckpointStore, CheckpointError, has_checkpoint
from .scenes import material

DEFAULTS = dict(
    n_grains=14000,      # grains to create
    d_min=0.0025,        # m   (0.25 cm)
    d_max=0.0050,        # m   (0.50 cm)
    rho=1000.0,          # kg/m³
    mu=0.4,
    en=0.0,
    g=9.81,              # m/s²
    dt=2e-4,             # s
    rate=200.0,          # grains per second
    feed_radius=0.008,   # m   (0.8 cm)
    floor_radius=0.0,    # m; 0: sized from n_grains (1.4 × the expected base radius)
    relax=0.0,           # s of relaxation after the last grain
    seed=1,
    epochs='',           # comma-separated snapshot times [s]; '' = every snap_every
    snap_every=2.0,      # s between snapshots when epochs is empty
    checkpoint_every=60.0,  # wall-clock seconds between checkpoints
    tolerance=1e-3,      # Gauss–Seidel relative residual (see docs/pile.md for its effect on forces)
    max_iter=2000,
    relaxation=1.0,      # Gauss–Seidel over-relaxation ω (with momentum off, 1.8 halves the sweeps on piles)
    momentum=True,       # Nesterov momentum (piles: 3.9–5.5× fewer sweeps, 1.8–2.5× faster steps; docs/performance.md)
    correction_momentum=False,  # momentum in the position correction too: 4x fewer correction sweeps; opt-in until checked on whole piles (docs/performance.md)
    sweep_order=5,       # Gauss–Seidel order: 5 slabs (parallel with yade -j2, same results for any thread count), 1 height
    parallel_min_contacts=10000,  # fewer contacts: sweeps on one thread (same results; 2 threads gain nothing there and collapse beside another busy process)
    vtk=False,           # also export VTK files (ParaView) at snapshots
    stop_time=0.0,       # s; > 0: checkpoint and stop there (continue later with resume)
    method='CD',         # 'CD', or 'MD': YADE's soft contacts (linear spring–slider) on the same protocol
    young=1e7,           # Pa; MD only (contact stiffness kn = young·r)
    md_safety=0.5,       # MD only: O.dt = md_safety·PWaveTimeStep() (replaces dt)
    md_damping=0.2,      # MD only: Cundall's non-viscous damping, as YADE deposition scripts use
)


# ----------------------------------------------------------------------------- set-up

def expected_base_radius(n, d_min, d_max, slope_deg=26.0, packing=0.6):
    """Base radius [m] of a cone of ``n`` grains at the given slope and packing fraction."""
    v_grain = math.pi / 6 * (d_max ** 4 - d_min ** 4) / (4 * (d_max - d_min))  # mean of d³ times π/6
    volume = n * v_grain / packing
    return (3 * volume / (math.pi * math.tan(math.radians(slope_deg)))) ** (1 / 3)


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
    """Append one pile grain (the run's material, at rest); returns its id."""
    return O.bodies.append(utils.sphere((x, y, z), r, material=O.materials[0]))


def set_engines(p):
    """The run's engines and time step: the CD engine list, or (``method='MD'``) YADE's linear
    soft-contact list with ``O.dt = md_safety·PWaveTimeStep()`` (then written back to p['dt'])."""
    method = p.get('method', 'CD')
    if method == 'CD':
        O.engines = engines(gravity=(0, 0, -p['g']), en=p['en'], tolerance=p['tolerance'], maxIter=p['max_iter'],
                            relaxation=p.get('relaxation', 1.0), momentum=bool(p.get('momentum', True)),
                            correctionMomentum=bool(p.get('correction_momentum', False)),
                            parallelMinContacts=int(p.get('parallel_min_contacts', DEFAULTS['parallel_min_contacts'])),
                            sweepOrder=int(p.get('sweep_order', 1)),
                            warnUnconverged=False)
        O.dt = p['dt']
    elif method == 'MD':
        from .md import md_engines
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
    import json
    p = dict(DEFAULTS)
    run_json = os.path.join(os.path.dirname(os.path.abspath(path)), 'run.json')
    if os.path.exists(run_json):
        with open(run_json) as f:
            p.update({k: v for k, v in json.load(f).items() if k in DEFAULTS})
    p.update(overrides)
    snap = np.load(path)
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

    It stands in for the end state of the paper's deposition (14 000 grains, about 33 000
    contacts), which deposition would take about 40 h to reach here (docs/performance.md). Its
    history differs (no layers, no feeding, a denser start): a benchmark state, not a result."""
    from yade import pack
    p = dict(DEFAULTS)
    p.update({k: v for k, v in overrides.items() if v is not None})
    unknown = set(p) - set(DEFAULTS)
    if unknown:
        raise ValueError('unknown pile parameters: %s' % ', '.join(sorted(unknown)))
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


# ----------------------------------------------------------------------------- creation rule

def creation_height(x, y, r, centres, radii):
    """Lowest height of a sphere (radius ``r``) centred on the vertical through (x, y) at which
    it rests on one of the spheres (``centres``, ``radii``) met on that vertical, or on the
    plane z = 0, without overlapping any of them.

    Sphere j is met when its horizontal distance d_j < r + r_j; the new sphere then overlaps it
    for heights within s_j = sqrt((r + r_j)² − d_j²) of z_j and rests on it at z_j + s_j. The
    candidates are these resting heights and r (the plane); the lowest free one is returned, so
    a grain in flight above the pile does not lift the new grain above itself."""
    if len(radii) == 0:
        return r
    d2 = (centres[:, 0] - x) ** 2 + (centres[:, 1] - y) ** 2
    reach = (r + radii) ** 2 - d2
    hit = reach > 0
    if not hit.any():
        return r
    zc, s = centres[hit, 2], np.sqrt(reach[hit])
    candidates = np.sort(np.concatenate(([r], zc + s)))
    candidates = candidates[candidates >= r]
    # free: outside every open interval (z_j − s_j, z_j + s_j); a relative margin absorbs round-off
    free = np.all(np.abs(candidates[:, None] - zc[None, :]) >= s[None, :] * (1 - 1e-12), axis=1)
    return float(candidates[np.argmax(free)])  # the highest candidate is always free


class Feeder:
    """Creates grains by the paper's rule. Keeps the list of grains near the axis (the only ones
    a new grain can touch), refreshed from all grains every ``refresh`` creations."""

    def __init__(self, p, rng, births, clock=None):
        self.p, self.rng, self.births = p, rng, births
        self.clock = clock or Clock()    # the run's clock (birth times); default: YADE's
        self.reach = p['feed_radius'] + p['d_max']  # a grain outside this cylinder is never touched
        self.near = []
        self.count = 0

    def refresh(self):
        self.near = [b.id for b in O.bodies if isinstance(b.shape, Sphere)
                     and (b.state.pos[0] ** 2 + b.state.pos[1] ** 2) < (self.reach + 2 * self.p['d_max']) ** 2]

    def create(self):
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
        z = creation_height(x, y, r, centres, radii)
        bid = add_grain(x, y, z, r)
        self.births[bid] = self.clock.time()
        self.near.append(bid)
        self.count += 1
        return bid


# ----------------------------------------------------------------------------- records

def snapshot(path, births, p, t=None):
    """Save what the analyses need at the current time ``t`` (default O.time; SI): grains (pos,
    radius, vel, fixed, birth time, ids) and contacts (ids, point, normal, force on body 2 [N]).
    Written under a temporary name and renamed: a kill never leaves half a snapshot."""
    ids, pos, rad, vel, fixed, birth = [], [], [], [], [], []
    for b in O.bodies:
        if not isinstance(b.shape, Sphere):
            continue
        ids.append(b.id)
        pos.append(tuple(b.state.pos))
        rad.append(b.shape.radius)
        vel.append(tuple(b.state.vel))
        fixed.append(not b.dynamic)
        birth.append(births.get(b.id, -1.0))
    c1, c2, cp, cn, cf = [], [], [], [], []
    for i in O.interactions:
        if not i.isReal:
            continue
        f = i.phys.normalForce + i.phys.shearForce
        c1.append(i.id1)
        c2.append(i.id2)
        cp.append(tuple(i.geom.contactPoint))
        cn.append(tuple(i.geom.normal))
        cf.append(tuple(f))
    tmp = path + '.tmp'
    with open(tmp, 'wb') as f:
        np.savez_compressed(f, time=O.time if t is None else t, g=p['g'], rho=p['rho'], ids=np.array(ids), pos=np.array(pos),
                            radius=np.array(rad), vel=np.array(vel), fixed=np.array(fixed), birth=np.array(birth),
                            c_id1=np.array(c1, dtype=int), c_id2=np.array(c2, dtype=int), c_point=np.array(cp).reshape(-1, 3),
                            c_normal=np.array(cn).reshape(-1, 3), c_force=np.array(cf).reshape(-1, 3))
    os.replace(tmp, path)


# Wall time per simulated second of a fed pile grows as N^ETA_EXPONENT: measured 1.7 at h = 1e-3 s
# (contacts ∝ N, sweeps per step ∝ N^0.7 in the 14 000- and 5000-grain runs, 1000-5200 grains);
# the same states solved at h = 2e-4 s need sweeps growing as N^0.5 (docs/performance.md, "The time
# step at scale"). The larger exponent is kept: a wrong ETA costs little on short runs.
ETA_EXPONENT = 1.7


def eta_seconds(t, t_end, t_feed_end, wall_per_sim_s, exponent=ETA_EXPONENT, points=200):
    """Wall time [s] left from simulated time ``t`` to ``t_end`` when a simulated second now costs
    ``wall_per_sim_s`` and its cost grows as the grain count to the power ``exponent``, the count
    growing in proportion to the time until ``t_feed_end`` and constant after it (the relaxation).
    A constant rate (``exponent`` 0) gives ``(t_end - t) * wall_per_sim_s``."""
    if t >= t_end:
        return 0.0
    n_now = max(min(t, t_feed_end), 1e-12)
    s = np.linspace(t, t_end, points)
    growth = (np.minimum(s, t_feed_end).clip(min=n_now) / n_now) ** exponent
    return float(wall_per_sim_s * np.trapz(growth, s))


def feed_end_time(p):
    """Simulated time [s] at which the run ``p`` creates its last grain (:func:`ensemble.feed_time`)."""
    return feed_time(p['n_grains'], p['rate'], p['dt'])


def snapshot_times(p, t_end):
    """Times [s] of a run's snapshots: its epochs, or every snap_every up to t_end (the last at t_end)
    and, when the run relaxes after the feed, the end of the feed too (the analyses' "end of feed"
    epoch, which the regular times need not hit: 25 s for 5000 grains, snap_every 2 s)."""
    if p['epochs']:
        return _epoch_list(p['epochs'])
    k = max(1, int(round(t_end / p['snap_every'])))
    times = [t_end * (i + 1) / k for i in range(k)]
    t_feed = feed_end_time(p)
    if t_feed < t_end - 0.5 * p['dt'] and min(abs(t - t_feed) for t in times) > 0.5 * p['dt']:
        times = sorted(times + [t_feed])
    return times


# ----------------------------------------------------------------------------- parameters

# Options a resumed run may be given anew; any other option must equal the run's own.
RESUME_MAY_CHANGE = ('stop_time', 'checkpoint_every', 'vtk', 'parallel_min_contacts')
# what a branch (:func:`branch`) may change besides: how precisely each step is solved, not the
# pile's physics or protocol (grains, feed, time step, friction)
BRANCH_MAY_CHANGE = RESUME_MAY_CHANGE + ('tolerance', 'max_iter', 'correction_momentum')


def _epoch_list(epochs):
    try:
        return sorted(float(t) for t in str(epochs).split(',') if t.strip())
    except ValueError:
        raise ValueError("epochs must be comma-separated times in seconds, not %r" % (epochs,)) from None


def check_params(p):
    """Raise ValueError naming the first bad parameter of a pile run (before any work is done)."""
    unknown = set(p) - set(DEFAULTS)
    if unknown:
        raise ValueError('unknown pile parameters: %s' % ', '.join(sorted(unknown)))
    for key, default in DEFAULTS.items():
        v = p[key]
        if isinstance(default, bool):
            ok = isinstance(v, (bool, np.bool_))
        elif isinstance(default, (int, float)):
            ok = isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) and math.isfinite(v)
        else:
            ok = isinstance(v, str)
        if not ok:
            raise ValueError('pile parameter %s must be a %s, not %r' % (key, type(default).__name__, v))
    rules = [
        ('n_grains', p['n_grains'] >= 1 and int(p['n_grains']) == p['n_grains'], 'a positive integer'),
        ('d_min', p['d_min'] > 0, 'positive [m]'),
        ('d_max', p['d_max'] >= p['d_min'], '>= d_min [m]'),
        ('rho', p['rho'] > 0, 'positive [kg/m³]'),
        ('mu', p['mu'] >= 0, '>= 0'),
        ('en', 0 <= p['en'] <= 1, 'in [0, 1]'),
        ('g', p['g'] > 0, 'positive [m/s²]'),
        ('dt', p['dt'] > 0, 'positive [s]'),
        ('rate', p['rate'] > 0, 'positive [grains/s]'),
        ('feed_radius', p['feed_radius'] >= 0, '>= 0 [m]'),
        ('floor_radius', p['floor_radius'] >= 0, '>= 0 [m] (0: sized from n_grains)'),
        ('relax', p['relax'] >= 0, '>= 0 [s]'),
        ('snap_every', p['snap_every'] > 0, 'positive [s]'),
        ('checkpoint_every', p['checkpoint_every'] > 0, 'positive [s of wall time]'),
        ('tolerance', 0 < p['tolerance'] < 1, 'in (0, 1)'),
        ('max_iter', p['max_iter'] >= 1, '>= 1'),
        ('relaxation', 0 < p['relaxation'] < 2, 'in (0, 2)'),
        ('sweep_order', p['sweep_order'] in (0, 1, 2, 3, 4, 5), 'one of 0–5'),
        ('parallel_min_contacts', p['parallel_min_contacts'] >= 0 and int(p['parallel_min_contacts']) == p['parallel_min_contacts'],
         'an integer >= 0 (0: threads at any size)'),
        ('stop_time', p['stop_time'] >= 0, '>= 0 [s]'),
        ('method', p['method'] in ('CD', 'MD'), "'CD' or 'MD'"),
        ('young', p['young'] > 0, 'positive [Pa]'),
        ('md_safety', 0 < p['md_safety'] <= 1, 'in (0, 1]'),
        ('md_damping', 0 <= p['md_damping'] < 1, 'in [0, 1)'),
    ]
    for key, ok, what in rules:
        if not ok:
            raise ValueError('pile parameter %s must be %s (got %r)' % (key, what, p[key]))
    if any(t <= 0 for t in _epoch_list(p['epochs'])):
        raise ValueError('pile parameter epochs must hold positive times (got %r)' % (p['epochs'],))


def disk_need(p):
    """Bytes a run needs in its directory, estimated from its size: the checkpoints kept (three
    units at once while one is written; 1000 B per body each, measured 480 on a 100-grain pile,
    whose grains have fewer contacts than a large pile's) and the snapshots (400 B per body each,
    measured 125)."""
    floor_radius = p['floor_radius'] or 1.4 * expected_base_radius(p['n_grains'], p['d_min'], p['d_max'])
    d_mean = 0.5 * (p['d_min'] + p['d_max'])
    bodies = p['n_grains'] + 0.55 * (floor_radius / (0.5 * d_mean)) ** 2
    t_end = feed_end_time(p) + p['relax']
    n_snaps = len(snapshot_times(p, t_end))
    return int(bodies * (3 * 1000 + n_snaps * 400) + 1e6)


def preflight(run_dir, p):
    """Fail before work: the run directory must be creatable, writable, and hold room for the
    run's checkpoints and snapshots. Raises OSError / CheckpointError with the cause."""
    try:
        os.makedirs(run_dir, exist_ok=True)
        probe = os.path.join(run_dir, '.write-probe')
        with open(probe, 'wb') as f:
            f.write(b'\0' * 4096)
            f.flush()
            os.fsync(f.fileno())
        os.remove(probe)
    except OSError as e:
        raise CheckpointError('run directory %s is not usable: %s' % (run_dir, e.strerror or e)) from e
    st = os.statvfs(run_dir)
    free, need = st.f_bavail * st.f_frsize, disk_need(p)
    if free < need:
        raise CheckpointError('run directory %s has %.1f MB free; this run needs about %.1f MB for its checkpoints '
                              'and snapshots' % (run_dir, free / 1e6, need / 1e6))


# ----------------------------------------------------------------------------- driver

class Clock:
    """The run's time and step count: O.time and O.iter plus the offsets of a run rebuilt from
    its saved state (YADE's clock restarts at 0 in a new scene). 0 + x == x, so a run that never
    was rebuilt keeps O.time's exact values."""

    def __init__(self, t0=0.0, i0=0):
        self.t0, self.i0 = t0, i0

    def time(self):
        return self.t0 + O.time

    def iter(self):
        return self.i0 + O.iter


RUN_FILES = ('run.json', 'progress.csv', 'segments.csv', 'checkpoint.json', 'checkpoint.yade.gz')


def _run_json(run_dir, missing):
    """A run's parameters: its ``run.json`` over DEFAULTS (options added since the run began
    take their defaults). ``missing`` (with one %s for the directory) is the error without it."""
    path = os.path.join(run_dir, 'run.json')
    if not os.path.exists(path):
        raise FileNotFoundError(missing % run_dir)
    p = dict(DEFAULTS)
    with open(path) as f:
        p.update(json.load(f))
    return p


class PileRun:
    """One pile run in its directory: started, resumed from a checkpoint, advanced, checkpointed.

    A checkpoint is one verified unit of :class:`yadecd.checkpoint.CheckpointStore` holding
    ``state.npz`` (the layout-independent state, :mod:`yadecd.runstate`) and ``scene.yade.gz``
    (YADE's archive, the fast path: it resumes bit for bit when the plugin is the same)."""

    def __init__(self, run_dir, p, log):
        self.run_dir, self.p, self.log = run_dir, p, log
        self.store = CheckpointStore(run_dir)
        self.clock = Clock()
        self.births, self.done_snaps = {}, set()
        self.rng = np.random.default_rng(p['seed'])
        self.feeder = Feeder(p, self.rng, self.births, self.clock)
        self.resumed_from = None     # description of the checkpoint resumed from
        self.wall_before = 0.0       # wall time [s] of the segments before this one (a resumed run)
        self.segment_start = time.time()

    # ------------------------------------------------------------------ starting
    @classmethod
    def start(cls, run_dir, overrides, log=print, overwrite=False):
        """A new run: parameters checked, directory checked (an existing run is never replaced
        unless ``overwrite``), floor and engines built, ``run.json`` written."""
        p = dict(DEFAULTS)
        p.update({k: v for k, v in overrides.items() if v is not None})
        check_params(p)
        if has_run(run_dir):
            if not overwrite:
                raise FileExistsError('%s already holds a pile run: pass resume=True (--resume) to continue it, or '
                                      'overwrite=True (--overwrite) to start it again' % run_dir)
            clear_run(run_dir)
        preflight(run_dir, p)
        self = cls(run_dir, p, log)
        p['n_paving'] = build_scene(p)
        _write_json(os.path.join(run_dir, 'run.json'), p)
        return self

    @classmethod
    def resume(cls, run_dir, overrides, log=print):
        """Continue the run in ``run_dir`` from its newest valid checkpoint (a damaged one is
        reported and the one before it used). ``overrides`` may only change RESUME_MAY_CHANGE;
        a run killed before its first checkpoint starts again from its ``run.json``."""
        p = _run_json(run_dir, 'nothing to resume in %s: it holds no run.json')
        given = {k: v for k, v in overrides.items() if v is not None}
        unknown = set(given) - set(DEFAULTS)
        if unknown:
            raise ValueError('unknown pile parameters: %s' % ', '.join(sorted(unknown)))
        clash = ['%s (run: %r, given: %r)' % (k, p.get(k), v) for k, v in sorted(given.items())
                 if k not in RESUME_MAY_CHANGE and p.get(k) != v]
        if clash:
            raise ValueError('options differ from the run being resumed in %s: %s; only %s may change on resume'
                             % (run_dir, ', '.join(clash), ', '.join(RESUME_MAY_CHANGE)))
        p['stop_time'] = 0.0            # a stop applies to the segment it was given for
        p.update({k: v for k, v in given.items() if k in RESUME_MAY_CHANGE})
        check_params({k: v for k, v in p.items() if k in DEFAULTS})
        preflight(run_dir, p)
        for name in os.listdir(run_dir):      # files a kill left half-written (snapshots, run.json)
            if name.endswith('.tmp') and os.path.isfile(os.path.join(run_dir, name)):
                os.remove(os.path.join(run_dir, name))
        self = cls(run_dir, p, log)
        if not self._load_newest():
            log('no checkpoint yet in %s: starting the run again' % run_dir)
            clear_run(run_dir, keep=('run.json',))
            p['n_paving'] = build_scene(p)
            return self
        self._truncate_progress()
        log('resumed %s at t=%.3f s, %d grains (%s)' % (run_dir, self.clock.time(), self.feeder.count, self.resumed_from))
        return self

    @classmethod
    def load(cls, run_dir, log=print):
        """The run's newest valid checkpoint loaded into ``O`` without continuing the run, for
        tools that re-solve or inspect a run's state: nothing in ``run_dir`` changes. Loads YADE's
        archive when the checkpoint has one written by this plugin, else rebuilds the scene from
        its ``state.npz`` (a carried run), as :meth:`resume` does; ``clock.time()`` is then the
        run's time and ``births`` every grain's birth time."""
        self = cls(run_dir, _run_json(run_dir, '%s holds no pile run: no run.json'), log)
        if not self._load_newest():
            raise FileNotFoundError('%s holds no valid checkpoint to load' % run_dir)
        return self

    def _load_newest(self):
        """Load the newest valid checkpoint (a damaged one is reported and the one before it
        used), or a first-release one, into ``O``; False when the run has none."""
        latest = self.store.latest()
        for m in self.store.messages:
            self.log('checkpoint: ' + m)
        if latest is not None:
            self._resume_unit(*latest)
        elif os.path.exists(os.path.join(self.run_dir, 'checkpoint.json')):
            self._resume_release_1()
        else:
            return False
        return True

    def _restore_counters(self, meta, births, near):
        self.births.update(births)
        self.rng.bit_generator.state = meta['rng']
        self.feeder.count = int(meta['created'])
        self.feeder.near = [int(i) for i in near]
        self.done_snaps.update(meta['snaps'])
        self.wall_before = float(meta['wall_s']) if 'wall_s' in meta else self._progress_wall(self.clock.time())

    def _progress_wall(self, t):
        """Wall time [s] of the last progress line at or before ``t`` (checkpoints written before they
        recorded the run's wall time: their first segment's progress lines count from the start)."""
        path, wall = os.path.join(self.run_dir, 'progress.csv'), 0.0
        if os.path.exists(path):
            with open(path) as f:
                for ln in f.readlines()[1:]:
                    parts = ln.strip().split(',')
                    if len(parts) >= 6 and _float(parts[0]) <= t + 0.5 * self.p['dt']:
                        wall = _float(parts[5])
        return wall if math.isfinite(wall) else 0.0

    def _resume_unit(self, seq, unit, info):
        meta = info['meta']
        data = runstate.read(os.path.join(unit, 'state.npz'))
        births = dict(zip(runstate.extra(data, 'birth_id').tolist(), runstate.extra(data, 'birth_time').tolist()))
        near = runstate.extra(data, 'near').tolist()
        scene = os.path.join(unit, 'scene.yade.gz')
        if meta.get('plugin_digest') == runstate.plugin_digest() and os.path.exists(scene):
            O.load(scene)
            # attributes not saved with the scene come from the run's parameters
            O.engines[-1].correctionMomentum = bool(self.p.get('correction_momentum', False))
            O.engines[-1].parallelMinContacts = int(self.p['parallel_min_contacts'])
            self.clock.t0, self.clock.i0 = meta['time_offset'], meta['iter_offset']
            self.resumed_from = 'checkpoint %d, YADE archive: bit-identical continuation' % seq
        else:
            self.rebuild(data)
            self.resumed_from = ('checkpoint %d, rebuilt from state.npz: written by plugin %s, this is %s; the same '
                                 'physical state, not bit-identical to an uninterrupted run'
                                 % (seq, str(meta.get('plugin_digest'))[:12], runstate.plugin_digest()[:12]))
        if abs(self.clock.time() - meta['time']) > 1e-9 or self.clock.iter() != meta['iter']:
            raise CheckpointError('checkpoint %d is inconsistent: its scene is at t=%r, step %d, its record at t=%r, step %d'
                                  % (seq, self.clock.time(), self.clock.iter(), meta['time'], meta['iter']))
        self._restore_counters(meta, births, near)
        integ = O.engines[-1]
        if hasattr(integ, 'nUnconverged'):
            integ.nUnconverged = int(meta.get('n_unconverged', 0))

    def _resume_release_1(self):
        """Checkpoints of the first release (``checkpoint.yade.gz`` + ``checkpoint.json``)."""
        try:
            with open(os.path.join(self.run_dir, 'checkpoint.json')) as f:
                state = json.load(f)
        except ValueError as e:
            raise CheckpointError('first-release checkpoint %s/checkpoint.json is damaged (%s); it has no older copy'
                                  % (self.run_dir, e)) from e
        O.load(os.path.join(self.run_dir, 'checkpoint.yade.gz'))
        meta = dict(rng=state['rng'], created=state['created'], snaps=state['snaps'])
        self._restore_counters(meta, {int(k): v for k, v in state['births'].items()}, [])
        self.resumed_from = 'first-release checkpoint (checkpoint.yade.gz)'

    def rebuild(self, data):
        """The scene again from a run state, by the code that builds a new run: floor and engines
        (:func:`build_scene`), grains (:func:`add_grain`), then positions, velocities and contacts
        with their warm-start impulses (:mod:`yadecd.runstate`)."""
        p = self.p
        ids, kind = data['body_id'], data['body_kind']
        n_paving = int(p['n_paving'])
        if len(ids) < n_paving + 1 or kind[0] != 0 or not (kind[1:] == 1).all():
            raise runstate.RunStateError('run state does not hold a pile scene (a wall, then spheres)')
        floor = np.column_stack([data['pos'][1:n_paving + 1, :2], data['radius'][1:n_paving + 1]])
        build_scene(p, floor=floor)
        for x, r in zip(data['pos'][n_paving + 1:], data['radius'][n_paving + 1:]):
            add_grain(x[0], x[1], x[2], r)
        runstate.restore_bodies(data)
        restored, skipped = runstate.restore_contacts(data)
        self.clock.t0, self.clock.i0 = float(data['time']), int(data['iter'])
        self.log('rebuilt from state.npz: %d bodies, %d contacts with their impulses%s'
                 % (len(ids), restored, ', %d pairs no longer in reach' % skipped if skipped else ''))

    def _truncate_progress(self):
        """Drop progress lines written after the checkpoint resumed from (they will be redone)."""
        path = os.path.join(self.run_dir, 'progress.csv')
        if not os.path.exists(path):
            return
        with open(path) as f:
            lines = f.readlines()
        t = self.clock.time() + 0.5 * self.p['dt']
        keep = lines[:1] + [ln for ln in lines[1:] if ln.count(',') >= 5 and _float(ln.split(',')[0]) <= t]
        with open(path + '.tmp', 'w') as f:
            f.writelines(keep)
        os.replace(path + '.tmp', path)

    # ------------------------------------------------------------------ checkpoints
    def checkpoint(self):
        """Write one checkpoint unit (between steps, never from inside O.run)."""
        t, it = self.clock.time(), self.clock.iter()
        bid = sorted(self.births)
        extra = dict(birth_id=np.array(bid, dtype=np.int64), birth_time=np.array([self.births[b] for b in bid]),
                     near=np.array(self.feeder.near, dtype=np.int64))
        meta = dict(time=t, iter=it, time_offset=self.clock.t0, iter_offset=self.clock.i0,
                    plugin_digest=runstate.plugin_digest(), yade_version=runstate.yade_version(),
                    rng=self.rng.bit_generator.state, created=self.feeder.count, snaps=sorted(self.done_snaps),
                    n_unconverged=int(getattr(O.engines[-1], 'nUnconverged', 0)),
                    wall_s=self.wall_before + (time.time() - self.segment_start))
        self.store.write({'state.npz': lambda path: runstate.capture(path, t, it, extra),
                          'scene.yade.gz': lambda path: O.save(path)}, meta)

    # ------------------------------------------------------------------ stepping
    def advance(self, t_stop=None):
        """Run to ``t_stop`` (default: the end of the run, or the run's stop_time), with
        creations, snapshots, progress lines and checkpoints; returns the parameter dict.

        SIGTERM and SIGINT (a shutdown, Ctrl-C) stop the run at the end of the current chunk of
        steps with a checkpoint, so that nothing is lost: the dict then has ``stopped_by`` (the
        signal's name) and ``finished`` False; ``--resume`` continues bit for bit."""
        with _StopSignals() as stop:
            return self._advance(t_stop, stop)

    def _advance(self, t_stop, stop):
        p, clock, feeder = self.p, self.clock, self.feeder
        period = creation_period(p['rate'], p['dt'])
        t_feed_end = feed_end_time(p)
        t_end = t_feed_end + p['relax']
        t_stop = min(t_end, t_stop or p['stop_time'] or t_end)
        snaps = [t for t in snapshot_times(p, t_end) if '%.3f' % t not in self.done_snaps]
        wall0, sim0 = time.time(), clock.time()
        self.segment_start = wall0
        runcost.append_segment(self.run_dir, sim0, self.wall_before, O.numThreads)
        last_ck = last_log = time.time()
        t_log = sim0                     # simulated time at the last progress line
        progress = open(os.path.join(self.run_dir, 'progress.csv'), 'a')
        if progress.tell() == 0:
            progress.write('time_s,grains,contacts,sweeps,residual,wall_s\n')
        while clock.time() < t_stop - 0.5 * p['dt'] and not stop.name:
            if feeder.count < p['n_grains'] and clock.iter() % period == 0:
                feeder.create()
            steps = period - clock.iter() % period
            if snaps:
                steps = min(steps, max(1, int(round((snaps[0] - clock.time()) / p['dt']))))
            steps = min(steps, max(1, int(round((t_stop - clock.time()) / p['dt']))))
            O.run(steps, True)
            t = clock.time()
            if snaps and t >= snaps[0] - 0.5 * p['dt']:
                tag = '%.3f' % snaps.pop(0)
                snapshot(os.path.join(self.run_dir, 'snap_%08.3f.npz' % t), self.births, p, t)
                if p['vtk']:
                    from yade import export
                    export.VTKExporter(os.path.join(self.run_dir, 'vtk_%08.3f' % t)).exportSpheres(what=dict(vel='b.state.vel'))
                self.done_snaps.add(tag)
            now = time.time()
            if now - last_log > 10 or t >= t_stop - 0.5 * p['dt']:
                rate = (t - sim0) / max(now - wall0, 1e-9)
                # the cost of a simulated second now (since the last line), grown with the grain count
                recent = (now - last_log) / (t - t_log) if t > t_log else float('inf')
                eta = eta_seconds(t, t_end, t_feed_end, recent) if math.isfinite(recent) else float('inf')
                contacts, sweeps, residual = solver_stats()
                self.log('t=%7.3f s  grains %6d/%d  contacts %6d  sweeps %4d  residual %.1e  %.3f sim-s/s  ETA %s'
                         % (t, feeder.count, p['n_grains'], contacts, sweeps, residual, rate,
                            _duration(eta)))
                progress.write('%.6f,%d,%d,%d,%.3e,%.1f\n' % (t, feeder.count, contacts, sweeps, residual,
                                                              self.wall_before + now - wall0))  # the run's wall time
                progress.flush()
                last_log, t_log = now, t
            if now - last_ck > p['checkpoint_every']:
                self.checkpoint()
                last_ck = time.time()
        self.checkpoint()
        progress.close()
        p['wall_time_s'] = time.time() - wall0   # this segment's (a resumed run: since the resume)
        p['wall_time_total_s'] = self.wall_before + p['wall_time_s']   # all segments
        p['finished'] = clock.time() >= t_end - 0.5 * p['dt']
        p['unconverged_steps'] = getattr(O.engines[-1], 'nUnconverged', 0)
        if stop.name:
            p['stopped_by'] = stop.name
            self.log('stopped by %s at t=%.4f s with a checkpoint: continue with --resume' % (stop.name, clock.time()))
        else:
            p.pop('stopped_by', None)
        _write_json(os.path.join(self.run_dir, 'run.json'), p)
        return p


class _StopSignals:
    """Within the block, SIGTERM and SIGINT only record their name (``.name``): the run loop
    stops at its next chunk boundary and checkpoints. The previous handlers come back on exit.
    Only the main thread may set handlers; elsewhere nothing is changed."""

    def __init__(self):
        self.name, self.old = None, {}

    def _note(self, signum, frame):
        self.name = signal.Signals(signum).name

    def __enter__(self):
        try:
            for s in (signal.SIGTERM, signal.SIGINT):
                self.old[s] = signal.signal(s, self._note)
        except ValueError:          # not the main thread
            self.old = {}
        return self

    def __exit__(self, *exc):
        for s, h in self.old.items():
            signal.signal(s, h)
        return False


def _duration(seconds):
    """'HH:MM:SS', with days in front when longer ('2d 03:04:05'); '?' when unknown."""
    if not math.isfinite(seconds) or seconds >= 1e8:
        return '?'
    days, rest = divmod(int(round(seconds)), 86400)
    return ('%dd ' % days if days else '') + time.strftime('%H:%M:%S', time.gmtime(rest))


def _float(text):
    try:
        return float(text)
    except ValueError:
        return float('inf')


def _write_json(path, data):
    with open(path + '.tmp', 'w') as f:
        json.dump(data, f, indent=1)
        f.flush()
        os.fsync(f.fileno())
    os.replace(path + '.tmp', path)


def has_run(run_dir):
    """Whether ``run_dir`` holds a pile run (its run.json, or checkpoints)."""
    return os.path.exists(os.path.join(run_dir, 'run.json')) or has_checkpoint(run_dir)


def clear_run(run_dir, keep=()):
    """Remove a run's own files (run.json, progress, checkpoints, snapshots, VTK) and nothing else."""
    import shutil
    if not os.path.isdir(run_dir):
        return
    for name in os.listdir(run_dir):
        path = os.path.join(run_dir, name)
        if name in keep:
            continue
        if name in RUN_FILES or name.startswith(('snap_', 'vtk_')) or name.endswith('.tmp'):
            if os.path.isdir(path):
                shutil.rmtree(path)
            else:
                os.remove(path)
        elif name == 'ckpt':
            shutil.rmtree(path)


def branch(src, dest, options, log=print):
    """Start a branch of the pile run in ``src`` in ``dest``: the run's portable part copied
    (:func:`yadecd.carry.carry`, from its newest valid checkpoint), the solver options among
    ``options`` (BRANCH_MAY_CHANGE) applied from that point on; any other option given must equal
    the source's. ``run.json`` of the branch keeps the source's parameters and history
    (progress, segments) and lists, under ``branches``, where it left its source: the source,
    the simulated time, the checkpoint, and each changed option as [before, after]. Continue it
    with ``resume``. Used to run a faster solver setting from a long run's state and compare
    the two, or to finish a run at that setting.

    :raises FileNotFoundError: ``src`` holds no run.json.
    :raises ValueError: an option outside BRANCH_MAY_CHANGE that differs from the source's, or a bad value.
    :raises FileExistsError: ``dest`` already holds a run (a branch never replaces one)."""
    from yadecd.carry import carry
    src_json = os.path.join(src, 'run.json')
    if not os.path.exists(src_json):
        raise FileNotFoundError('nothing to branch from in %s: it holds no run.json' % src)
    with open(src_json) as f:
        before = dict(DEFAULTS, **json.load(f))
    options = {k: v for k, v in options.items() if v is not None}
    unknown = sorted(set(options) - set(DEFAULTS))
    if unknown:
        raise ValueError('unknown pile parameters: %s' % ', '.join(unknown))
    clash = ['%s (source: %r, given: %r)' % (k, before.get(k), v) for k, v in sorted(options.items())
             if k not in BRANCH_MAY_CHANGE and before.get(k) != v]
    if clash:
        raise ValueError('a branch may change only %s; these differ from %s: %s'
                         % (', '.join(BRANCH_MAY_CHANGE), src, ', '.join(clash)))
    changes = {k: v for k, v in options.items() if k in BRANCH_MAY_CHANGE and before.get(k) != v}
    check_params({k: v for k, v in dict(before, **changes).items() if k in DEFAULTS})
    if has_run(dest):
        raise FileExistsError('%s already holds a pile run: a branch never replaces one' % dest)
    record = carry(src, dest, log=log)
    path = os.path.join(dest, 'run.json')
    with open(path) as f:
        p = json.load(f)
    p.setdefault('branches', []).append({
        'source': os.path.abspath(src), 'time': record['time'], 'checkpoint': record['checkpoint'],
        'changes': {k: [before.get(k), v] for k, v in sorted(changes.items())}})
    p.update(changes)
    _write_json(path, p)
    log('branch %s of %s at t=%.3f s: %s' % (dest, src, record['time'], ', '.join(
        '%s %r -> %r' % (k, before.get(k), v) for k, v in sorted(changes.items())) or 'no option changed'))
    return p


def run(run_dir, resume=False, log=print, overwrite=False, branch_from=None, **overrides):
    """Build (or resume) a pile in ``run_dir``; returns the run's parameter dict.

    Every check happens before the first step: bad parameters (ValueError), an existing run
    without ``resume`` or ``overwrite`` (FileExistsError), options that differ from the run being
    resumed (ValueError), an unwritable or too-full directory (CheckpointError). Progress lines
    give simulated time, grains, contacts, Gauss–Seidel sweeps and residual of the last step, the
    wall-clock rate and the ETA (the current cost of a simulated second, grown with the grain
    count: :func:`eta_seconds`). Snapshots go to ``snap_<t>.npz``; checkpoints to ``ckpt/``.
    ``branch_from``: start ``run_dir`` as a :func:`branch` of that run (the solver options among
    ``overrides`` changed), then continue it; other options must match the source's."""
    if branch_from is not None:
        branch(branch_from, run_dir, overrides, log)
        overrides = {k: v for k, v in overrides.items() if k in RESUME_MAY_CHANGE}
        resume = True
    if resume:
        return PileRun.resume(run_dir, overrides, log).advance()
    r = PileRun.start(run_dir, overrides, log, overwrite=overwrite)
    return r.advance()

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
every analysis needs, see :func:`snapshot`), ``checkpoint.yade.gz`` + ``checkpoint.json`` (the
state to ``resume`` from) and ``progress.csv``.
"""
import json
import math
import os
import sys
import time

import numpy as np

from yade import O, utils, Vector3
from yade.wrapper import Sphere, ContactDynamicsIntegrator

from . import engines
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
    momentum=True,       # Nesterov momentum over the sweeps (2–4× fewer sweeps on piles, docs/performance.md)
    sweep_order=5,       # Gauss–Seidel order: 5 slabs (parallel with yade -j2, same results for any thread count), 1 height
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


def build_scene(p):
    """Reset O and create the floor (wall + paving) and the engines. Returns the number of
    paving grains."""
    O.reset()
    rng = np.random.default_rng(p['seed'] + 1_000_003)  # the paving has its own stream
    mat = material(p['mu'], p['rho'])
    O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
    floor_radius = p['floor_radius'] or 1.4 * expected_base_radius(p['n_grains'], p['d_min'], p['d_max'])
    for x, y, r in paving(rng, floor_radius, p['d_min'], p['d_max']):
        O.bodies.append(utils.sphere((x, y, r), r, fixed=True, material=mat, color=(0.5, 0.5, 0.5)))
    set_engines(p)
    return len(O.bodies) - 1


def set_engines(p):
    """The run's engines and time step: the CD engine list, or (``method='MD'``) YADE's linear
    soft-contact list with ``O.dt = md_safety·PWaveTimeStep()`` (then written back to p['dt'])."""
    method = p.get('method', 'CD')
    if method == 'CD':
        O.engines = engines(gravity=(0, 0, -p['g']), en=p['en'], tolerance=p['tolerance'], maxIter=p['max_iter'],
                            relaxation=p.get('relaxation', 1.0), momentum=bool(p.get('momentum', True)),
                            sweepOrder=int(p.get('sweep_order', 1)),
                            warnUnconverged=False)
        O.dt = p['dt']
    elif method == 'MD':
        from .compare import md_engines
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


def cone_state(run_dir, n_grains=14000, slope_deg=22.0, settle=0.1, cell_grains=2000, log=print, **overrides):
    """A large pile state for solver benchmarks, built in minutes instead of by deposition.

    Grains of the protocol's diameter law in a dense random packing (YADE's
    ``pack.randomDensePack``, periodic compression of ``cell_grains`` spheres, tiled) are cut to a cone of
    slope ``slope_deg`` and base radius sized for about ``n_grains`` grains, set on the paving
    (base at z = d_max, just above it) and settled by the CD engine for ``settle`` seconds of
    simulated time. Writes ``run.json`` and ``snap_<t>.npz`` in ``run_dir`` (the format of
    :func:`run`'s snapshots, so ``scripts/bench/solver_bench.py --snapshot`` takes it) and returns
    the snapshot's path.

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
    grains = [(centres[k], radii[k]) for k in kept[np.argsort(centres[kept, 2], kind='stable')]]
    log('cone_state: %d grains in a cone of radius %.2f cm, height %.2f cm (dense packing of %d grains: %.0f s)'
        % (len(grains), 100 * radius, 100 * radius * tan_s, len(radii), time.time() - t0))
    z0 = p['d_max']  # the paving's grains reach z = 2 r ≤ d_max
    p['floor_radius'] = p['floor_radius'] or 1.3 * radius
    p['n_paving'] = build_scene(p)
    mat = O.materials[0]
    for c, r in grains:
        O.bodies.append(utils.sphere((c[0], c[1], c[2] + z0), r, material=mat))
    p.update(n_grains=len(grains), cone_slope_deg=slope_deg, cone_settle_s=settle)
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

    def __init__(self, p, rng, births):
        self.p, self.rng, self.births = p, rng, births
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
        mat = O.materials[0]
        bid = O.bodies.append(utils.sphere((x, y, z), r, material=mat))
        self.births[bid] = O.time
        self.near.append(bid)
        self.count += 1
        return bid


# ----------------------------------------------------------------------------- records

def snapshot(path, births, p):
    """Save what the analyses need at the current time (SI): grains (pos, radius, vel, fixed,
    birth time, ids) and contacts (ids, point, normal, force on body 2 [N])."""
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
    np.savez_compressed(path, time=O.time, g=p['g'], rho=p['rho'], ids=np.array(ids), pos=np.array(pos),
                        radius=np.array(rad), vel=np.array(vel), fixed=np.array(fixed), birth=np.array(birth),
                        c_id1=np.array(c1, dtype=int), c_id2=np.array(c2, dtype=int), c_point=np.array(cp).reshape(-1, 3),
                        c_normal=np.array(cn).reshape(-1, 3), c_force=np.array(cf).reshape(-1, 3))


def save_checkpoint(run_dir, state):
    """Between steps (never from inside O.run), so that a resumed run continues exactly."""
    tmp = os.path.join(run_dir, 'checkpoint.tmp.yade.gz')
    O.save(tmp)
    with open(os.path.join(run_dir, 'checkpoint.json.tmp'), 'w') as f:
        json.dump(state, f)
    os.replace(tmp, os.path.join(run_dir, 'checkpoint.yade.gz'))
    os.replace(os.path.join(run_dir, 'checkpoint.json.tmp'), os.path.join(run_dir, 'checkpoint.json'))


# ----------------------------------------------------------------------------- driver

def snapshot_times(p, t_end):
    if p['epochs']:
        return sorted(float(t) for t in str(p['epochs']).split(',') if t.strip())
    k = max(1, int(round(t_end / p['snap_every'])))
    return [t_end * (i + 1) / k for i in range(k)]


def run(run_dir, resume=False, log=print, **overrides):
    """Build (or resume) a pile in ``run_dir``; returns the run's parameter dict.

    Progress lines give simulated time, grains, contacts, Gauss–Seidel sweeps and residual of
    the last step, the wall-clock rate and the ETA. Snapshots go to ``snap_<t>.npz``."""
    os.makedirs(run_dir, exist_ok=True)
    ck = os.path.join(run_dir, 'checkpoint.json')
    if resume and os.path.exists(ck):
        with open(os.path.join(run_dir, 'run.json')) as f:
            p = json.load(f)
        with open(ck) as f:
            state = json.load(f)
        O.load(os.path.join(run_dir, 'checkpoint.yade.gz'))
        births = {int(k): v for k, v in state['births'].items()}
        rng = np.random.default_rng()
        rng.bit_generator.state = state['rng']
        feeder = Feeder(p, rng, births)
        feeder.count = state['created']
        done_snaps = set(state['snaps'])
        log('resumed %s at t=%.3f s, %d grains' % (run_dir, O.time, feeder.count))
    else:
        p = dict(DEFAULTS)
        p.update({k: v for k, v in overrides.items() if v is not None})
        unknown = set(p) - set(DEFAULTS)
        if unknown:
            raise ValueError('unknown pile parameters: %s' % ', '.join(sorted(unknown)))
        if not (0 < p['d_min'] <= p['d_max']):
            raise ValueError('need 0 < d_min <= d_max (got %g, %g)' % (p['d_min'], p['d_max']))
        if p['n_grains'] < 1 or p['rate'] <= 0 or p['dt'] <= 0:
            raise ValueError('n_grains, rate and dt must be positive')
        if p['method'] not in ('CD', 'MD'):
            raise ValueError("method must be 'CD' or 'MD', not %r" % (p['method'],))
        n_paving = build_scene(p)
        p['n_paving'] = n_paving
        with open(os.path.join(run_dir, 'run.json'), 'w') as f:
            json.dump(p, f, indent=1)
        rng = np.random.default_rng(p['seed'])
        births = {}
        feeder = Feeder(p, rng, births)
        done_snaps = set()
    period = max(1, int(round(1 / (p['rate'] * p['dt']))))  # steps between creations
    t_feed = p['n_grains'] * period * p['dt']
    t_end = t_feed + p['relax']
    snaps = [t for t in snapshot_times(p, t_end) if '%.3f' % t not in done_snaps]
    wall0, sim0 = time.time(), O.time
    last_ck = last_log = time.time()
    progress = open(os.path.join(run_dir, 'progress.csv'), 'a')
    if progress.tell() == 0:
        progress.write('time_s,grains,contacts,sweeps,residual,wall_s\n')

    def state():
        return dict(births={str(k): v for k, v in births.items()}, rng=rng.bit_generator.state,
                    created=feeder.count, snaps=sorted(done_snaps))

    t_stop = min(t_end, overrides.get('stop_time') or (0 if resume else p['stop_time']) or t_end)
    while O.time < t_stop - 0.5 * p['dt']:
        if feeder.count < p['n_grains'] and O.iter % period == 0:
            feeder.create()
        steps = period - O.iter % period
        if snaps:
            steps = min(steps, max(1, int(round((snaps[0] - O.time) / p['dt']))))
        steps = min(steps, max(1, int(round((t_stop - O.time) / p['dt']))))
        O.run(steps, True)
        if snaps and O.time >= snaps[0] - 0.5 * p['dt']:
            tag = '%.3f' % snaps.pop(0)
            snapshot(os.path.join(run_dir, 'snap_%08.3f.npz' % O.time), births, p)
            if p['vtk']:
                from yade import export
                export.VTKExporter(os.path.join(run_dir, 'vtk_%08.3f' % O.time)).exportSpheres(what=dict(vel='b.state.vel'))
            done_snaps.add(tag)
        now = time.time()
        if now - last_log > 10 or O.time >= t_stop - 0.5 * p['dt']:
            rate = (O.time - sim0) / max(now - wall0, 1e-9)
            eta = (t_end - O.time) / rate if rate > 0 else float('inf')
            contacts, sweeps, residual = solver_stats()
            log('t=%7.3f s  grains %6d/%d  contacts %6d  sweeps %4d  residual %.1e  %.3f sim-s/s  ETA %s'
                % (O.time, feeder.count, p['n_grains'], contacts, sweeps, residual, rate,
                   time.strftime('%H:%M:%S', time.gmtime(eta)) if eta < 1e7 else '?'))
            progress.write('%.6f,%d,%d,%d,%.3e,%.1f\n' % (O.time, feeder.count, contacts, sweeps, residual, now - wall0))
            progress.flush()
            last_log = now
        if now - last_ck > p['checkpoint_every']:
            save_checkpoint(run_dir, state())
            last_ck = now
    save_checkpoint(run_dir, state())
    progress.close()
    p['wall_time_s'] = time.time() - wall0
    p['unconverged_steps'] = getattr(O.engines[-1], 'nUnconverged', 0)
    with open(os.path.join(run_dir, 'run.json'), 'w') as f:
        json.dump(p, f, indent=1)
    return p

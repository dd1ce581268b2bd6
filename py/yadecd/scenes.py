"""Scenes defined once, used by the tests, the benchmarks and the scripts alike.

Every builder resets ``O``, creates the bodies, sets ``O.engines`` and ``O.dt`` and returns a
small dict of what the caller needs (ids, parameters). Units are SI.
"""
import math

from yade import O, utils
from yade import Vector3
from yade.wrapper import FrictMat, InteractionLoop

from . import engines, integrator

__all__ = ['material', 'sphere_on_plane', 'dimer', 'dimer_on_plane', 'clump_heap', 'dimer_column', 'column', 'tetrahedron', 'binary_collision',
           'projectile', 'point_on_sphere', 'mass_ratio_stack', 'random_loose_packing', 'fcc_block', 'cradle', 'set_cd']


def material(mu, density=1000.0, label=None):
    """A FrictMat with friction coefficient ``mu`` (frictionAngle = atan(mu)) and ``density``
    [kg/m³]; Young's modulus is irrelevant to CD and left at YADE's default."""
    m = FrictMat(frictionAngle=math.atan(mu), density=density)
    if label:
        m.label = label
    return O.materials.append(m)


def sphere_on_plane(theta, mu, r=0.01, dt=1e-4, density=1000.0):
    """A sphere resting on the horizontal wall z=0 under gravity tilted by ``theta`` in the x–z
    plane: the same as a horizontal-gravity-free sphere on a plane inclined at ``theta``.
    Returns ``{'sphere': id, 'g': 9.81}``."""
    O.reset()
    g = 9.81
    mat = material(mu, density)
    floor = O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
    s = O.bodies.append(utils.sphere((0, 0, r), r, material=mat))
    O.engines = engines(gravity=(g * math.sin(theta), 0, -g * math.cos(theta)), tolerance=1e-12)
    O.dt = dt
    return {'sphere': s, 'floor': floor, 'g': g, 'r': r}


def dimer(centre, axis, r=0.01, spacing=2.2, material=None, fixed=False):
    """Append a clump of two equal spheres of radius ``r``, centres ``spacing``·r apart along the
    unit vector ``axis`` about ``centre`` (apart, not touching, so that YADE computes the clump's
    mass and inertia exactly: m = 2 m_s, I about the axis = 2·(2/5) m_s r²). Returns
    ``(clump id, [member ids])``."""
    a = Vector3(*axis).normalized()
    c = Vector3(*centre)
    half = 0.5 * spacing * r
    kw = {} if material is None else {'material': material}
    members = [utils.sphere(tuple(c + k * half * a), r, **kw) for k in (-1, 1)]
    cid, ids = O.bodies.appendClumped(members)
    if fixed:
        O.bodies[cid].state.blockedDOFs = 'xyzXYZ'
    return cid, list(ids)


def dimer_on_plane(theta, mu, along=True, r=0.01, dt=1e-4, spacing=2.2, density=1000.0, **opts):
    """A :func:`dimer` resting with both spheres on the wall z=0 under gravity tilted by
    ``theta`` in the x–z plane (a plane inclined at ``theta``, downhill +x), its axis along the
    slope (x, ``along``) or across it (y). Returns ``{'clump', 'members', 'floor', 'g', 'r'}``."""
    O.reset()
    g = 9.81
    mat = material(mu, density)
    floor = O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
    cid, ids = dimer((0, 0, r), (1, 0, 0) if along else (0, 1, 0), r, spacing, mat)
    opts.setdefault('tolerance', 1e-12)
    O.engines = engines(gravity=(g * math.sin(theta), 0, -g * math.cos(theta)), **opts)
    O.dt = dt
    return {'clump': cid, 'members': ids, 'floor': floor, 'g': g, 'r': r}


def open_box(box, mat):
    """Walls x, y = 0 and ``box`` and the floor z = 0, of material ``mat``: an open box."""
    for ax in (0, 1):
        O.bodies.append(utils.wall(0, axis=ax, sense=1, material=mat))
        O.bodies.append(utils.wall(box, axis=ax, sense=-1, material=mat))
    O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))


def clump_heap(n_dimers=8, n_spheres=4, r=0.005, box=0.04, mu=0.4, dt=2e-4, seed=1, spacing=2.2, **opts):
    """``n_dimers`` :func:`dimer` clumps (random axes) and ``n_spheres`` spheres of radius ``r``,
    on a grid of cells 1.05·(spacing + 2)·r wide (a dimer in any orientation fits one) above the
    floor of an :func:`open_box` of side ``box``, dropped from rest: a small heap of clumps and
    spheres together.
    Returns ``{'clumps': [...], 'members': [[...], ...], 'spheres': [...]}``."""
    import random
    O.reset()
    rnd = random.Random(seed)
    mat = material(mu)
    open_box(box, mat)
    cell = 1.05 * (spacing + 2) * r
    per_row = max(1, int(box / cell))
    sites = [((k % per_row + 0.5) * cell, (k // per_row % per_row + 0.5) * cell, (k // per_row ** 2 + 0.5) * cell)
             for k in range(n_dimers + n_spheres)]
    rnd.shuffle(sites)
    clumps, members, spheres = [], [], []
    for c in sites[:n_dimers]:
        axis = (rnd.uniform(-1, 1), rnd.uniform(-1, 1), rnd.uniform(-1, 1))
        cid, ids = dimer(c, axis, r, spacing, mat)
        clumps.append(cid)
        members.append(ids)
    for c in sites[n_dimers:]:
        spheres.append(O.bodies.append(utils.sphere(c, r, material=mat)))
    O.engines = engines(gravity=(0, 0, -9.81), **opts)
    O.dt = dt
    return {'clumps': clumps, 'members': members, 'spheres': spheres}


def column(n, r=0.01, mu=0.3, dt=1e-4, gap=0.0, density=1000.0, **opts):
    """``n`` equal spheres stacked on the wall z=0, touching (or ``gap`` apart), at rest.
    Returns ``{'ids': [...], 'm': mass}`` (ids bottom to top)."""
    O.reset()
    mat = material(mu, density)
    O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
    ids = [O.bodies.append(utils.sphere((0, 0, r + k * (2 * r + gap)), r, material=mat)) for k in range(n)]
    O.engines = engines(gravity=(0, 0, -9.81), **opts)
    O.dt = dt
    return {'ids': ids, 'm': O.bodies[ids[0]].state.mass, 'r': r}


def dimer_column(n, r=0.01, mu=0.3, dt=1e-4, spacing=2.2, density=1000.0, **opts):
    """``n`` :func:`dimer` clumps lying along x on the wall z=0, stacked, each resting on the one
    below by both members (2 contacts a level), at rest. Returns ``{'clumps': [...] (bottom to
    top), 'm': a clump's mass, 'r': r}``."""
    O.reset()
    mat = material(mu, density)
    O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
    clumps = [dimer((0, 0, r + 2 * r * k), (1, 0, 0), r, spacing, mat)[0] for k in range(n)]
    O.engines = engines(gravity=(0, 0, -9.81), **opts)
    O.dt = dt
    return {'clumps': clumps, 'm': O.bodies[clumps[0]].state.mass, 'r': r}


def tetrahedron(r=0.01, mu=0.5, dt=1e-4, **opts):
    """Three touching spheres on the wall z=0 and a fourth resting on them (a tetrahedral
    pyramid). Returns ``{'base': [...], 'top': id, 'm': mass}``."""
    O.reset()
    mat = material(mu)
    O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
    d = 2 * r
    base = []
    for k in range(3):
        a = 2 * math.pi * k / 3
        rho = d / math.sqrt(3)  # circumradius of the equilateral triangle of side 2r
        base.append(O.bodies.append(utils.sphere((rho * math.cos(a), rho * math.sin(a), r), r, material=mat)))
    top = O.bodies.append(utils.sphere((0, 0, r + d * math.sqrt(2 / 3)), r, material=mat))
    O.engines = engines(gravity=(0, 0, -9.81), **opts)
    O.dt = dt
    return {'base': base, 'top': top, 'm': O.bodies[top].state.mass}


def binary_collision(v1, v2, r1=0.01, r2=0.015, rho1=1000.0, rho2=3000.0, offset=0.0, mu=0.5,
                     en=0.0, et=0.0, dt=1e-5, gap=0.0, period=None):
    """Two free spheres (no gravity) whose contact normal is x, body 1 on the left, touching
    (``gap`` = 0) or ``gap`` apart; ``offset`` shifts sphere 2 along y (the normal is then
    still set by the centres). Velocities ``v1``, ``v2`` are 3-vectors. With ``period`` [m] the
    scene is a periodic cube of that side, body 1 against its +x face and body 2 one period back
    (x2 − period): they meet across the boundary, body 2 through its image."""
    O.reset()
    m1, m2 = material(mu, rho1), material(mu, rho2)
    x1 = 0.0 if period is None else period - r1
    b1 = O.bodies.append(utils.sphere((x1, 0, 0), r1, material=m1))
    dist = r1 + r2 + gap
    x2 = x1 + math.sqrt(dist ** 2 - offset ** 2) - (0.0 if period is None else period)
    b2 = O.bodies.append(utils.sphere((x2, offset, 0), r2, material=m2))
    if period is not None:
        O.periodic = True
        O.cell.setBox(period, period, period)
    O.bodies[b1].state.vel = Vector3(*v1)
    O.bodies[b2].state.vel = Vector3(*v2)
    O.engines = engines(gravity=(0, 0, 0), en=en, et=et, tolerance=1e-13)
    O.dt = dt
    return {'ids': (b1, b2)}


def projectile(speed, r=0.01, dt=1e-3, start_gap=0.35, gravity=0.0):
    """A sphere flying at ``speed`` along −z towards the wall z=0, starting ``start_gap`` above
    it; with ``speed·dt > r`` it would cross the wall in one step without near-contact
    detection."""
    O.reset()
    mat = material(0.3)
    O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
    s = O.bodies.append(utils.sphere((0, 0, r + start_gap), r, material=mat))
    O.bodies[s].state.vel = Vector3(0, 0, -speed)
    O.engines = engines(gravity=(0, 0, -gravity))
    O.dt = dt
    return {'sphere': s, 'r': r}


def point_on_sphere(R=1.0, r=1e-3, v0=0.2, dt=1e-4):
    """Moreau's §II example: a point-like particle (a sphere of radius r ≪ R) on the outside of a
    fixed frictionless sphere of radius R, starting at the top with horizontal speed ``v0``.
    It follows the wall and leaves it where cos θ = (2 + v0²/(g(R+r)))/3."""
    O.reset()
    mat = material(0.0)
    big = O.bodies.append(utils.sphere((0, 0, 0), R, fixed=True, material=mat))
    p = O.bodies.append(utils.sphere((0, 0, R + r), r, material=mat))
    O.bodies[p].state.vel = Vector3(v0, 0, 0)
    O.engines = engines(gravity=(0, 0, -9.81), tolerance=1e-12)
    O.dt = dt
    return {'wall': big, 'point': p, 'R': R, 'r': r, 'g': 9.81}


def mass_ratio_stack(ratio, r=0.01, dt=1e-4, **opts):
    """A light sphere on the wall z=0 and a sphere ``ratio`` times heavier on top of it."""
    O.reset()
    light = material(0.3, 1000.0)
    heavy = material(0.3, 1000.0 * ratio)
    O.bodies.append(utils.wall(0, axis=2, sense=1, material=light))
    lo = O.bodies.append(utils.sphere((0, 0, r), r, material=light))
    hi = O.bodies.append(utils.sphere((0, 0, 3 * r), r, material=heavy))
    O.engines = engines(gravity=(0, 0, -9.81), **opts)
    O.dt = dt
    return {'light': lo, 'heavy': hi}


def random_loose_packing(n=30, r=0.005, box=0.04, mu=0.4, dt=2e-4, seed=1, **opts):
    """``n`` spheres (radii in [0.8r, 1.2r]) dropped from random non-overlapping positions into a
    box of side ``box`` with walls x, y = 0, box and floor z=0."""
    import random
    O.reset()
    rnd = random.Random(seed)
    mat = material(mu)
    open_box(box, mat)
    placed = []
    z = 1.3 * r
    while len(placed) < n:
        rad = r * rnd.uniform(0.8, 1.2)
        for _ in range(200):
            p = (rnd.uniform(rad, box - rad), rnd.uniform(rad, box - rad), z + rnd.uniform(0, 4 * r))
            if all((p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2 > (rad + s + 1e-4) ** 2 for q, s in placed):
                placed.append((p, rad))
                break
        else:
            z += 2 * r
    ids = [O.bodies.append(utils.sphere(p, s, material=mat)) for p, s in placed]
    O.engines = engines(gravity=(0, 0, -9.81), **opts)
    O.dt = dt
    return {'ids': ids}


def fcc_block(n_target, r=0.005, mu=0.4, dt=2e-4, boxed=False, dimers=False, **opts):
    """A block of about ``n_target`` equal spheres on a face-centred cubic lattice resting on the
    wall z=0, each touching its 12 lattice neighbours (6 contacts per sphere): a dense,
    hyperstatic contact network of any size, built instantly; the benchmark packings. A free
    block is not in equilibrium (its sides spread); ``boxed=True`` adds four walls touching its
    sides, and the block then rests: the floor carries exactly its weight. ``dimers=True`` makes
    the same packing of touching pairs: in each lattice cell the spheres of basis sites 0 and 1,
    and 2 and 3 (2r apart), become one clump (``O.bodies.clump``), so the contacts are the
    sphere block's but for the pairs' own (the benchmark of clump against sphere contacts).
    Returns ``{'ids': [...]}`` (and ``'clumps'`` with dimers)."""
    O.reset()
    mat = material(mu)
    O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
    a = 2 * math.sqrt(2) * r  # cube edge of the FCC cell whose nearest neighbours are 2r apart
    side = max(1, round((n_target / 4) ** (1 / 3)))
    basis = ((0, 0, 0), (0.5, 0.5, 0), (0.5, 0, 0.5), (0, 0.5, 0.5))
    ids = []
    for i in range(side):
        for j in range(side):
            for k in range(side):
                for bx, by, bz in basis:
                    c = (r + a * (i + bx), r + a * (j + by), r + a * (k + bz))
                    ids.append(O.bodies.append(utils.sphere(c, r, material=mat)))
    clumps = [O.bodies.clump(ids[k:k + 2]) for k in range(0, len(ids), 2)] if dimers else None
    if boxed:  # walls through the outermost sphere surfaces: x, y = 0 and 2r + a(side − 1/2)
        for ax in (0, 1):
            O.bodies.append(utils.wall(0, axis=ax, sense=1, material=mat))
            O.bodies.append(utils.wall(2 * r + a * (side - 0.5), axis=ax, sense=-1, material=mat))
    O.engines = engines(gravity=(0, 0, -9.81), **opts)
    O.dt = dt
    return {'ids': ids} if clumps is None else {'ids': ids, 'clumps': clumps}


def cradle(n=5, r=0.01, v=1.0, gap_ratio=0.1, en=1.0, dt=1e-4, density=1000.0, mu=0.3):
    """A Newton's cradle without strings: ``n`` equal spheres in a row along x, ``gap_ratio``·r
    apart, no gravity; the first moves at ``v`` towards the others. With gaps the collisions are
    successive binary ones: for e_n = 1 the last sphere leaves at ``v``, the others stop. The
    impacts are head-on, so friction plays no part; ``mu`` defaults to 0.3 because with μ = 0
    plugin builds before 0c434f6 never converged next to an open gap contact (see
    docs/compare.md)."""
    O.reset()
    mat = material(mu, density)
    step = 2 * r + gap_ratio * r
    ids = [O.bodies.append(utils.sphere((k * step, 0, 0), r, material=mat)) for k in range(n)]
    O.bodies[ids[0]].state.vel = Vector3(v, 0, 0)
    O.engines = engines(gravity=(0, 0, 0), en=en, tolerance=1e-12)
    O.dt = dt
    return {'ids': ids, 'r': r, 'v': v, 'gap': gap_ratio * r}


def set_cd(dt=None, tolerance=None, maxIter=None, en=None, et=None, relaxation=None, momentum=None, **options):
    """Adjust the CD scene just built: time step, solver tolerance and maxIter, over-relaxation
    and momentum (``None``, the default, keeps the engine's own: :func:`yadecd.solver_options`),
    restitution of contacts not yet created, other integrator attributes; unconverged-step
    warnings are silenced (they are counted in ``nUnconverged``, which :func:`run` reports)."""
    if relaxation is not None:
        options['relaxation'] = relaxation
    if momentum is not None:
        options['momentum'] = momentum
    cd = integrator()
    if dt is not None:
        O.dt = dt
    if tolerance is not None:
        cd.tolerance = tolerance
    if maxIter is not None:
        cd.maxIter = int(maxIter)
    cd.warnUnconverged = False
    for k, v in options.items():
        setattr(cd, k, v)
    set_restitution(en, et)
    return cd


def set_restitution(en=None, et=None, contacts=False):
    """Give the scene's CD contact physics functor the restitution coefficients ``en`` and ``et``
    (``None`` keeps one), for the contacts it creates from now on; with ``contacts``, the existing
    contacts too (a saved packing's)."""
    for e in O.engines:
        if isinstance(e, InteractionLoop):
            for f in e.physDispatcher.functors:
                if en is not None:
                    f.en = en
                if et is not None:
                    f.et = et
    if contacts:
        for i in O.interactions:
            if i.isReal:
                if en is not None:
                    i.phys.en = en
                if et is not None:
                    i.phys.et = et

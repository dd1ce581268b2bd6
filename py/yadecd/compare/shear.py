"""Plane shear at controlled normal stress: the μ(I) and φ(I) rheology of frictional spheres, by
Contact Dynamics and by YADE's MD on the same packing (docs/compare.md).

The geometry is da Cruz et al.'s (PRE 72, 021309, 2005), in 3D: a cell periodic in x and y (a
static cell), the grains between two rough walls, each wall one clump of a square monolayer of
spheres of the mean diameter at random heights (±d/4). The bottom wall is fixed; the top wall
moves at the velocity V along x, is free along z under the force −p·A (YADE's ForceEngine), and
can neither turn nor move along y (``blockedDOFs = 'xyXYZ'``, its x velocity prescribed). The
normal stress is thus imposed by a body of the scene, which Contact Dynamics solves implicitly
with the contacts (a periodic cell driven by YADE's PeriTriaxController instead bounces on a rigid
packing: docs/compare.md). Grains: ``n`` spheres of diameters uniform in d̄(1 ± spread),
density ρ, friction μ (grains and walls), no gravity.

Units are SI, chosen so that the inertial time t_i = d̄·sqrt(ρ/p) is 1 ms (d̄ = 1 mm,
ρ = 2500 kg/m³, p = 2500 Pa); rigid grains depend on the inertial number I = γ̇·d̄/sqrt(p/ρ)
only, MD grains also on the stiffness level (E/p, stated with each run).

Measured every sample: the top wall's travel over the gap (the nominal strain), the contact
force on the top wall (τ = F_x/A; F_z/A, which must average to p), the grains' velocity profile
v_x(z), whose straight-line fit over the central half of the gap gives the bulk shear rate γ̇,
and the solid fraction of that central half (the exact volume of the grains' parts inside it).
The steady state is the part after ``skip_strain``: μ = τ/p as the ratio of the means,
I = γ̇·d̄/sqrt(p/ρ) with the mean bulk γ̇, φ; error bars by batch means (:func:`summarise`).
"""
import json
import math
import os
import time

import numpy as np

from yade import O, utils, Vector3
from yade.wrapper import ForceEngine

from .. import engines, integrator
from ..analysis.rheology import PROTOCOL
from ..analysis.stats import batch_means, batch_ratio
from ..io import jsonable, write_json_atomic
from ..scenes import material, set_restitution

__all__ = ['REFERENCE', 'inertial_time', 'packing', 'build', 'run', 'checkpoint_state', 'summarise', 'SAMPLE_FIELDS', 'slab_volume']

#: the reference scales [SI]: mean diameter, grain density, normal stress, friction, size spread
REFERENCE = dict(d=1e-3, rho=2500.0, p=2500.0, mu=0.5, spread=0.2)

#: the columns of a run's time series
SAMPLE_FIELDS = ('step', 'time', 'strain', 'gap', 'fx', 'fz', 'gamma_dot', 'phi', 'mu', 'n_contacts', 'sweeps', 'wall_s')


def inertial_time(d=REFERENCE['d'], rho=REFERENCE['rho'], p=REFERENCE['p']):
    """t_i = d·sqrt(ρ/p) [s]: the time a grain takes to move by d under pressure p."""
    return d * math.sqrt(rho / p)


def slab_volume(z, r, z0, z1):
    """Volume [m³] of the part of each sphere (centre height ``z``, radius ``r``, arrays) between
    the planes z0 < z1, by the cap formula V(h) = π h² (3r − h)/3 of the part of a sphere below a
    plane h above its bottom."""
    z, r = np.asarray(z, dtype=float), np.asarray(r, dtype=float)

    def below(zp):
        h = np.clip(zp - (z - r), 0.0, 2 * r)
        return math.pi * h * h * (3 * r - h) / 3

    return below(z1) - below(z0)


def _wall(z, side, d, rng, mat):
    """One rough wall: a clump of a square monolayer of touching spheres of diameter ``d``
    covering the x–y period ``side``, at heights z ± d/4 at random. Returns (clump id, members)."""
    k = int(round(side / d))
    pitch = side / k
    members = [utils.sphere(((i + 0.5) * pitch, (j + 0.5) * pitch, z + rng.uniform(-0.25, 0.25) * d), 0.5 * d, material=mat)
               for i in range(k) for j in range(k)]
    cid, ids = O.bodies.appendClumped(members)
    return cid, list(ids)


def _parts():
    """The scene's walls and grains: the top wall is the clump free along z (blockedDOFs 'xyXYZ', set by
    :func:`packing`), the bottom wall the other clump, the grains the bodies of no clump."""
    top = [b for b in O.bodies if b.isClump and b.state.blockedDOFs == 'xyXYZ'][0]
    bottom = [b for b in O.bodies if b.isClump and b.id != top.id][0]
    grains = [b for b in O.bodies if not b.isClump and not b.isClumpMember]
    members = {m for m in top.shape.members.keys()}
    return bottom, top, grains, members


def packing(path, n=2000, seed=1, tolerance=1e-3, max_steps=20000, settle_steps=1000, log=print, **ref):
    """A gas of ``n`` grains (YADE's ``makeCloud`` at solid fraction 0.3) between the walls,
    compressed by the top wall under Contact Dynamics: the wall comes down at 0.2·sqrt(p/ρ) until
    the grains push it back with p·A, then is let go under −p·A (V = 0) for ``settle_steps``
    (50 t_i: the packing need not be at rest, its shear transient is discarded). Saved as a YADE archive at ``path`` (``.yade.gz``), from which :func:`build` starts
    the runs of both methods. Returns a dict (side, gap, φ of the central half, steps)."""
    from yade import pack
    r = dict(REFERENCE, **ref)
    d, rho, p = r['d'], r['rho'], r['p']
    rng = np.random.default_rng(seed)
    volume = n * math.pi / 6 * d ** 3 * (1 + r['spread'] ** 2)
    side = d * round(math.sqrt(volume / 0.59 / (18 * d)) / d)          # about 18 d of grains at φ = 0.59
    height = volume / 0.3 / side ** 2
    O.reset()
    O.periodic = True
    O.cell.setBox(side, side, 3 * (height + 6 * d))
    mat = material(r['mu'], rho)
    bottom, _ = _wall(2 * d, side, d, rng, mat)
    top, _ = _wall(2 * d + height + 2.5 * d, side, d, rng, mat)
    sp = pack.SpherePack()
    got = sp.makeCloud((0, 0, 2.75 * d), (side, side, 2.75 * d + height), rMean=d / 2, rRelFuzz=r['spread'], num=n, seed=seed)
    if got != n:
        raise RuntimeError('makeCloud placed %d of %d grains: give the gas more room' % (got, n))
    for c, rad in sp:
        O.bodies.append(utils.sphere(c, rad, material=mat))
    O.bodies[bottom].state.blockedDOFs = 'xyzXYZ'
    O.bodies[top].state.blockedDOFs = 'xyXYZ'
    O.engines = engines(gravity=(0, 0, 0), tolerance=tolerance, maxIter=5000,
                        extra=[ForceEngine(force=(0, 0, -p * side * side), ids=[top], label='press')])
    integrator().warnUnconverged = False
    ti = inertial_time(d, rho, p)
    O.dt = 0.05 * ti
    # the wall comes down at 0.2·sqrt(p/ρ) until the grains push back with p, then is let go under
    # the force (falling freely onto the gas it would strike it at metres per second)
    wall = O.bodies[top].state
    wall.blockedDOFs = 'xyzXYZ'
    wall.vel = Vector3(0, 0, -0.2 * math.sqrt(p / rho))
    steps = 0
    while steps < max_steps:
        O.run(50, True)
        steps += 50
        if measure(O.bodies[bottom], O.bodies[top], [], set(O.bodies[top].shape.members.keys()))['fz'] > p * side * side:
            break
    else:
        raise RuntimeError('the wall came down for %d steps without meeting the grains' % max_steps)
    wall.vel = Vector3(0, 0, 0)
    wall.blockedDOFs = 'xyXYZ'
    O.run(settle_steps, True)         # under −p·A: the sample is sheared from here, its transient discarded
    steps += settle_steps
    z = wall.pos[2] - O.bodies[bottom].state.pos[2]
    ke = sum(0.5 * b.state.mass * b.state.vel.squaredNorm() for b in O.bodies if not b.isClumpMember)
    log('packing: %d steps, gap %.3f mm, kinetic energy %.2e p·V' % (steps, z * 1e3, ke / (p * side * side * z)))
    O.save(path)
    sample = measure(O.bodies[bottom], O.bodies[top], [b for b in O.bodies if not b.isClump and not b.isClumpMember],
                     set(O.bodies[top].shape.members.keys()))
    return dict(side=side, gap=sample['gap'], phi=sample['phi'], steps=steps, n=n, seed=seed, **r)


def _md_engines(young, en, es):
    """YADE's MD engines for the shear: Hertz–Mindlin with normal and tangential restitution ``en``
    and ``es`` (its viscous damping; ``es`` = 1: none in the tangential direction), no global damping
    (:func:`yadecd.compare.md.md_engines`)."""
    from .md import md_engines
    for m in O.materials:
        m.young = young
        m.poisson = 0.25
    return md_engines(gravity=(0, 0, 0), law='hertz', damping=0.0, en=en, es=es)


def build(path, method, I, dgamma=PROTOCOL['cd']['dgamma'], dt_max=PROTOCOL['cd']['dt_max'],
          tolerance=PROTOCOL['cd']['tolerance'], en_cd=PROTOCOL['cd']['en_cd'], young_over_p=PROTOCOL['md']['young_over_p'],
          en_md=PROTOCOL['md']['en_md'], es_md=PROTOCOL['md']['es_md'], safety=PROTOCOL['md']['safety'], **ref):
    """The packing saved at ``path`` (:func:`packing`) sheared at the inertial number ``I`` by
    ``method`` ('cd' or 'md'): the top wall moves at V = γ̇·gap with γ̇ = I·sqrt(p/ρ)/d̄ (the bulk
    rate is measured; wall slip makes it smaller). CD: time step h = min(dgamma/γ̇, dt_max·t_i),
    solver ``tolerance``, normal restitution ``en_cd`` (Moreau's law; 0 by default, given to the
    packing's contacts and to new ones). MD: Young's modulus E = ``young_over_p``·p, restitution
    ``en_md`` and tangential restitution ``es_md`` (YADE's Hertz–Mindlin law adds its tangential
    viscous force to a sticking contact's elastic force without bounding the sum by Coulomb's
    limit; ``es_md`` = 1 removes it), h = ``safety``·PWaveTimeStep. The defaults are the reference protocol
    (:data:`yadecd.analysis.rheology.PROTOCOL`). Returns a dict (gamma_dot, V, dt, ti)."""
    if method not in ('cd', 'md'):
        raise ValueError("method must be 'cd' or 'md', not %r" % (method,))
    if not 0 < safety <= 1:
        raise ValueError('safety is the MD time step over the P-wave step, in (0, 1], not %r' % (safety,))
    if not 0 < I <= 1:
        raise ValueError('the inertial number I must be in (0, 1], not %r' % (I,))
    for name, e in (('en_cd', en_cd), ('en_md', en_md), ('es_md', es_md)):
        if not 0 <= e <= 1:
            raise ValueError('%s is a restitution coefficient, in [0, 1], not %r' % (name, e))
    r = dict(REFERENCE, **ref)
    d, rho, p = r['d'], r['rho'], r['p']
    ti = inertial_time(d, rho, p)
    gamma_dot = I / ti
    O.load(path)
    bottom, top, grains, members = _parts()
    gap = top.state.pos[2] - bottom.state.pos[2]
    V = gamma_dot * gap
    if method == 'md':
        press = [e for e in O.engines if isinstance(e, ForceEngine)]
        O.interactions.clear()       # CD's contacts (CDPhys); the collider makes them again as MD's
        O.engines = _md_engines(young_over_p * p, en_md, es_md)
        O.engines = O.engines[:-1] + press + O.engines[-1:]
        O.dt = safety * utils.PWaveTimeStep()
    else:
        integrator().tolerance = tolerance
        O.dt = min(dgamma / gamma_dot, dt_max * ti)
        set_restitution(en_cd, contacts=True)
    top.state.vel = Vector3(V, 0, 0)
    return dict(gamma_dot=gamma_dot, V=V, dt=O.dt, ti=ti, method=method, I=I, gap0=gap)


def measure(bottom, top, grains, top_members):
    """One sample: gap [m], contact force on the top wall [N], bulk shear rate [1/s] (fit of
    v_x(z) over the central half of the gap), solid fraction of the central half."""
    zb = bottom.state.pos[2]
    gap = top.state.pos[2] - zb
    fx, fz = [], []            # summed exactly (math.fsum): the result does not depend on the container's order,
    n_contacts = 0             # which a scene loaded from an archive does not keep
    for i in O.interactions:
        if not i.isReal:
            continue
        n_contacts += 1
        sign = 1 if i.id2 in top_members else -1 if i.id1 in top_members else 0
        if sign:
            force = i.phys.normalForce + i.phys.shearForce
            fx.append(sign * force[0])
            fz.append(sign * force[2])
    z = np.array([b.state.pos[2] for b in grains])
    vx = np.array([b.state.vel[0] for b in grains])
    rad = np.array([b.shape.radius for b in grains])
    z0, z1 = zb + 0.25 * gap, zb + 0.75 * gap
    mid = (z > z0) & (z < z1)
    slope = np.polyfit(z[mid], vx[mid], 1)[0] if mid.sum() > 2 else float('nan')
    side2 = abs(O.cell.hSize[0, 0] * O.cell.hSize[1, 1])
    phi = float(slab_volume(z, rad, z0, z1).sum() / (side2 * (z1 - z0)))
    return dict(gap=gap, fx=math.fsum(fx), fz=math.fsum(fz), gamma_dot=float(slope), phi=phi, n_contacts=n_contacts)


def checkpoint_state(stem):
    """The bookkeeping of the checkpoint ``<stem>.ckpt.json`` (samples done, the scene's archive,
    the run's settings), or None when there is none."""
    path = stem + '.ckpt.json'
    if not os.path.exists(path):
        return None
    with open(path) as f:
        return json.load(f)


def _save_checkpoint(stem, state):
    """The scene and ``state`` at ``stem``: the archive under a name that carries the sample
    count, then the JSON that points to it (atomically), then the older archive removed, so that
    a crash at any point leaves a JSON whose archive exists and matches it."""
    old = checkpoint_state(stem)
    archive = '%s.ckpt_%06d.yade.gz' % (stem, state['samples'])
    O.save(archive)
    state = dict(state, archive=os.path.basename(archive))
    write_json_atomic(stem + '.ckpt.json', state)
    if old and old.get('archive') and old['archive'] != state['archive']:
        stale = os.path.join(os.path.dirname(os.path.abspath(stem)), old['archive'])
        if os.path.exists(stale):
            os.remove(stale)


def run(path, method, I, strain=3.0, samples_per_strain=100, log=print, on_sample=None, checkpoint=None,
        checkpoint_every=20, done_rows=(), **options):
    """Shear the packing at ``path`` at inertial number ``I`` to the nominal ``strain`` (top wall
    travel over the gap) by ``method``; returns (the run's description dict, the sample rows in
    :data:`SAMPLE_FIELDS` order). ``on_sample(row)`` is called with each row as it is measured.

    With ``checkpoint`` (a path stem), the scene (a YADE archive: the same bits on resume) and the
    run's bookkeeping are saved every ``checkpoint_every`` samples and at the end. When that
    checkpoint exists, the run continues from it instead of starting anew, to ``strain`` (which may
    exceed the strain it was started for: the run is extended); ``done_rows`` are the rows
    measured up to the checkpoint (its ``samples`` first rows: :func:`checkpoint_state`), and the
    method, I and options must be the checkpoint's."""
    state = checkpoint_state(checkpoint) if checkpoint else None
    if state is None:
        info = build(path, method, I, **options)
        bottom, top, grains, members = _parts()
        rows, wall_before = [], 0.0
        info.update(x0=top.state.pos[0], iter0=O.iter)
    else:
        if (state['method'], state['I'], state['options']) != (method, I, jsonable(options)):
            raise ValueError('the checkpoint %s.ckpt.json is of %s at I=%g with %s, not of %s at I=%g with %s' % (
                checkpoint, state['method'], state['I'], state['options'], method, I, jsonable(options)))
        if len(done_rows) < state['samples']:
            raise ValueError('the checkpoint %s.ckpt.json holds %d samples, but %d rows were given' % (
                checkpoint, state['samples'], len(done_rows)))
        O.load(os.path.join(os.path.dirname(os.path.abspath(checkpoint)), state['archive']))
        info, rows, wall_before = dict(state['info']), [tuple(r) for r in done_rows[:state['samples']]], state['wall_s']
        bottom, top, grains, members = _parts()
        log('%s I=%g: resumed at sample %d (strain %.3f) from %s' % (method, I, len(rows), rows[-1][2] if rows else 0.0,
                                                                     state['archive']))
    rate = info['V'] / info['gap0']
    per_sample = max(1, int(round(1.0 / (samples_per_strain * rate * O.dt))))
    n_samples = int(math.ceil(strain / (per_sample * rate * O.dt)))
    area = abs(O.cell.hSize[0, 0] * O.cell.hSize[1, 1])
    cd = integrator() if method == 'cd' else None
    start = time.time()

    def keep(final=False):
        if checkpoint:
            _save_checkpoint(checkpoint, dict(method=method, I=I, options=jsonable(options), info=jsonable(info), samples=len(rows),
                                              wall_s=wall_before + time.time() - start, final=final))

    for k in range(len(rows), n_samples):
        sweeps = 0
        for _ in range(per_sample):
            O.step()
            sweeps += cd.iterations if cd is not None else 0
        m = measure(bottom, top, grains, members)
        strain_now = (top.state.pos[0] - info['x0']) / info['gap0']
        mu = abs(m['fx']) / m['fz'] if m['fz'] > 0 else float('nan')
        rows.append((O.iter, O.time, strain_now, m['gap'], m['fx'] / area, m['fz'] / area, m['gamma_dot'], m['phi'], mu,
                     m['n_contacts'], sweeps / per_sample, wall_before + time.time() - start))
        if on_sample is not None:
            on_sample(rows[-1])
        if (k + 1) % max(1, n_samples // 20) == 0:
            log('%s I=%g: strain %.2f, mu %.3f, phi %.4f, bulk rate %.3g/s (wall %.3g/s), %d contacts, %.0f sweeps/step, %.0f s'
                % (method, I, strain_now, mu, m['phi'], m['gamma_dot'], rate, m['n_contacts'], rows[-1][10], rows[-1][11]))
        if (k + 1) % checkpoint_every == 0 and k + 1 < n_samples:
            keep()
    keep(final=True)
    out = {k: v for k, v in info.items() if k not in ('x0', 'iter0')}
    out.update(per_sample=per_sample, n_samples=n_samples, strain=strain, steps=O.iter - info['iter0'],
               wall_s=wall_before + time.time() - start, n=len(grains), area=area, d=float(options.get('d', REFERENCE['d'])),
               rho=float(options.get('rho', REFERENCE['rho'])), p=float(options.get('p', REFERENCE['p'])))
    return out, rows


def summarise(rows, d, rho, p, skip_strain=1.0, n_batches=10):
    """Steady-state values over the samples after ``skip_strain``, with batch-means errors:
    μ = τ/σ_zz as the ratio of the means of the wall's stresses (:func:`batch_ratio`), the wall's
    normal stress (whose mean must be the imposed p), the bulk shear rate and I = γ̇ d/sqrt(p/ρ),
    φ of the central half."""
    col = {f: i for i, f in enumerate(SAMPLE_FIELDS)}
    steady = [r for r in rows if r[col['strain']] >= skip_strain]
    out = {'samples': len(steady), 'skip_strain': skip_strain}
    mu = batch_ratio([abs(r[col['fx']]) for r in steady], [r[col['fz']] for r in steady], n_batches)
    out['mu'] = mu
    out['normal_stress'] = batch_means([r[col['fz']] for r in steady], n_batches)
    out['gamma_dot'] = batch_means([r[col['gamma_dot']] for r in steady], n_batches)
    scale = d / math.sqrt(p / rho)
    g = out['gamma_dot']
    out['I'] = {'mean': g['mean'] * scale, 'sem': g['sem'] * scale, 'drift_z': g['drift_z']}
    out['phi'] = batch_means([r[col['phi']] for r in steady], n_batches)
    out['sweeps'] = float(np.mean([r[col['sweeps']] for r in steady])) if steady else float('nan')
    return out

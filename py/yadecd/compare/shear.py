"""Periodic simple shear at controlled normal stress: the μ(I) and φ(I) rheology of frictional
spheres, by Contact Dynamics and by YADE's MD on the same packing (docs/compare.md).

The cell holds ``n`` spheres of diameters uniform in d̄(1 ± spread), density ρ, friction μ, no
gravity. The flow is along x, the gradient along z: L = γ̇ e_x ⊗ e_z (``O.cell.velGrad[0, 2]``),
and YADE's own :yref:`PeriTriaxController` (``dynCell``: the cell height obeys
M·d(ε̇_zz)/dt = σ_zz − goal) holds the normal stress σ_zz at −p while the x and y sizes stay
fixed. The cell flips to a compact base as it shears (``Cell.flipFlippable``).

Units are SI, chosen so that the inertial time t_i = d̄·sqrt(ρ/p) is 1 ms (d̄ = 1 mm,
ρ = 2500 kg/m³, p = 2500 Pa); rigid grains depend on the inertial number I = γ̇·d̄/sqrt(p/ρ)
only, MD grains also on the stiffness level (E/p, stated with each run).

Measured every ``sample_every`` steps: the shear strain γ, the stress tensor (contacts, by
``utils.getStress``; kinetic, −(1/V) Σ m v'⊗v' with v' = v − L·x, x the unwrapped position),
the solid fraction φ = Σ V_grain / V_cell. The steady state is the part after ``skip_strain``:
μ = σ_xz/σ_zz of the total stress as the ratio of the means, I from the mean σ_zz, φ; error
bars by batch means (:func:`summarise`).
"""
import math
import time

import numpy as np

from yade import O, utils, Matrix3, Vector3
from yade.wrapper import PeriTriaxController

from .. import engines, integrator
from ..analysis.stats import batch_means, batch_ratio
from ..scenes import material

__all__ = ['REFERENCE', 'inertial_time', 'packing', 'build', 'run', 'summarise', 'SAMPLE_FIELDS']

#: the reference scales [SI]: mean diameter, grain density, normal stress, friction, size spread
REFERENCE = dict(d=1e-3, rho=2500.0, p=2500.0, mu=0.5, spread=0.2)

#: the columns of a run's time series
SAMPLE_FIELDS = ('step', 'time', 'gamma', 'phi', 'sxx', 'syy', 'szz', 'sxz', 'kxx', 'kzz', 'kxz',
                 'mu', 'I', 'n_contacts', 'sweeps', 'wall_s')


def inertial_time(d=REFERENCE['d'], rho=REFERENCE['rho'], p=REFERENCE['p']):
    """t_i = d·sqrt(ρ/p) [s]: the time a grain takes to move by d under pressure p."""
    return d * math.sqrt(rho / p)


def _cell_mass(phi, height, rho):
    """The controller's cell 'mass' M [kg/m] (M·ε̈ = Δσ): a lid of the sample's own mass on a
    column of the cell's height, ρ φ L_z², whose response time to a gap of δ is about
    t_i·sqrt(2 φ (δ/d)(L_z/d)), well below the shear's time per unit strain at I ≤ 0.1."""
    return rho * phi * height ** 2


def _controller(goal, mask, mass, rate):
    return PeriTriaxController(goal=Vector3(*goal), stressMask=mask, dynCell=True, mass=mass,
                               maxStrainRate=Vector3(rate, rate, rate), maxUnbalanced=-1.0,
                               relStressTol=0.0, absStressTol=0.0, label='shearControl')


def solid_fraction():
    return sum(4.0 / 3.0 * math.pi * b.shape.radius ** 3 for b in O.bodies) / O.cell.hSize.determinant()


def packing(n=2000, seed=1, phi0=0.3, tolerance=1e-4, max_steps=40000, log=print, **ref):
    """A random gas of ``n`` spheres (YADE's ``makeCloud``, periodic, at solid fraction ``phi0``)
    compressed isotropically to −p by :yref:`PeriTriaxController` under Contact Dynamics, until
    every normal stress is within 1 % of p and the kinetic energy is below 1e-6 p·V.

    Returns a dict of arrays (``pos`` [m], ``radius`` [m], ``hsize`` [m], ``phi``, the reference
    scales) from which :func:`build` starts both methods' runs."""
    from yade import pack
    r = dict(REFERENCE, **ref)
    d, p, rho = r['d'], r['p'], r['rho']
    ti = inertial_time(d, rho, p)
    mean_vol = math.pi / 6 * d ** 3 * (1 + r['spread'] ** 2)      # E[D³] for D uniform in d(1 ± s)
    side = (n * mean_vol / phi0) ** (1 / 3)
    O.reset()
    O.periodic = True
    O.cell.setBox(side, side, side)
    sp = pack.SpherePack()
    got = sp.makeCloud((0, 0, 0), (side, side, side), rMean=d / 2, rRelFuzz=r['spread'], num=n, periodic=True, seed=seed)
    if got != n:
        raise RuntimeError('makeCloud placed %d of %d spheres at phi0 = %g: lower phi0' % (got, n, phi0))
    mat = material(r['mu'], rho)
    for c, rad in sp:
        O.bodies.append(utils.sphere(c, rad, material=mat))
    ctrl = _controller((-p, -p, -p), 7, _cell_mass(0.6, side, rho), 1.0 / ti)
    O.engines = engines(gravity=(0, 0, 0), extra=[ctrl], tolerance=tolerance, maxIter=5000)
    integrator().warnUnconverged = False
    O.dt = 0.05 * ti
    steps = 0
    while steps < max_steps:
        O.run(200, True)
        steps += 200
        s = utils.getStress()
        ke = sum(0.5 * b.state.mass * b.state.vel.squaredNorm() for b in O.bodies)
        V = O.cell.hSize.determinant()
        ok = all(abs(s[k, k] + p) < 0.01 * p for k in range(3)) and ke < 1e-6 * p * V
        if steps % 2000 == 0 or ok:
            log('packing: step %d, phi %.4f, stress %.1f %.1f %.1f Pa, kinetic %.2e pV'
                % (steps, solid_fraction(), s[0, 0], s[1, 1], s[2, 2], ke / (p * V)))
        if ok:
            break
    else:
        raise RuntimeError('the packing did not settle at p in %d steps' % max_steps)
    bodies = list(O.bodies)
    return dict(pos=np.array([tuple(b.state.pos) for b in bodies]), radius=np.array([b.shape.radius for b in bodies]),
                hsize=np.array(O.cell.hSize), phi=solid_fraction(), n=n, seed=seed, steps=steps,
                **{k: np.array(v) for k, v in r.items()})


def _md_engines(young, en):
    """YADE's MD engines for the shear: Hertz–Mindlin with restitution ``en`` (its viscous
    damping), no global damping (:func:`yadecd.compare.md.md_engines`)."""
    from .md import md_engines
    for m in O.materials:
        m.young = young
        m.poisson = 0.25
    return md_engines(gravity=(0, 0, 0), law='hertz', damping=0.0, en=en)


def build(pack, method, I, dgamma=5e-4, dt_max=0.05, tolerance=1e-4, young_over_p=1e5, en_md=0.1, safety=0.5):
    """The packing ``pack`` (:func:`packing`) sheared at inertial number ``I`` by ``method``
    ('cd' or 'md'). CD: time step h = min(dgamma/γ̇, dt_max·t_i), solver ``tolerance``, e_n = 0.
    MD: Young's modulus E = ``young_over_p``·p, restitution ``en_md``, h = ``safety``·PWaveTimeStep.
    Returns a dict: gamma_dot [1/s], dt [s], the controller."""
    if method not in ('cd', 'md'):
        raise ValueError("method must be 'cd' or 'md', not %r" % (method,))
    if not 0 < I <= 1:
        raise ValueError('the inertial number I must be in (0, 1], not %r' % (I,))
    d, rho, p, mu = (float(pack[k]) for k in ('d', 'rho', 'p', 'mu'))
    ti = inertial_time(d, rho, p)
    gamma_dot = I / ti
    O.reset()
    O.periodic = True
    O.cell.hSize = Matrix3(*np.asarray(pack['hsize']).ravel())
    mat = material(mu, rho)
    for c, rad in zip(pack['pos'], pack['radius']):
        O.bodies.append(utils.sphere(tuple(c), float(rad), material=mat))
    height = float(np.asarray(pack['hsize'])[2, 2])
    ctrl = _controller((0.0, 0.0, -p), 4, _cell_mass(float(pack['phi']), height, rho), 10.0 / ti)
    if method == 'cd':
        O.engines = engines(gravity=(0, 0, 0), extra=[ctrl], tolerance=tolerance, maxIter=5000)
        integrator().warnUnconverged = False
        O.dt = min(dgamma / gamma_dot, dt_max * ti)
    else:
        O.engines = _md_engines(young_over_p * p, en_md)
        O.engines = O.engines[:-1] + [ctrl] + O.engines[-1:]
        O.dt = safety * utils.PWaveTimeStep()
    O.cell.flipFlippable = True
    O.cell.velGrad = Matrix3(0, 0, gamma_dot, 0, 0, 0, 0, 0, 0)
    return dict(gamma_dot=gamma_dot, dt=O.dt, ti=ti, controller=ctrl, method=method, I=I)


def _stress_sample():
    """Contact stress (utils.getStress), kinetic stress of the fluctuations, solid fraction."""
    s = utils.getStress()
    L = O.cell.velGrad
    V = O.cell.hSize.determinant()
    k = np.zeros((3, 3))
    vol = 0.0
    for b in O.bodies:
        v = b.state.vel - L * b.state.pos
        k -= b.state.mass * np.outer(tuple(v), tuple(v))
        vol += 4.0 / 3.0 * math.pi * b.shape.radius ** 3
    return np.array([[s[i, j] for j in range(3)] for i in range(3)]), k / V, vol / V


def run(pack, method, I, strain=3.0, samples_per_strain=100, log=print, on_sample=None, **options):
    """Shear ``pack`` at inertial number ``I`` to the total ``strain`` by ``method``; returns
    (the run's description dict, the list of sample rows in :data:`SAMPLE_FIELDS` order).
    ``on_sample(row)`` is called with each row as it is measured (to write it at once)."""
    info = build(pack, method, I, **options)
    d, rho, p = (float(pack[k]) for k in ('d', 'rho', 'p'))
    per_sample = max(1, int(round(1.0 / (samples_per_strain * info['gamma_dot'] * O.dt))))
    n_samples = int(math.ceil(strain / (per_sample * info['gamma_dot'] * O.dt)))
    cd = integrator() if method == 'cd' else None
    rows, start = [], time.time()
    for k in range(n_samples):
        sweeps = 0
        for _ in range(per_sample):
            O.step()
            sweeps += cd.iterations if cd is not None else 0
        sc, sk, phi = _stress_sample()
        st = sc + sk
        szz, sxz = st[2, 2], st[0, 2]
        mu = abs(sxz) / -szz if szz < 0 else float('nan')
        Im = info['gamma_dot'] * d / math.sqrt(-szz / rho) if szz < 0 else float('nan')
        gamma = O.time * info['gamma_dot']
        rows.append((O.iter, O.time, gamma, phi, st[0, 0], st[1, 1], szz, sxz, sk[0, 0], sk[2, 2], sk[0, 2], mu, Im,
                     len([i for i in O.interactions if i.isReal]), sweeps / per_sample, time.time() - start))
        if on_sample is not None:
            on_sample(rows[-1])
        if (k + 1) % max(1, n_samples // 20) == 0:
            log('%s I=%g: gamma %.2f, mu %.4f, phi %.4f, I %.4g, %d contacts, %.0f sweeps/step, %.0f s'
                % (method, I, gamma, mu, phi, Im, rows[-1][13], rows[-1][14], rows[-1][15]))
    info = {k: v for k, v in info.items() if k != 'controller'}
    info.update(per_sample=per_sample, n_samples=n_samples, strain=strain, steps=O.iter, wall_s=time.time() - start,
                n=len(O.bodies), d=d, rho=rho, p=p)
    return info, rows


def summarise(rows, gamma_dot, d, rho, skip_strain=1.0, n_batches=10):
    """Steady-state values over the samples after ``skip_strain``, with batch-means errors:
    μ = σ_xz/σ_zz as the ratio of the means (:func:`batch_ratio`: the normal stress of a rigid
    packing under a dynamic cell fluctuates strongly, and the mean of per-sample ratios would be
    biased), the normal stress p = −σ_zz, I = γ̇ d/sqrt(p/ρ) from the mean p (its error by the
    delta method), φ, and the kinetic share of σ_zz."""
    col = {f: i for i, f in enumerate(SAMPLE_FIELDS)}
    steady = [r for r in rows if r[col['gamma']] >= skip_strain]
    out = {'samples': len(steady), 'skip_strain': skip_strain}
    mu = batch_ratio([r[col['sxz']] for r in steady], [r[col['szz']] for r in steady], n_batches)
    if mu['mean'] < 0:       # the sign of σ_xz follows the sense of the shear
        mu = dict(mu, mean=-mu['mean'], ci95=(-mu['ci95'][1], -mu['ci95'][0]), drift_z=-mu['drift_z'])
    out['mu'] = mu
    out['p'] = batch_means([-r[col['szz']] for r in steady], n_batches)
    p, sp = out['p']['mean'], out['p']['sem']
    I = gamma_dot * d / math.sqrt(p / rho) if p > 0 else float('nan')
    out['I'] = {'mean': I, 'sem': 0.5 * I * sp / p if p > 0 else float('nan'), 'drift_z': -out['p']['drift_z']}
    out['phi'] = batch_means([r[col['phi']] for r in steady], n_batches)
    out['kinetic_share'] = batch_ratio([r[col['kzz']] for r in steady], [r[col['szz']] for r in steady], n_batches)
    out['sweeps'] = float(np.mean([r[col['sweeps']] for r in steady])) if steady else float('nan')
    return out

"""The comparison's cases: each scene of :mod:`yadecd.scenes` with what to simulate, its exact
solution, how its error is measured and how failures (explosion, tunnelling) are recognised;
used by :func:`yadecd.compare.run` for both methods alike."""
import math

from yade import O
from yade import Vector3

from .. import scenes
from .measure import spheres, overlaps, mechanical_energy, floor_force, all_finite
from ..scenes import set_cd

__all__ = ['Scene', 'SCENES']

G = 9.81


class Scene:
    """One case of a benchmark scene: how to build it, how long to simulate, what to measure.
    Subclasses define ``build()`` (calls a :mod:`yadecd.scenes` builder), ``T`` (simulated
    time), ``sample()`` (called between steps, records what the errors need), ``finish()``
    (returns the error dict, with the main one under ``'error'``), and ``check_failure()``."""
    name = ''
    T = 0.1
    samples = 200        # samples over the run (per-step tracking is set by every_step)
    every_step = False   # sample after every step (cheap scenes whose extremes matter)
    energy = False       # energy drift is meaningful (no dissipation in the exact solution)
    rest = False         # quasi-static: MD may use Cundall damping
    case = ''

    def __init__(self, **kw):
        self.kw = kw
        self.info = None

    def build(self):
        """Build the scene in YADE (a :mod:`yadecd.scenes` builder); each subclass defines it."""
        raise NotImplementedError

    def begin(self, method):
        """Start a run by ``method`` ('CD' or 'MD'): clear the samples and overlap tallies, and take
        the mechanical energy at the start and the reference energy that scales its drift."""
        self.method = method
        self.t_samples, self.wall_samples = [], []
        self.max_overlap = 0.0
        self.sum_overlap, self.n_overlap = 0.0, 0
        self.E0 = mechanical_energy(self.gravity)
        self.E_ref = self.energy_scale()

    def energy_scale(self):
        """Energy against which blow-up is judged [J]."""
        ke = sum(0.5 * b.state.mass * b.state.vel.squaredNorm() for b in spheres() if b.dynamic)
        m = sum(b.state.mass for b in spheres() if b.dynamic)
        r = max(b.shape.radius for b in spheres())
        return ke + m * max(Vector3(self.gravity).norm(), 1e-3) * 2 * r

    def track_overlap(self):
        """The deepest overlap now, over the diameter of the smaller sphere; adds every contact's to
        the mean and keeps the run's largest."""
        worst = 0.0
        for ov, d in overlaps():
            worst = max(worst, ov / d)
            self.sum_overlap += ov / d
            self.n_overlap += 1
        self.max_overlap = max(self.max_overlap, worst)
        return worst

    def sample(self, wall):
        """Called every ``T/samples`` of simulated time (outside the timed steps)."""
        self.t_samples.append(O.time)
        self.wall_samples.append(wall)
        return self.max_overlap if self.every_step else self.track_overlap()

    def energy_gain(self):
        """Mechanical energy (kinetic + gravity + elastic) gained since the start, in units of
        the reference energy: > 0 means energy created from nothing."""
        return (mechanical_energy(self.gravity) - self.E0) / self.E_ref

    def failed(self):
        """Checked at every sample: 'explodes', 'tunnels' or None. Energy gained beyond 10× the
        reference energy is an explosion. A crossing (wall or another sphere passed, or an
        overlap deeper than a diameter) is 'tunnels', unless energy was also created (gain
        above 1×: the integration is unstable, 'explodes'); a soft column crushing under its
        weight releases energy and is 'tunnels'."""
        if not all_finite():
            return 'explodes'
        gain = self.energy_gain()
        if not gain <= 10:
            return 'explodes'
        if self.max_overlap > 1.0 or self.check_failure():
            return 'explodes' if gain > 1 else 'tunnels'
        return None

    def check_failure(self):
        """A scene's own failure test (a sphere past a wall, a stack crossed): True when it failed.
        None here: scenes without one rely on :meth:`failed`'s energy and overlap tests."""
        return None

    def finish(self):
        """The run's errors against the exact solution: a dict with the main one under ``'error'``;
        each subclass defines it."""
        raise NotImplementedError

    @property
    def gravity(self):
        """The gravity vector the scene was built with (for the potential energy)."""
        return self._gravity


class Incline(Scene):
    """``scenes.sphere_on_plane``: θ = 30°; μ = 0.5 rolls (a = 5/7 g sinθ), μ = 0.1 slips
    (a = g(sinθ − μ cosθ)). Errors at T = 0.2 s: velocity |v − aT| / (aT), position
    |x − (aT²/2, r)| / d; main error = the larger."""
    name = 'incline'
    T = 0.2

    def build(self):
        self.regime = self.kw.get('regime', 'rolling')
        mu = 0.5 if self.regime == 'rolling' else 0.1
        self.theta = math.radians(30)
        self.case = self.regime
        self.energy = self.regime == 'rolling'
        self.info = scenes.sphere_on_plane(self.theta, mu)
        self._gravity = (G * math.sin(self.theta), 0, -G * math.cos(self.theta))
        self.a = 5 / 7 * G * math.sin(self.theta) if self.regime == 'rolling' else G * (math.sin(self.theta) - mu * math.cos(self.theta))
        self.d = 2 * self.info['r']

    def check_failure(self):
        if O.bodies[self.info['sphere']].state.pos[2] < 0:
            return 'tunnels'

    def finish(self):
        s = O.bodies[self.info['sphere']].state
        t = O.time
        ve = abs(s.vel[0] - self.a * t) / (self.a * t)
        pe = math.hypot(s.pos[0] - 0.5 * self.a * t * t, s.pos[2] - self.info['r']) / self.d
        return {'error': max(ve, pe), 'vel_error': ve, 'pos_error': pe}


class Column(Scene):
    """``scenes.column(n)``: n spheres resting on a wall. Errors: floor force vs n·m·g (largest
    over the last 20 % of the run) and interpenetration; main error = max of the two."""
    name = 'column'
    rest = True

    def build(self):
        self.n = self.kw.get('n', 10)
        self.case = 'N=%d' % self.n
        self.T = self.kw.get('T', {10: 0.5, 40: 0.5}.get(self.n, 1.0))
        self.info = scenes.column(self.n)
        self._gravity = (0, 0, -G)
        self.W = self.n * self.info['m'] * G
        self.d = 2 * self.info['r']
        self.force_err, self.window_overlap = [], []

    def sample(self, wall):
        self.window_overlap.append(Scene.sample(self, wall))
        self.force_err.append(abs(floor_force(0) / self.W - 1))

    def check_failure(self):
        z = [O.bodies[i].state.pos[2] for i in self.info['ids']]
        if z[0] < 0 or any(b <= a for a, b in zip(z, z[1:])):
            return 'tunnels'

    def finish(self):
        k0 = int(0.8 * len(self.t_samples))
        fe = max(self.force_err[k0:]) if self.force_err[k0:] else float('nan')
        ov = max(self.window_overlap[k0:]) if self.window_overlap[k0:] else float('nan')
        out = {'error': max(fe, ov), 'force_error': fe, 'overlap_final_rel': ov}
        for eps in (1e-2, 1e-3):
            # settled: the last sample above eps, then below until the end
            bad = [k for k, e in enumerate(self.force_err) if not e < eps]
            if not bad:
                k = 0
            elif bad[-1] + 1 < len(self.force_err):
                k = bad[-1] + 1
            else:
                k = None
            out['t_settle_%g' % eps] = self.t_samples[k] if k is not None else float('nan')
            out['wall_settle_%g' % eps] = self.wall_samples[k] if k is not None else float('nan')
        return out


class DimerColumn(Column):
    """``scenes.dimer_column(n)``: n dimer clumps lying along x, stacked, each on the one below
    by both members, on a wall. Errors as for the column: floor force vs n·m_clump·g and
    interpenetration; T = 0.5 s."""
    name = 'dimer_column'

    def build(self):
        self.n = self.kw.get('n', 10)
        self.case = 'N=%d' % self.n
        self.T = self.kw.get('T', 0.5)
        self.info = scenes.dimer_column(self.n)
        self._gravity = (0, 0, -G)
        self.W = self.n * self.info['m'] * G
        self.d = 2 * self.info['r']
        self.force_err, self.window_overlap = [], []

    def check_failure(self):
        z = [O.bodies[i].state.pos[2] for i in self.info['clumps']]
        if z[0] < 0 or any(b <= a for a, b in zip(z, z[1:])):
            return 'tunnels'


class MassRatio(Column):
    """``scenes.mass_ratio_stack(ratio)``: a sphere ``ratio`` times heavier on a light one on a
    wall. Errors as for the column, floor force vs (1 + ratio)·m·g; T = 1 s."""
    name = 'mass_ratio'

    def build(self):
        self.ratio = self.kw.get('ratio', 10)
        self.case = 'ratio=%g' % self.ratio
        self.T = self.kw.get('T', 1.0)
        self.info = scenes.mass_ratio_stack(self.ratio)
        self.info['ids'] = [self.info['light'], self.info['heavy']]
        self._gravity = (0, 0, -G)
        m = O.bodies[self.info['light']].state.mass
        self.W = (1 + self.ratio) * m * G
        self.d = 2 * O.bodies[self.info['light']].shape.radius
        self.force_err, self.window_overlap = [], []


class Binary(Scene):
    """``scenes.binary_collision``: head-on, v1 = 1, v2 = −0.5 m/s, radii 10/15 mm, densities
    1000/3000, 2 mm apart, no gravity. Exact: v1' = v1 − (1+e) m2/(m1+m2)(v1−v2),
    v2' = v2 + (1+e) m1/(m1+m2)(v1−v2), impact at t_c = gap/(v1 − v2). Errors at T = 20 ms:
    velocity max |v' − v'exact| / |v1 − v2|, position max |x − x_exact| / d (d: the smaller
    diameter); main error = the larger."""
    name = 'binary'
    T = 0.02
    every_step = True

    def build(self):
        self.en = self.kw.get('en', 1.0)
        self.case = 'e=%g' % self.en
        self.energy = self.en == 1.0
        self.v1, self.v2 = 1.0, -0.5
        self.gap = 2e-3
        self.info = scenes.binary_collision((self.v1, 0, 0), (self.v2, 0, 0), gap=self.gap, en=self.en)
        self.x0 = [O.bodies[i].state.pos[0] for i in self.info['ids']]
        self._gravity = (0, 0, 0)
        b1, b2 = (O.bodies[i] for i in self.info['ids'])
        self.m1, self.m2 = b1.state.mass, b2.state.mass
        self.d = 2 * b1.shape.radius

    def check_failure(self):
        b1, b2 = (O.bodies[i] for i in self.info['ids'])
        if b2.state.pos[0] <= b1.state.pos[0]:
            return 'tunnels'

    def finish(self):
        b1, b2 = (O.bodies[i].state for i in self.info['ids'])
        e, m1, m2, dv = self.en, self.m1, self.m2, self.v1 - self.v2
        x1 = self.v1 - (1 + e) * m2 / (m1 + m2) * dv
        x2 = self.v2 + (1 + e) * m1 / (m1 + m2) * dv
        err = max(abs(b1.vel[0] - x1), abs(b2.vel[0] - x2), b1.vel.norm() - abs(b1.vel[0]),
                  b2.vel.norm() - abs(b2.vel[0])) / abs(dv)
        t, tc = O.time, self.gap / dv
        xe = [self.x0[0] + self.v1 * tc + x1 * (t - tc), self.x0[1] + self.v2 * tc + x2 * (t - tc)]
        pe = max((O.bodies[i].state.pos - Vector3(x, 0, 0)).norm() for i, x in zip(self.info['ids'], xe)) / self.d
        return {'error': max(err, pe), 'vel_error': err, 'pos_error': pe, 'restitution': (b2.vel[0] - b1.vel[0]) / dv}


class Projectile(Scene):
    """``scenes.projectile(speed)``: a sphere at ``speed`` towards a wall 0.35 m away, no
    gravity, elastic (CD: e_n = 1; MD linear: e ≈ 1; MD Hertz: en = 1). Exact: it comes back at
    ``speed``, z = r + |0.35 − speed·t|. Errors at T = 0.7 m / speed (back at its start; at
    least one step): velocity |v_z − speed| / speed, position |z − z_exact| / d; main error =
    the larger. Max interpenetration is the other measure."""
    name = 'projectile'
    every_step = True
    energy = True

    def build(self):
        self.speed = self.kw.get('speed', 10.0)
        self.case = 'v=%g' % self.speed
        self.info = scenes.projectile(self.speed)
        set_cd(en=1.0)
        self.T = 0.7 / self.speed
        self._gravity = (0, 0, 0)
        self.d = 2 * self.info['r']

    def energy_scale(self):
        return 0.5 * O.bodies[self.info['sphere']].state.mass * self.speed ** 2

    def check_failure(self):
        if O.bodies[self.info['sphere']].state.pos[2] < 0:
            return 'tunnels'

    def finish(self):
        s = O.bodies[self.info['sphere']].state
        err = abs(s.vel[2] - self.speed) / self.speed
        pe = abs(s.pos[2] - (self.info['r'] + abs(0.35 - self.speed * O.time))) / self.d
        return {'error': max(err, pe), 'vel_error': err, 'pos_error': pe, 'restitution': s.vel[2] / self.speed}


class Cradle(Scene):
    """:func:`cradle`: 5 spheres 1 mm apart, the first at 1 m/s, e_n = 1, head-on: the last
    leaves at 1 m/s, the others stop, each having moved by one gap g (sphere k starts at
    t_k = k·g/v). Errors at T = 30 ms: velocity max_i |v_i − v_i,exact| / v, position
    max_i |x_i − x_i,exact| / d; main error = the larger."""
    name = 'cradle'
    T = 0.03
    every_step = True
    energy = True

    def build(self):
        self.n = self.kw.get('n', 5)
        self.case = 'n=%d' % self.n
        self.info = scenes.cradle(self.n)
        self.x0 = [O.bodies[i].state.pos[0] for i in self.info['ids']]
        self._gravity = (0, 0, 0)
        self.d = 2 * self.info['r']

    def check_failure(self):
        x = [O.bodies[i].state.pos[0] for i in self.info['ids']]
        if any(b <= a for a, b in zip(x, x[1:])):
            return 'tunnels'

    def finish(self):
        v, t = self.info['v'], O.time
        exact = [0.0] * (self.n - 1) + [v]
        err = max((O.bodies[i].state.vel - Vector3(x, 0, 0)).norm() for i, x in zip(self.info['ids'], exact)) / v
        g = self.info['gap']
        xe = [x + g for x in self.x0[:-1]] + [self.x0[-1] + v * (t - (self.n - 1) * g / v)]
        pe = max((O.bodies[i].state.pos - Vector3(x, 0, 0)).norm() for i, x in zip(self.info['ids'], xe)) / self.d
        return {'error': max(err, pe), 'vel_error': err, 'pos_error': pe}


SCENES = {c.name: c for c in (Incline, Column, MassRatio, Binary, Projectile, Cradle, DimerColumn)}

"""Physics of the Contact Dynamics integrator against exact and textbook results.

Run inside YADE (``bash tests/run.sh``). Every test states the formula it checks; tolerances
are justified where they are not at round-off level.
"""
from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
import math
import unittest

from yade import O, utils
from yade import Vector3

import yadecd
from yadecd import scenes


def run(n):
    O.run(n, True)


def contact(id1, id2):
    i = O.interactions[id1, id2]
    if not i.isReal:
        raise AssertionError('no contact between #%d and #%d' % (id1, id2))
    return i


class TestIncline(unittest.TestCase):
    """A sphere (I = 2/5 m r²) on a plane inclined at θ with friction μ.

    μ ≥ (2/7)·tanθ: rolls without slipping, a = (5/7)·g·sinθ, ω = v/r.
    μ < (2/7)·tanθ: slips, a = g(sinθ − μ cosθ), angular acceleration 5μg cosθ/(2r).
    The midpoint scheme integrates constant accelerations exactly, so both hold to round-off.
    """
    theta = math.radians(30)
    steps = 200

    def roll(self, mu):
        sc = scenes.sphere_on_plane(self.theta, mu)
        run(self.steps)
        s = O.bodies[sc['sphere']].state
        t = O.time
        return sc, s, t

    def test_rolls_without_slipping(self):
        sc, s, t = self.roll(0.5)
        a = 5 / 7 * sc['g'] * math.sin(self.theta)
        self.assertAlmostEqual(s.vel[0] / (a * t), 1, delta=1e-12, msg='v = (5/7) g sinθ t')
        self.assertAlmostEqual(s.pos[0] / (0.5 * a * t * t), 1, delta=1e-12, msg='x = (5/7) g sinθ t²/2')
        self.assertAlmostEqual(s.angVel[1] * sc['r'] / s.vel[0], 1, delta=1e-12, msg='no slip: ω r = v')
        self.assertLess(abs(s.pos[2] - sc['r']), 1e-15, 'stays on the plane')
        self.assertEqual(O.interactions[sc['floor'], sc['sphere']].phys.status, 1, 'contact sticks')

    def test_slips(self):
        mu = 0.1
        sc, s, t = self.roll(mu)
        g, th, r = sc['g'], self.theta, sc['r']
        a = g * (math.sin(th) - mu * math.cos(th))
        self.assertAlmostEqual(s.vel[0] / (a * t), 1, delta=1e-12, msg='v = g(sinθ − μcosθ) t')
        self.assertAlmostEqual(s.angVel[1] / (5 * mu * g * math.cos(th) / (2 * r) * t), 1, delta=1e-12, msg='ω = 5μg cosθ t/(2r)')
        self.assertEqual(O.interactions[sc['floor'], sc['sphere']].phys.status, 2, 'contact slides')

    def test_threshold(self):
        """Just above μ_c = (2/7) tanθ it rolls, just below it slips: the cone is exact."""
        muc = 2 / 7 * math.tan(self.theta)
        g = 9.81
        for mu, rolls in ((muc * (1 + 1e-6), True), (muc * (1 - 1e-6), False)):
            sc, s, t = self.roll(mu)
            a = 5 / 7 * g * math.sin(self.theta) if rolls else g * (math.sin(self.theta) - mu * math.cos(self.theta))
            self.assertAlmostEqual(s.vel[0] / (a * t), 1, delta=1e-11, msg='mu=%.9f' % mu)
            self.assertEqual(O.interactions[sc['floor'], sc['sphere']].phys.status, 1 if rolls else 2)


class TestCoulombIsotropy(unittest.TestCase):
    """The Coulomb cone is a cone, not a pyramid: no direction of the tangent plane is favoured.
    The pile's slope rests on it (a pyramid would make the angle of repose depend on azimuth)."""
    theta = math.radians(30)

    def tilt(self, phi_deg, theta=None):
        """Gravity g tilted by theta (default 30°) towards azimuth phi: (sinθ cosφ, sinθ sinφ, -cosθ)·g."""
        th, ph = theta if theta is not None else self.theta, math.radians(phi_deg)
        return Vector3(9.81 * math.sin(th) * math.cos(ph), 9.81 * math.sin(th) * math.sin(ph), -9.81 * math.cos(th))

    def test_sphere_threshold_in_every_direction(self):
        """A sphere on a plane tilted towards x, y, the diagonal and 30°: just above μ_c = (2/7)
        tanθ it rolls (v = (5/7) g sinθ t), just below it slips (v = g(sinθ − μ cosθ) t), along
        the tilt direction only (the other horizontal component stays 0), to round-off."""
        muc = 2 / 7 * math.tan(self.theta)
        for phi in (0.0, 90.0, 45.0, 30.0):
            for mu, rolls in ((muc * (1 + 1e-6), True), (muc * (1 - 1e-6), False)):
                sc = scenes.sphere_on_plane(self.theta, mu)
                yadecd.integrator().gravity = self.tilt(phi)
                run(200)
                s = O.bodies[sc['sphere']].state
                a = 5 / 7 * 9.81 * math.sin(self.theta) if rolls else 9.81 * (math.sin(self.theta) - mu * math.cos(self.theta))
                u = (math.cos(math.radians(phi)), math.sin(math.radians(phi)))
                along = s.vel[0] * u[0] + s.vel[1] * u[1]
                across = -s.vel[0] * u[1] + s.vel[1] * u[0]
                msg = 'phi=%g mu=%.9f' % (phi, mu)
                self.assertAlmostEqual(along / (a * O.time), 1, delta=1e-11, msg=msg)
                self.assertLess(abs(across), 1e-12 * abs(along), msg)
                self.assertEqual(O.interactions[sc['floor'], sc['sphere']].phys.status, 1 if rolls else 2, msg)

    def block_displacements(self, phi_deg, theta, steps=200):
        """Tetrahedral block of 4 grains (μ = 0.5) whose grains cannot rotate (a sphere cluster
        free to roll rolls down any tilt, so only sliding can test the cone), rotated by phi
        about z, gravity tilted by theta towards phi. Returns the displacement vectors after
        ``steps`` steps, rotated back by -phi."""
        sc = scenes.tetrahedron(mu=0.5, tolerance=1e-12, maxIter=100000)
        c, s = math.cos(math.radians(phi_deg)), math.sin(math.radians(phi_deg))
        ids = sc['base'] + [sc['top']]
        start = {}
        for i in ids:
            st = O.bodies[i].state
            st.pos = Vector3(c * st.pos[0] - s * st.pos[1], s * st.pos[0] + c * st.pos[1], st.pos[2])
            st.blockedDOFs = 'XYZ'
            start[i] = Vector3(st.pos)
        yadecd.integrator().gravity = self.tilt(phi_deg, theta)
        run(steps)
        out = []
        for i in ids:
            d = O.bodies[i].state.pos - start[i]
            out.append((c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]))
        return out

    def test_block_slides_at_the_same_tilt_in_every_direction(self):
        """The non-rotating block on planes tilted towards x, y, the diagonal and 30°: it holds
        exactly (every displacement below 1e-18 m) at 0.9999 of the friction angle atan 0.5, and
        at 1.0001 of it slides as one body along the tilt, x = g(sinθ − μ cosθ) t²/2 for every
        grain and every direction, to 1e-9 (a pyramidal friction law would hold longer
        diagonally)."""
        theta_c = math.atan(0.5)
        for phi in (0.0, 90.0, 45.0, 30.0):
            held = self.block_displacements(phi, 0.9999 * theta_c)
            self.assertLess(max(max(abs(x) for x in d) for d in held), 1e-18, 'phi %g holds' % phi)
            th = 1.0001 * theta_c
            t = 200 * O.dt
            expect = 9.81 * (math.sin(th) - 0.5 * math.cos(th)) * t * t / 2
            for d in self.block_displacements(phi, th):
                self.assertAlmostEqual(d[0] / expect, 1, delta=1e-9, msg='phi %g slides along the tilt' % phi)
                self.assertLess(abs(d[1]) + abs(d[2]), 1e-9 * expect, 'phi %g: no motion across' % phi)


class TestCurvedWall(unittest.TestCase):
    """Moreau §II: a point-like particle on the outside of a fixed frictionless sphere of radius R,
    starting at the top with speed v0. While in contact |x| = R + r (it never crosses the wall);
    it leaves the wall where the normal force m(g cosθ − v²/(R+r)) vanishes, i.e. with
    v² = v0² + 2g(R+r)(1 − cosθ): cosθ* = (2 + v0²/(g(R+r)))/3."""

    def test_follows_and_leaves(self):
        sc = scenes.point_on_sphere(R=1.0, r=1e-3, v0=0.2, dt=1e-4)
        Rr, g, p = sc['R'] + sc['r'], sc['g'], sc['point']
        theta_last_contact, worst_in, worst_out = None, 0.0, 0.0
        for step in range(40000):
            O.step()
            x = O.bodies[p].state.pos
            d = x.norm() - Rr
            i = O.interactions[sc['wall'], p]
            touching = i.isReal and i.phys.normalForce.norm() > 0
            if touching:
                theta_last_contact = math.acos(x[2] / x.norm())
                worst_out = max(worst_out, d)
            worst_in = min(worst_in, d)
            if theta_last_contact and not touching and d > 1e-4:
                break
        cos_expected = (2 + 0.2 ** 2 / (g * Rr)) / 3
        # first-order in h: the contact is released within a step, where the particle moves
        # v·h ≈ 3e-4 m along the wall, i.e. ~3e-4 rad: 1e-3 is three steps
        self.assertAlmostEqual(math.cos(theta_last_contact), cos_expected, delta=1e-3, msg='detachment angle')
        self.assertGreater(worst_in, -1e-12, 'never crosses the wall')
        # curvature drift over a step: (v h)²/(2R) ≈ 1e-8 m
        self.assertLess(worst_out, 1e-7, 'stays on the wall while in contact')


class TestRest(unittest.TestCase):
    """Equilibrium is exact: bodies at rest under Coulomb friction stay at rest (u_f = 0 when
    u_i = 0), and the normal forces carry the weights above."""

    def test_column(self):
        n = 10
        sc = scenes.column(n, tolerance=1e-12, maxIter=20000)
        ids, m = sc['ids'], sc['m']
        x0 = [Vector3(O.bodies[i].state.pos) for i in ids]
        run(300)
        drift = max((O.bodies[i].state.pos - x).norm() for i, x in zip(ids, x0))
        self.assertLess(drift, 1e-12 * sc['r'], 'column stays at rest')
        below = [0] + ids[:-1]
        for k, (a, b) in enumerate(zip(below, ids)):
            fn = contact(a, b).phys.normalForce[2]
            self.assertAlmostEqual(fn / ((n - k) * m * 9.81), 1, delta=1e-9, msg='contact %d carries %d weights' % (k, n - k))
        self.assertLess(utils.unbalancedForce(), 1e-9)

    def test_tetrahedron(self):
        sc = scenes.tetrahedron(tolerance=1e-10, maxIter=20000)
        ids = sc['base'] + [sc['top']]
        x0 = [Vector3(O.bodies[i].state.pos) for i in ids]
        run(500)
        drift = max((O.bodies[i].state.pos - x).norm() for i, x in zip(ids, x0))
        self.assertLess(drift, 1e-12 * 0.01, 'pyramid stays at rest')
        floor = sum(contact(0, b).phys.normalForce[2] for b in sc['base'])
        self.assertAlmostEqual(floor / (4 * sc['m'] * 9.81), 1, delta=1e-9, msg='floor carries 4 weights')
        self.assertAlmostEqual(O.forces.f(0)[2] / (-4 * sc['m'] * 9.81), 1, delta=1e-9, msg='O.forces on the floor')
        self.assertLess(utils.unbalancedForce(), 1e-9)


class TestCollisions(unittest.TestCase):
    """Binary collisions of free spheres touching at t=0, against the classical formulas:
    normal: U_N' = −en U_N; tangential, sticking (large μ): U_T' = −et U_T; sliding (small μ):
    tangential impulse μ r_N against U_T; momentum and angular momentum conserved."""

    def collide(self, v1, v2, en, et=0.0, mu=0.5, offset=0.0):
        sc = scenes.binary_collision(v1, v2, en=en, et=et, mu=mu, offset=offset)
        b1, b2 = [O.bodies[i] for i in sc['ids']]
        before = [(Vector3(b.state.vel), Vector3(b.state.angVel), b.state.mass, b.state.inertia[0]) for b in (b1, b2)]
        O.step()
        i = contact(*sc['ids'])
        n = i.geom.normal
        return b1, b2, before, i, n

    def test_head_on(self):
        for en in (0.0, 0.5, 1.0):
            b1, b2, before, i, n = self.collide((1, 0, 0), (-0.5, 0, 0), en)
            (v1, _, m1, _), (v2, _, m2, _) = before
            p = m1 * v1[0] + m2 * v2[0]
            e1 = (p + m2 * en * (v2[0] - v1[0])) / (m1 + m2)
            e2 = (p + m1 * en * (v1[0] - v2[0])) / (m1 + m2)
            self.assertAlmostEqual(b1.state.vel[0], e1, delta=1e-12, msg='en=%g body 1' % en)
            self.assertAlmostEqual(b2.state.vel[0], e2, delta=1e-12, msg='en=%g body 2' % en)
            run(20)  # they separate (or stay together for en=0) with unchanged velocities
            self.assertAlmostEqual(b1.state.vel[0], e1, delta=1e-12)
            self.assertAlmostEqual(b2.state.vel[0], e2, delta=1e-12)

    def relative_contact_velocity(self, b1, b2, c):
        return (b2.state.vel + b2.state.angVel.cross(c - b2.state.pos)) - (b1.state.vel + b1.state.angVel.cross(c - b1.state.pos))

    def test_oblique_sticking(self):
        for en, et in ((0.0, 0.0), (0.8, 0.3), (1.0, 1.0)):
            b1, b2, before, i, n = self.collide((1, 0.3, 0), (-0.2, -0.4, 0.1), en, et, mu=10.0, offset=0.01)
            # branch vectors of the step's frame (at q_m): c − x1 = (r1 − pen/2) n, c − x2 = −(r2 − pen/2) n
            pen = i.geom.penetrationDepth
            c1, c2 = (i.geom.refR1 - pen / 2) * n, -(i.geom.refR2 - pen / 2) * n
            Ui = before[1][0] - before[0][0]  # no initial spin
            Uf = (b2.state.vel + b2.state.angVel.cross(c2)) - (b1.state.vel + b1.state.angVel.cross(c1))
            UiN, UfN = Ui.dot(n), Uf.dot(n)
            self.assertAlmostEqual(UfN, -en * UiN, delta=1e-12, msg='normal restitution en=%g' % en)
            UiT, UfT = Ui - UiN * n, Uf - UfN * n
            self.assertLess((UfT + et * UiT).norm(), 1e-12, 'tangential restitution et=%g' % et)
            m1, m2 = before[0][2], before[1][2]
            dp = (b1.state.vel * m1 + b2.state.vel * m2) - (before[0][0] * m1 + before[1][0] * m2)
            self.assertLess(dp.norm(), 1e-15, 'momentum')

    def test_oblique_sliding(self):
        mu, en = 0.01, 0.5  # |U_T|/W_TT > mu r_N: the contact slides
        b1, b2, before, i, n = self.collide((1, 0.3, 0), (-0.2, -0.4, 0.1), en, 0.0, mu=mu, offset=0.01)
        (v1, _, m1, _), (v2, _, m2, _) = before
        Ui = v2 - v1
        UiN = Ui.dot(n)
        UiT = Ui - UiN * n
        rN = -(1 + en) * UiN * m1 * m2 / (m1 + m2)
        P = rN * n - mu * rN * UiT.normalized()  # impulse on body 2
        self.assertLess((b2.state.vel - (v2 + P / m2)).norm(), 1e-12, 'body 2 velocity')
        self.assertLess((b1.state.vel - (v1 - P / m1)).norm(), 1e-12, 'body 1 velocity')
        self.assertEqual(i.phys.status, 2, 'contact slides')


class TestImpacts(unittest.TestCase):
    """A sphere hitting a wall with speed·h = 10 r: near-contact detection catches it; with
    en = 0 it never crosses the wall, never moves back up, and ends at rest on the wall,
    wherever the impact falls within the step."""

    def check(self, start_gap, gravity=0.0):
        sc = scenes.projectile(100.0, r=0.01, dt=1e-3, start_gap=start_gap, gravity=gravity)
        s, r = O.bodies[sc['sphere']].state, sc['r']
        for step in range(30):
            O.step()
            self.assertGreater(s.pos[2] - r, -1e-9 * r, 'gap=%g step %d: crossed the wall (z=%g)' % (start_gap, step, s.pos[2]))
            self.assertLessEqual(s.vel[2], 1e-12, 'gap=%g step %d: bounced back' % (start_gap, step))
        self.assertLess(abs(s.pos[2] - r), 1e-9 * r, 'gap=%g: rests on the wall' % start_gap)
        self.assertLess(s.vel.norm(), 1e-9, 'gap=%g: at rest' % start_gap)

    def test_impact_anywhere_in_step(self):
        for gap in (0.35, 0.3251, 0.3249, 0.30001, 0.3):
            self.check(gap)

    def test_impact_with_gravity(self):
        self.check(0.3123, gravity=9.81)

    def test_fast_sphere_on_sphere(self):
        """Same with a fixed sphere as target (sphere–sphere near contact)."""
        O.reset()
        mat = scenes.material(0.3)
        t = O.bodies.append(utils.sphere((0, 0, 0), 0.01, fixed=True, material=mat))
        s = O.bodies.append(utils.sphere((0, 0, 0.3573), 0.01, material=mat))
        O.bodies[s].state.vel = Vector3(0, 0, -100)
        O.engines = yadecd.engines(gravity=(0, 0, 0))
        O.dt = 1e-3
        for step in range(20):
            O.step()
            d = (O.bodies[s].state.pos - O.bodies[t].state.pos).norm() - 0.02
            self.assertGreater(d, -1e-11, 'step %d crossed' % step)
            self.assertLessEqual(O.bodies[s].state.vel[2], 1e-12)
        self.assertLess(abs(d), 1e-11)

    def test_restitution_bounce(self):
        """A ball dropped from height H with en = 0.5 rebounds to en²·H (to O(h))."""
        O.reset()
        mat = scenes.material(0.3)
        O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
        r, H = 0.01, 0.1
        s = O.bodies.append(utils.sphere((0, 0, r + H), r, material=mat))
        O.engines = yadecd.engines(gravity=(0, 0, -9.81), en=0.5)
        O.dt = 1e-5
        top, rising = 0.0, False
        for k in range(40000):
            O.step()
            z, vz = O.bodies[s].state.pos[2] - r, O.bodies[s].state.vel[2]
            if vz > 0:
                rising = True
            if rising:
                top = max(top, z)
                if vz < 0:
                    break
        # the impact is resolved one step late at most: relative error ~ v h / H ≈ 1e-3
        self.assertAlmostEqual(top / (0.25 * H), 1, delta=5e-3, msg='rebound height en²H')


class TestMassRatio(unittest.TestCase):
    """A sphere 1000 times heavier resting on a light one on the floor. Gauss–Seidel converges
    slowly (contraction ≈ m_heavy/(m_heavy+m_light) per sweep) but warm starts carry the
    impulses over steps: forces reach the weights, overlaps stay within the position tolerance."""

    def test_heavy_on_light(self):
        sc = scenes.mass_ratio_stack(1000.0, tolerance=1e-6, maxIter=1000, warnUnconverged=False)
        run(400)
        cd = yadecd.integrator()
        lo, hi = O.bodies[sc['light']].state, O.bodies[sc['heavy']].state
        W = (lo.mass + hi.mass) * 9.81
        f_floor = contact(0, sc['light']).phys.normalForce[2]
        print('\n    mass ratio 1000: last step %d sweeps, residual %.2e, unconverged steps %d/400, floor force / weight = %.9f'
              % (cd.iterations, cd.residual, cd.nUnconverged, f_floor / W))
        self.assertAlmostEqual(f_floor / W, 1, delta=1e-4, msg='floor carries both weights')
        # the position correction guarantees overlaps below positionTolerance·r
        tol = cd.positionTolerance * 0.01
        self.assertGreater(lo.pos[2] - 0.01, -tol, 'light sphere overlaps the floor')
        self.assertGreater((hi.pos - lo.pos).norm() - 0.02, -tol, 'spheres overlap')


class TestForcesAndKinematics(unittest.TestCase):
    def test_external_force(self):
        """O.forces (setPermF) enters the free velocity: a free sphere accelerates at F/m + g."""
        O.reset()
        s = O.bodies.append(utils.sphere((0, 0, 0), 0.01))
        O.engines = yadecd.engines(gravity=(0, 0, -9.81))
        O.dt = 1e-4
        F = Vector3(0.002, 0, 0)
        O.forces.setPermF(s, F)
        run(100)
        m = O.bodies[s].state.mass
        self.assertAlmostEqual(O.bodies[s].state.vel[0] / (F[0] / m * O.time), 1, delta=1e-12)
        self.assertAlmostEqual(O.bodies[s].state.vel[2] / (-9.81 * O.time), 1, delta=1e-12)

    def test_moving_wall(self):
        """A fixed wall moving up at constant speed carries a resting sphere with it."""
        sc = scenes.column(1)
        O.bodies[0].state.vel = Vector3(0, 0, 0.05)
        run(100)
        s = O.bodies[sc['ids'][0]].state
        self.assertAlmostEqual(s.vel[2], 0.05, delta=1e-12)
        self.assertAlmostEqual(s.pos[2] - O.bodies[0].state.pos[2], sc['r'], delta=1e-12)

    def test_blocked_dofs(self):
        """blockedDOFs are respected: a sphere with 'z' blocked does not fall."""
        O.reset()
        s = O.bodies.append(utils.sphere((0, 0, 0.1), 0.01))
        O.bodies[s].state.blockedDOFs = 'z'
        O.bodies[s].state.vel = Vector3(0.1, 0, 0)
        O.engines = yadecd.engines(gravity=(0, 0, -9.81))
        O.dt = 1e-4
        run(50)
        self.assertEqual(O.bodies[s].state.pos[2], 0.1)
        self.assertAlmostEqual(O.bodies[s].state.pos[0], 0.1 * O.time, delta=1e-14)


class TestEnergy(unittest.TestCase):
    """O.energy.total() = kinetic + gravWork + contactDissip (+ positionCorrection) is conserved
    to the solver tolerance: the midpoint scheme's energy balance is exact per step."""

    def test_settling_packing(self):
        scenes.random_loose_packing(n=25, tolerance=1e-10, maxIter=5000, warnUnconverged=False)
        O.trackEnergy = True
        run(600)
        e = O.energy
        scale = max(abs(e['gravWork']), 1e-30)
        self.assertGreater(e['contactDissip'], 0, 'contacts dissipate')
        self.assertLess(abs(e.total()) / scale, 1e-6, 'total energy conserved: %s' % dict(e.items()))

    def test_elastic_bounce(self):
        """en = 1: kinetic + potential energy is conserved through an impact."""
        O.reset()
        mat = scenes.material(0.3)
        O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
        s = O.bodies.append(utils.sphere((0, 0, 0.01), 0.01, material=mat))
        O.bodies[s].state.vel = Vector3(0, 0, -1)
        O.engines = yadecd.engines(gravity=(0, 0, -9.81), en=1.0)
        O.dt = 1e-4
        O.trackEnergy = True
        m = O.bodies[s].state.mass
        E0 = 0.5 * m * 1.0 ** 2  # O.energy starts with no work booked: total = E0
        run(100)
        self.assertGreater(O.bodies[s].state.vel[2], 0, 'bounced')
        self.assertLess(abs(O.energy['contactDissip']) / E0, 1e-13, 'no dissipation with en = 1')
        self.assertLess(abs(O.energy.total() - E0) / E0, 1e-13, 'kinetic + gravity work conserved')


class TestSaveLoad(unittest.TestCase):
    """O.save/O.load between steps continues identically, bit for bit."""

    def test_continue_bit_for_bit(self):
        sc = scenes.random_loose_packing(n=20, warnUnconverged=False)
        run(150)
        O.saveTmp('cd-continue')
        run(150)
        a = [tuple(O.bodies[i].state.pos) + tuple(O.bodies[i].state.vel) for i in sc['ids']]
        O.loadTmp('cd-continue')
        run(150)
        b = [tuple(O.bodies[i].state.pos) + tuple(O.bodies[i].state.vel) for i in sc['ids']]
        self.assertEqual(a, b)


if __name__ == '__main__':
    unittest.main()

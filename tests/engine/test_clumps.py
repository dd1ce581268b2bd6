"""Clumps of spheres under Contact Dynamics, against rigid-body mechanics.

A clump is one rigid body for the solver: mass m, principal inertia I (YADE's clump state, in
the clump's frame), contacts of its members acting at lever arms from its centre of mass, members
moved rigidly with it. Every case states its formula; the midpoint scheme integrates constant
accelerations exactly, and a single impact is solved exactly in one step, so the tolerances are
round-off (1e-12 relative) unless said otherwise.

Scenes: :func:`yadecd.scenes.dimer` (two spheres of radius r, centres 2.2 r apart: not touching,
so YADE's clump inertia is exact) and :func:`yadecd.scenes.dimer_on_plane`.
"""
from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
import math
import unittest

import numpy as np
from yade import O, utils, Vector3
from yade.wrapper import Box

import yadecd
from yadecd import scenes

G = 9.81


def run(n):
    O.run(n, True)


def inertia_world(state):
    """The clump's inertia tensor in the global frame, R diag(I) Rᵀ."""
    R = np.array(state.ori.toRotationMatrix())
    return R @ np.diag(list(state.inertia)) @ R.T


class TestDimerInertia(unittest.TestCase):
    """YADE's clump of two apart spheres: m = 2 m_s, I_axis = 2·(2/5) m_s r², I_perp =
    2·(2/5 m_s r² + m_s (s r/2)²), the inputs every exact case below relies on."""

    def test_mass_and_inertia(self):
        sc = scenes.dimer_on_plane(0.0, 0.5, along=True)
        c = O.bodies[sc['clump']].state
        ms = O.bodies[sc['members'][0]].state.mass
        r, half = sc['r'], 1.1 * sc['r']
        self.assertAlmostEqual(c.mass / (2 * ms), 1, delta=1e-12)
        I = inertia_world(c)
        self.assertAlmostEqual(I[0, 0] / (2 * 0.4 * ms * r * r), 1, delta=1e-9)
        self.assertAlmostEqual(I[1, 1] / (2 * (0.4 * ms * r * r + ms * half * half)), 1, delta=1e-9)


class TestDimerOnIncline(unittest.TestCase):
    """A dimer on a plane inclined at θ (gravity tilted, floor z = 0), friction μ.

    Along the slope (axis x): both spheres slide or stick together, no rotation.
      tanθ < μ: at rest. tanθ > μ: a = g(sinθ − μ cosθ), ω = 0 (the normal forces share the
      load so that the friction's moment about the centre of mass is balanced).
    Across the slope (axis y): it rolls like a wheel of radius r about its axis,
      a = g sinθ / (1 + I_axis/(m r²)) = 5/7 g sinθ, ω r = v, as long as μ ≥ (2/7) tanθ.
    """
    steps = 200

    def test_sticks_along_the_slope(self):
        theta = math.radians(20)
        sc = scenes.dimer_on_plane(theta, mu=0.5, along=True)        # tan 20° = 0.36 < 0.5
        run(self.steps)
        c = O.bodies[sc['clump']].state
        self.assertLess(c.vel.norm(), 1e-12)
        self.assertLess(c.angVel.norm(), 1e-10)
        self.assertLess(abs(c.pos[0]), 1e-14)
        # the floor carries the clump's weight, m g (tilted gravity: the whole vector)
        F = sum((O.forces.f(i) for i in sc['members']), Vector3(0, 0, 0))
        self.assertAlmostEqual((F + c.mass * yadecd.integrator().gravity).norm() / (c.mass * G), 0, delta=1e-9)

    def test_slides_along_the_slope(self):
        theta, mu = math.radians(30), 0.2
        sc = scenes.dimer_on_plane(theta, mu=mu, along=True)
        run(self.steps)
        c = O.bodies[sc['clump']].state
        a = G * (math.sin(theta) - mu * math.cos(theta))
        self.assertAlmostEqual(c.vel[0] / (a * O.time), 1, delta=1e-12, msg='v = g(sinθ − μ cosθ) t')
        self.assertAlmostEqual(c.pos[0] / (0.5 * a * O.time ** 2), 1, delta=1e-12)
        self.assertLess(c.angVel.norm(), 1e-9 * c.vel.norm() / sc['r'], 'no rotation')
        for m in sc['members']:        # members move rigidly with it, both on the floor
            self.assertAlmostEqual(O.bodies[m].state.pos[2], sc['r'], delta=1e-14)
            self.assertLess((O.bodies[m].state.vel - c.vel).norm(), 1e-12)
            self.assertEqual(O.interactions[sc['floor'], m].phys.status, 2, 'slides')

    def test_rolls_across_the_slope(self):
        theta, mu = math.radians(30), 0.5                            # μ > (2/7) tan 30° = 0.165
        sc = scenes.dimer_on_plane(theta, mu=mu, along=False)
        c = O.bodies[sc['clump']].state
        Iaxis = inertia_world(c)[1, 1]
        run(self.steps)
        a = G * math.sin(theta) / (1 + Iaxis / (c.mass * sc['r'] ** 2))
        self.assertAlmostEqual(a / (5 / 7 * G * math.sin(theta)), 1, delta=1e-9, msg='I_axis = 2/5 m r²')
        self.assertAlmostEqual(c.vel[0] / (a * O.time), 1, delta=1e-12, msg='v = g sinθ t/(1 + I/(m r²))')
        self.assertAlmostEqual(c.angVel[1] * sc['r'] / c.vel[0], 1, delta=1e-12, msg='rolls: ω r = v')
        self.assertLess(abs(c.angVel[0]) + abs(c.angVel[2]), 1e-9 * abs(c.angVel[1]))
        for m in sc['members']:
            self.assertAlmostEqual(O.bodies[m].state.pos[2], sc['r'], delta=1e-13, msg='stays on the plane')
            self.assertEqual(O.interactions[sc['floor'], m].phys.status, 1, 'sticks')

    def test_energy_is_conserved_while_rolling(self):
        """Rolling without slip dissipates nothing: the engine's energy total stays at its start."""
        scenes.dimer_on_plane(math.radians(30), mu=0.5, along=False)
        O.trackEnergy = True
        run(1)
        e0 = O.energy.total()
        run(self.steps)
        ke = O.energy['kinetic']
        self.assertGreater(ke, 0)
        self.assertLess(abs(O.energy.total() - e0), 1e-9 * ke)


class TestTiltedLanding(unittest.TestCase):
    """A dimer tilted by α in the x–z plane falls at speed v without turning and lands on one
    sphere, inelastically (e_n = 0), without gravity. Rigid-body impulse with lever l (contact
    point minus centre of mass), n = +z, K = (1/m) 1 + [l]×ᵀ I⁻¹ [l]×:
      frictionless: P = −v_N/(1/m + (l×n)·I⁻¹(l×n)) n;
      sticking (μ large): P = −K⁻¹ U_i, U_i = velocity of the contact point (all of it stops);
    then v' = v + P/m, ω' = I⁻¹ (l × P). Moreau's scheme takes the frame and the lever at the
    mid-step configuration q_m = q_i + h/2 v: YADE's wall functor puts the contact point there on
    the wall plane, h/2·|v_N| (the overlap the prediction creates) above the sphere's lowest point. The frictionless impulse does not
    see that (only l × n enters it); the sticking one does, so it is checked with the lever at q_m."""
    r = 0.01

    def land(self, mu, alpha_deg=35.0, v=(0.3, 0.0, -1.0)):
        O.reset()
        mat = scenes.material(mu)
        floor = O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
        a = math.radians(alpha_deg)
        axis = (math.cos(a), 0, math.sin(a))
        half = 1.1 * self.r
        centre = (0, 0, self.r + half * math.sin(a))                 # the lower sphere touches z = 0
        cid, ids = scenes.dimer(centre, axis, self.r, 2.2, mat)
        O.bodies[cid].state.vel = Vector3(*v)
        O.engines = yadecd.engines(gravity=(0, 0, 0), tolerance=1e-14, maxIter=10000)
        O.dt = 1e-5
        c = O.bodies[cid].state
        low = min(ids, key=lambda i: O.bodies[i].state.pos[2])
        lever = np.array(O.bodies[low].state.pos) - np.array(c.pos) + np.array([0, 0, -self.r])
        m, Iinv = c.mass, np.linalg.inv(inertia_world(c))
        v0 = np.array(v)
        centre_m = np.array(c.pos) + 0.5 * O.dt * v0                 # the clump at q_m
        O.step()
        self.cid = cid
        self.lever_m = np.array(O.interactions[floor, low].geom.contactPoint) - centre_m
        return c, m, Iinv, lever, v0, floor, low

    @staticmethod
    def cross_matrix(l):
        return np.array([[0, -l[2], l[1]], [l[2], 0, -l[0]], [-l[1], l[0], 0]])

    def test_frictionless(self):
        c, m, Iinv, l, v0, floor, low = self.land(mu=0.0)
        n = np.array([0, 0, 1.0])
        ln = np.cross(l, n)
        P = -v0.dot(n) / (1 / m + ln.dot(Iinv @ ln)) * n
        np.testing.assert_allclose(np.array(c.vel), v0 + P / m, rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.array(c.angVel), Iinv @ np.cross(l, P), rtol=0, atol=1e-10)
        # the contact point no longer approaches the floor
        u = np.array(c.vel) + np.cross(np.array(c.angVel), l)
        self.assertAlmostEqual(u[2], 0, delta=1e-12)

    def test_sticking(self):
        c, m, Iinv, l, v0, floor, low = self.land(mu=100.0)
        self.assertAlmostEqual(self.lever_m[2] - l[2], 0.5 * O.dt * abs(v0[2]), delta=1e-15)
        l = self.lever_m
        L = self.cross_matrix(l)
        K = np.eye(3) / m + L.T @ Iinv @ L
        P = -np.linalg.solve(K, v0)                                  # ω_i = 0: U_i = v0
        self.assertLess(math.hypot(P[0], P[1]), 100.0 * P[2], 'inside the cone')
        np.testing.assert_allclose(np.array(c.vel), v0 + P / m, rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.array(c.angVel), Iinv @ np.cross(l, P), rtol=0, atol=1e-9)
        u = np.array(c.vel) + np.cross(np.array(c.angVel), l)
        np.testing.assert_allclose(u, 0, atol=1e-12, err_msg='the contact point stops')
        # the impulse is the contact's, on the member that touches and summed on the clump
        np.testing.assert_allclose(np.array(O.forces.f(low)) * O.dt, P, rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.array(O.forces.f(self.cid)) * O.dt, P, rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.array(O.forces.t(self.cid)) * O.dt, np.cross(l, P), rtol=0, atol=1e-14)


class TestStackedClumps(unittest.TestCase):
    """Two dimers crossed on the floor: the upper one, across the lower one, lies in its groove,
    each of its spheres on both lower spheres (centres 2r apart: height r + √(4 − 2·1.1²) r).
    At rest, the floor carries the weight of both, Σ F_floor = (m₁ + m₂) g, and YADE's
    unbalancedForce (which reads the clumps' forces) is 0."""

    def test_at_rest_carrying_the_weight(self):
        O.reset()
        r = 0.01
        mat = scenes.material(0.5)
        floor = O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
        c1, m1 = scenes.dimer((0, 0, r), (1, 0, 0), r, 2.2, mat)
        c2, m2 = scenes.dimer((0, 0, r + math.sqrt(4 - 2 * 1.1 ** 2) * r), (0, 1, 0), r, 2.2, mat)
        O.engines = yadecd.engines(gravity=(0, 0, -G), tolerance=1e-12, maxIter=100000)
        O.dt = 1e-4
        run(50)
        for cid in (c1, c2):
            self.assertLess(O.bodies[cid].state.vel.norm(), 1e-12)
            self.assertLess(O.bodies[cid].state.angVel.norm(), 1e-9)
        weight = (O.bodies[c1].state.mass + O.bodies[c2].state.mass) * G
        self.assertAlmostEqual(-O.forces.f(floor)[2] / weight, 1, delta=1e-9)
        self.assertEqual(len([i for i in O.interactions if i.isReal and i.phys.normalForce.norm() > 0]), 6)
        self.assertLess(utils.unbalancedForce(), 1e-9)


class TestDimerColumn(unittest.TestCase):
    """scenes.dimer_column (the comparison's clump scene): ten dimers stacked along x, each on the
    one below by both members. At rest: every clump still (to 1e-12 m/s), the floor carrying
    exactly the column's weight 10·m·g (to 1e-9), two loaded contacts per level."""

    def test_carries_its_weight(self):
        sc = scenes.dimer_column(10, tolerance=1e-12, maxIter=100000)
        floor = 0
        run(100)
        for cid in sc['clumps']:
            self.assertLess(O.bodies[cid].state.vel.norm(), 1e-12)
        self.assertAlmostEqual(-O.forces.f(floor)[2] / (10 * sc['m'] * G), 1, delta=1e-9)
        self.assertEqual(len([i for i in O.interactions if i.isReal and i.phys.normalForce.norm() > 0]), 20)


class TestFixedAndBlocked(unittest.TestCase):

    def test_sphere_rests_on_a_fixed_clump(self):
        """A fixed clump is an obstacle: a sphere on it stays at rest, its contact force m g."""
        O.reset()
        r = 0.01
        mat = scenes.material(0.5)
        cid, ids = scenes.dimer((0, 0, r), (1, 0, 0), r, 2.2, mat, fixed=True)
        top = O.bodies[ids[1]].state.pos
        s = O.bodies.append(utils.sphere((top[0], 0, top[2] + 2 * r), r, material=mat))
        O.engines = yadecd.engines(gravity=(0, 0, -G), tolerance=1e-12)
        O.dt = 1e-4
        run(50)
        self.assertLess(O.bodies[s].state.vel.norm(), 1e-12)
        self.assertAlmostEqual(O.forces.f(s)[2] / (O.bodies[s].state.mass * G), 1, delta=1e-9)
        self.assertEqual(O.bodies[cid].state.vel.norm(), 0.0)

    def test_blocked_rotation_slides_like_a_block(self):
        """Rotations blocked: across the slope it cannot roll and slides, a = g(sinθ − μ cosθ)."""
        theta, mu = math.radians(30), 0.2
        sc = scenes.dimer_on_plane(theta, mu=mu, along=False)
        O.bodies[sc['clump']].state.blockedDOFs = 'XYZ'
        run(200)
        c = O.bodies[sc['clump']].state
        a = G * (math.sin(theta) - mu * math.cos(theta))
        self.assertAlmostEqual(c.vel[0] / (a * O.time), 1, delta=1e-12)
        self.assertEqual(c.angVel.norm(), 0.0)


class TestBadClumps(unittest.TestCase):
    """What the engine cannot do is refused before anything moves, naming the body."""

    def test_member_that_is_not_a_sphere(self):
        O.reset()
        mat = scenes.material(0.5)
        O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
        cid, ids = O.bodies.appendClumped([utils.sphere((0, 0, 0.02), 0.01, material=mat),
                                           utils.box((0.03, 0, 0.02), (0.01, 0.01, 0.01), material=mat)])
        O.engines = yadecd.engines(gravity=(0, 0, -G))
        O.dt = 1e-4
        box = [i for i in ids if isinstance(O.bodies[i].shape, Box)][0]
        before = [tuple(b.state.pos) for b in O.bodies]
        with self.assertRaises(ValueError) as cm:
            O.step()
        self.assertIn('body #%d' % box, str(cm.exception))
        self.assertIn('clump #%d' % cid, str(cm.exception))
        self.assertIn('spheres only', str(cm.exception))
        self.assertEqual([tuple(b.state.pos) for b in O.bodies], before)

    def test_clump_of_zero_inertia(self):
        sc = scenes.dimer_on_plane(0.0, 0.5)
        O.bodies[sc['clump']].state.inertia = Vector3(0, 0, 0)
        with self.assertRaises(ValueError) as cm:
            O.step()
        self.assertIn('body #%d' % sc['clump'], str(cm.exception))
        self.assertIn('inertia', str(cm.exception))


if __name__ == '__main__':
    unittest.main()

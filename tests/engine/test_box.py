"""Spheres against boxes (``utils.box``, Ig2_Box_Sphere_CDScGeom) under Contact Dynamics, against
exact rigid-body results and the closest-point geometry.

Run inside YADE (``scripts/yade -n -x tests/run_tests.py -k Box``). Every test states the formula
it checks. The midpoint scheme integrates piecewise-constant accelerations exactly when the
changes fall on step boundaries, so those cases hold to round-off; the others say why not.
"""
from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yade import O, utils
import yadecd

import math
import unittest

from yade import Quaternion, Vector3
from yade.wrapper import NewtonIntegrator, Ig2_Box_Sphere_ScGeom

from yadecd import scenes

G = 9.81


def run(n):
    O.run(n, True)


def contact(id1, id2):
    i = O.interactions[id1, id2]
    if not i.isReal:
        raise AssertionError('no contact between #%d and #%d' % (id1, id2))
    return i


def box_scene(mu=0.5, center=(0, 0, -0.05), extents=(0.5, 0.5, 0.05), ori=Quaternion((0, 0, 1), 0), gravity=(0, 0, -G),
              dt=1e-4, en=0.0, fixed=True, **opts):
    """``O`` reset, one box (fixed by default), engines and time step set; returns ``(box id, material id)``."""
    O.reset()
    mat = scenes.material(mu)
    box = O.bodies.append(utils.box(center, extents, orientation=ori, fixed=fixed, material=mat))
    O.engines = yadecd.engines(gravity=gravity, en=en, **opts)
    O.dt = dt
    return box, mat


def closest_point(box, c):
    """The point of the (rotated) box ``box`` closest to ``c``: c in the box's axes, clamped to the
    extents, back to global axes."""
    st, e = O.bodies[box].state, O.bodies[box].shape.extents
    local = st.ori.conjugate() * (c - st.pos)
    clamped = Vector3(*(max(-e[k], min(e[k], local[k])) for k in range(3)))
    return st.pos + st.ori * clamped


class TestBoxRest(unittest.TestCase):
    """Equilibrium on a box is exact: u_i = 0 gives u_f = 0, and the normal impulse carries the weight."""

    def test_sphere_rests_on_box(self):
        """A sphere (r = 1 cm) touching the top of a fixed box (turned by 0.3 rad about z: any
        orientation with a horizontal top) stays where it is: |x − x0| < 1e-12 r after 500 steps,
        u = 0, and the contact force is N = m g (relative 1e-9), on the box −m g (O.forces)."""
        box, mat = box_scene(ori=Quaternion((0, 0, 1), 0.3), tolerance=1e-12)
        r = 0.01
        s = O.bodies.append(utils.sphere((0.1, -0.2, r), r, material=mat))
        x0 = Vector3(O.bodies[s].state.pos)
        run(500)
        st = O.bodies[s].state
        m = st.mass
        self.assertLess((st.pos - x0).norm(), 1e-12 * r, 'stays at rest')
        self.assertLess(st.vel.norm() + st.angVel.norm() * r, 1e-12, 'no velocity')
        i = contact(box, s)
        self.assertEqual(i.id1, box, 'body 1 is the box')
        self.assertLess((i.geom.normal - Vector3(0, 0, 1)).norm(), 1e-14, 'normal from the box to the sphere')
        self.assertAlmostEqual(i.phys.normalForce[2] / (m * G), 1, delta=1e-9, msg='N = m g')
        self.assertAlmostEqual(O.forces.f(box)[2] / (-m * G), 1, delta=1e-9, msg='the box carries the weight')
        self.assertLess(i.phys.shearForce.norm(), 1e-9 * m * G, 'no friction needed')

    def test_dropped_sphere_lands_on_box(self):
        """A sphere released 2 cm above a fixed box (en = 0) lands on it and stays: at rest with the
        gap 0 (within the position tolerance 1e-6 r), never below it. Without a box functor in
        yadecd.engines() it fell through."""
        box, mat = box_scene(tolerance=1e-12)
        r = 0.01
        s = O.bodies.append(utils.sphere((0, 0, r + 0.02), r, material=mat))
        st = O.bodies[s].state
        for step in range(1500):
            O.step()
            self.assertGreater(st.pos[2] - r, -1e-6 * r, 'step %d: below the top face' % step)
        self.assertLess(abs(st.pos[2] - r), 1e-6 * r, 'rests on the top')
        self.assertLess(st.vel.norm(), 1e-12, 'at rest')
        self.assertAlmostEqual(contact(box, s).phys.normalForce[2] / (st.mass * G), 1, delta=1e-9, msg='N = m g')


class TestBoxSlideToRoll(unittest.TestCase):
    """A solid sphere (I = 2/5 m r²) launched without spin at v0 on a horizontal box with friction
    μ. While it slips, friction μ m g decelerates it and spins it up:
    v = v0 − μ g t, ω r = (5/2) μ g t; slip ends when v = ω r, at t* = 2 v0/(7 μ g), with
    v* = (5/7) v0; from then on it rolls at v*, ω r = v*, with no friction force.
    x = v0 t − μ g t²/2 (t ≤ t*), x* + v* (t − t*) after.
    The accelerations are piecewise constant and v0 is chosen so that t* = 400 h exactly (v0 =
    (7/2) μ g t*): the step that ends at t* removes the last slip exactly, so Moreau's midpoint
    scheme is exact (round-off only) at every step."""

    def test_slip_then_roll(self):
        mu, r, h = 0.5, 0.01, 1e-4
        tstar = 400 * h
        v0 = 3.5 * mu * G * tstar
        box, mat = box_scene(mu=mu, dt=h, tolerance=1e-12)
        s = O.bodies.append(utils.sphere((0, 0, r), r, material=mat))
        st = O.bodies[s].state
        st.vel = Vector3(v0, 0, 0)
        vstar = 5 / 7 * v0
        xstar = v0 * tstar - mu * G * tstar ** 2 / 2
        done = 0
        for steps in (100, 200, 399, 400, 401, 600, 1000):
            run(steps - done)
            done = steps
            t = steps * h
            if t <= tstar + h / 2:
                v, wr, x, status = v0 - mu * G * t, 2.5 * mu * G * t, v0 * t - mu * G * t * t / 2, 2
            else:
                v, wr, x, status = vstar, vstar, xstar + vstar * (t - tstar), 1
            msg = 'step %d (t* = step 400)' % steps
            self.assertAlmostEqual(st.vel[0] / v, 1, delta=1e-12, msg=msg + ': v')
            self.assertAlmostEqual(st.angVel[1] * r / wr, 1, delta=1e-12, msg=msg + ': ω r')
            self.assertAlmostEqual(st.pos[0] / x, 1, delta=1e-12, msg=msg + ': x')
            self.assertLess(abs(st.vel[1]) + abs(st.vel[2]) + abs(st.pos[2] - r), 1e-15, msg + ': stays on the top, along x')
            if steps != 400:  # at t* the slip is 0 to round-off: stick or slide are both exact
                self.assertEqual(contact(box, s).phys.status, status, msg + ': slides (2) before t*, sticks (1) after')
        self.assertLess(contact(box, s).phys.shearForce.norm(), 1e-12 * st.mass * G, 'rolling needs no friction')


class TestBoxIncline(unittest.TestCase):
    """A sphere on the top of a box turned by θ = 30° about y (an inclined plane, normal
    n = (sin θ, 0, cos θ), down-slope d = (cos θ, 0, −sin θ)), released at rest.
    - free sphere, μ ≥ (2/7) tan θ: rolls without slipping, a = (5/7) g sin θ, ω r = v;
    - free sphere, μ < (2/7) tan θ: slips, a = g (sin θ − μ cos θ), ω̇ = 5 μ g cos θ/(2 r);
    - sphere whose rotations are blocked (a block): tan θ < μ sticks (at rest, contact force m g
      upwards: N = m g cos θ, T = m g sin θ); tan θ > μ slides at a = g (sin θ − μ cos θ).
    Constant accelerations: the midpoint scheme is exact, to round-off."""
    theta = math.radians(30)
    r = 0.01
    steps = 200

    def release(self, mu, blocked=False):
        th, r = self.theta, self.r
        box, mat = box_scene(mu=mu, center=(0, 0, 0), extents=(1.0, 0.5, 0.05), ori=Quaternion((0, 1, 0), th),
                             tolerance=1e-12)
        n = Vector3(math.sin(th), 0, math.cos(th))
        d = Vector3(math.cos(th), 0, -math.sin(th))
        s = O.bodies.append(utils.sphere((0.05 + r) * n, r, material=mat))
        if blocked:
            O.bodies[s].state.blockedDOFs = 'XYZ'
        run(self.steps)
        st = O.bodies[s].state
        self.assertLess(abs(st.pos.dot(n) - (0.05 + r)), 1e-12 * r, 'stays on the inclined top face')
        self.assertLess(abs(st.vel.dot(n)) + abs(st.vel[1]), 1e-12, 'moves along the slope only')
        return box, s, st, n, d, O.time

    def test_rolls(self):
        mu = 0.5  # (2/7) tan 30° = 0.165
        box, s, st, n, d, t = self.release(mu)
        a = 5 / 7 * G * math.sin(self.theta)
        self.assertAlmostEqual(st.vel.dot(d) / (a * t), 1, delta=1e-12, msg='v = (5/7) g sinθ t')
        self.assertAlmostEqual(st.pos.dot(d) / (a * t * t / 2), 1, delta=1e-12, msg='x = (5/7) g sinθ t²/2')
        self.assertAlmostEqual(st.angVel[1] * self.r / st.vel.dot(d), 1, delta=1e-12, msg='no slip: ω r = v')
        self.assertEqual(contact(box, s).phys.status, 1, 'contact sticks')

    def test_slips(self):
        mu = 0.1
        box, s, st, n, d, t = self.release(mu)
        th = self.theta
        a = G * (math.sin(th) - mu * math.cos(th))
        self.assertAlmostEqual(st.vel.dot(d) / (a * t), 1, delta=1e-12, msg='v = g(sinθ − μcosθ) t')
        self.assertAlmostEqual(st.angVel[1] / (5 * mu * G * math.cos(th) / (2 * self.r) * t), 1, delta=1e-12,
                               msg='ω = 5μg cosθ t/(2r)')
        self.assertEqual(contact(box, s).phys.status, 2, 'contact slides')

    def test_block_sticks_below_friction_angle(self):
        mu = 0.6  # tan 30° = 0.577
        box, s, st, n, d, t = self.release(mu, blocked=True)
        m = st.mass
        self.assertLess((st.pos - (0.05 + self.r) * n).norm(), 1e-12 * self.r, 'stays at rest')
        self.assertLess(st.vel.norm(), 1e-12)
        i = contact(box, s)
        f = i.phys.normalForce + i.phys.shearForce
        self.assertLess((f - Vector3(0, 0, m * G)).norm(), 1e-9 * m * G, 'contact force = m g upwards')
        self.assertAlmostEqual(i.phys.normalForce.norm() / (m * G * math.cos(self.theta)), 1, delta=1e-9, msg='N = m g cosθ')
        self.assertEqual(i.phys.status, 1, 'contact sticks')

    def test_block_slides_above_friction_angle(self):
        mu = 0.55
        box, s, st, n, d, t = self.release(mu, blocked=True)
        a = G * (math.sin(self.theta) - mu * math.cos(self.theta))
        self.assertAlmostEqual(st.vel.dot(d) / (a * t), 1, delta=1e-12, msg='v = g(sinθ − μcosθ) t')
        self.assertAlmostEqual(st.pos.dot(d) / (a * t * t / 2), 1, delta=1e-12, msg='x = g(sinθ − μcosθ) t²/2')
        self.assertEqual(contact(box, s).phys.status, 2, 'contact slides')


class TestBoxRestitution(unittest.TestCase):
    """A sphere hitting the top of a fixed box with normal restitution e_n (engines(en=...)).
    The impact lands within a step (open law, end-of-step gap 0) and is resolved at the next one
    by Moreau's law with the approach velocity U recorded at landing: U' = −e_n U, exactly."""

    def test_rebound_without_gravity(self):
        """No gravity: the sphere approaches at v = 1 m/s from a gap of 123.4 steps' travel (the
        impact falls inside a step); it leaves at e_n v, exactly (1e-12), and keeps that speed."""
        r, v = 0.01, 1.0
        for en in (0.0, 0.3, 0.8, 1.0):
            box, mat = box_scene(gravity=(0, 0, 0), en=en, tolerance=1e-12)
            s = O.bodies.append(utils.sphere((0, 0, r + 0.01234), r, material=mat))
            st = O.bodies[s].state
            st.vel = Vector3(0, 0, -v)
            for step in range(300):
                O.step()
                self.assertGreater(st.pos[2] - r, -1e-9 * r, 'en=%g step %d: below the top' % (en, step))
            self.assertAlmostEqual(st.vel[2], en * v, delta=1e-12, msg='en=%g: rebound speed en·v' % en)
            self.assertLess(abs(st.vel[0]) + abs(st.vel[1]) + st.angVel.norm(), 1e-15, 'en=%g: straight up' % en)

    def test_rebound_under_gravity(self):
        """Under gravity, a sphere dropped from rest at H = 5 cm: the rebound velocity (after the
        impact step) is −e_n times the velocity at the start of the landing step, exactly
        (1e-12 relative), and that is the free-fall speed √(2gH) to within g h (the landing
        step's velocity is taken at its start)."""
        r, H, en, h = 0.01, 0.05, 0.5, 1e-4
        box, mat = box_scene(en=en, dt=h, tolerance=1e-12)
        s = O.bodies.append(utils.sphere((0, 0, r + H), r, material=mat))
        st = O.bodies[s].state
        landing = None
        for step in range(2000):
            v_start = st.vel[2]
            O.step()
            i = O.interactions[box, s] if O.interactions.has(box, s) else None
            if landing is None and i is not None and i.isReal and i.phys.normalForce.norm() > 0:
                landing = v_start
                O.step()
                break
        self.assertIsNotNone(landing, 'the sphere reached the box')
        self.assertAlmostEqual(st.vel[2] / (-en * landing), 1, delta=1e-12, msg='rebound = −en × approach velocity')
        self.assertAlmostEqual(-landing, math.sqrt(2 * G * H), delta=G * h, msg='approach = √(2gH) to within g h')


class TestBoxTunnelling(unittest.TestCase):
    """A sphere flying at 100 m/s (10 radii per step, h = 1 ms) at a box thinner than its radius
    (4 mm thick, r = 1 cm): near-contact detection catches it whatever the gap at the start; with
    e_n = 0 it never crosses the top face, never moves back up and ends at rest on it."""

    def check(self, start_gap, gravity=0.0, ori=Quaternion((0, 0, 1), 0)):
        r = 0.01
        box, mat = box_scene(extents=(0.2, 0.2, 0.002), center=(0, 0, -0.002), ori=ori, gravity=(0, 0, -gravity), dt=1e-3)
        s = O.bodies.append(utils.sphere((0, 0, r + start_gap), r, material=mat))
        st = O.bodies[s].state
        st.vel = Vector3(0, 0, -100.0)
        for step in range(30):
            O.step()
            msg = 'gap=%g step %d' % (start_gap, step)
            self.assertGreater(st.pos[2] - r, -1e-9 * r, msg + ': crossed the top face (z=%g)' % st.pos[2])
            self.assertLessEqual(st.vel[2], 1e-12, msg + ': bounced back')
        self.assertLess(abs(st.pos[2] - r), 1e-9 * r, 'gap=%g: rests on the box' % start_gap)
        self.assertLess(st.vel.norm(), 1e-9, 'gap=%g: at rest' % start_gap)

    def test_fast_sphere_does_not_tunnel(self):
        for gap in (0.35, 0.3251, 0.3249, 0.30001, 0.3):
            self.check(gap)

    def test_fast_sphere_with_gravity_on_turned_box(self):
        self.check(0.3123, gravity=G, ori=Quaternion((0, 0, 1), 0.7))


class TestBoxEdgesAndCorners(unittest.TestCase):
    """The contact geometry is the closest-point geometry of the box: for a sphere of centre c
    and the closest point p of the box, n = (c − p)/|c − p| (a face normal over a face, ⊥ to the
    edge near an edge, along c − corner near a corner), penetration depth r − |c − p|, contact
    point (p + c − r n)/2; body 1 is the box. A contact exists once |c − p| − r is below the
    alert distance (0.05 r at rest), measured to the closest point, not face by face."""

    def test_face_edge_corner_normals(self):
        ori = Quaternion(Vector3(1, 2, 3).normalized(), 0.7)
        box, mat = box_scene(center=(0.1, 0.2, 0.3), extents=(0.05, 0.08, 0.03), ori=ori, gravity=(0, 0, 0),
                             tolerance=1e-12)
        st, e, r = O.bodies[box].state, O.bodies[box].shape.extents, 0.01
        # directions in the box's axes: a face, two edges, a corner (outward from the box)
        cases = {
            'face': (Vector3(0.01, -0.02, e[2]), Vector3(0, 0, 1)),
            'edge': (Vector3(e[0], 0.01, -e[2]), Vector3(1, 0, -1).normalized()),
            'oblique edge': (Vector3(-0.02, -e[1], e[2]), Vector3(0, -0.3, 1).normalized()),
            'corner': (Vector3(-e[0], e[1], e[2]), Vector3(-1, 2, 1).normalized()),
        }
        ids = {}
        for name, (on_box, out) in cases.items():
            for gap, contact_expected in ((0.01 * r, True), (-0.02 * r, True), (0.06 * r, False)):
                c = st.pos + ori * (on_box + (r + gap) * out)
                ids[O.bodies.append(utils.sphere(c, r, material=mat))] = (name, gap, contact_expected)
        O.step()  # no gravity, no velocity: overlapping spheres are pushed out only by the correction
        for s, (name, gap, contact_expected) in ids.items():
            msg = '%s, gap %g r' % (name, gap / r)
            has = O.interactions.has(box, s) and O.interactions[box, s].isReal
            self.assertEqual(has, contact_expected, msg + ': contact iff the closest-point gap < alert distance')
            if not has:
                continue
            i = O.interactions[box, s]
            self.assertEqual(i.id1, box, msg + ': body 1 is the box')
            c = O.bodies[s].state.pos
            p = closest_point(box, c)
            n = (c - p).normalized()
            self.assertLess((i.geom.normal - n).norm(), 1e-14, msg + ': normal (c − p)/|c − p|')
            self.assertAlmostEqual(i.geom.penetrationDepth, r - (c - p).norm(), delta=1e-15, msg=msg + ': depth r − |c − p|')
            self.assertLess((i.geom.contactPoint - (p + c - r * n) / 2).norm(), 1e-15, msg + ': contact point')

    def test_box_is_body_1_whatever_the_ids(self):
        """A box appended after the sphere (ids: sphere 0, box 1): the pair is swapped, body 1 is
        the box and the normal points to the sphere (+z on the top); the sphere rests, N = m g."""
        O.reset()
        mat = scenes.material(0.5)
        r = 0.01
        s = O.bodies.append(utils.sphere((0, 0, r), r, material=mat))
        box = O.bodies.append(utils.box((0, 0, -0.05), (0.5, 0.5, 0.05), fixed=True, material=mat))
        O.engines = yadecd.engines(gravity=(0, 0, -G), tolerance=1e-12)
        O.dt = 1e-4
        run(10)
        i = contact(s, box)
        self.assertEqual((i.id1, i.id2), (box, s))
        self.assertLess((i.geom.normal - Vector3(0, 0, 1)).norm(), 1e-15)
        self.assertAlmostEqual(i.phys.normalForce[2] / (O.bodies[s].state.mass * G), 1, delta=1e-9, msg='N = m g')
        self.assertLess(abs(O.bodies[s].state.pos[2] - r), 1e-12 * r)

    def test_sphere_slides_over_an_edge(self):
        """Moreau's §II problem with the box's edge as the obstacle: a frictionless sphere sliding
        at v0 = 0.1 m/s off the top of a box pivots about the edge (its centre on the circle
        of radius r about it, the normal along c − edge, the closest-point normal at every
        step's mid-point q_m = q_i + h/2 u_i) until the normal force m(g cosθ − v²/r) vanishes,
        v² = v0² + 2 g r (1 − cosθ): cosθ* = (2 + v0²/(g r))/3. The release is found within a
        step, where the normal turns by v h/r = 1e-3 rad: 2e-3 on cosθ*. The centre stays on the
        circle to 2e-6 r (the position tolerance and the curvature drift (v h)²/(2r) = 5e-7 r)."""
        r, v0, h = 0.01, 0.1, 1e-4
        box, mat = box_scene(mu=0.0, dt=h, tolerance=1e-12)
        edge = Vector3(0.5, 0, 0)
        s = O.bodies.append(utils.sphere((0.5 - 0.002, 0, r), r, material=mat))
        st = O.bodies[s].state
        st.vel = Vector3(v0, 0, 0)
        cos_last_contact = None
        for step in range(3000):
            qm = st.pos + h / 2 * st.vel
            O.step()
            i = O.interactions[box, s] if O.interactions.has(box, s) else None
            if i is None or not i.isReal or i.phys.normalForce.norm() == 0:
                if cos_last_contact is not None and st.pos[2] < -r:
                    break
                continue
            n = (qm - closest_point(box, qm)).normalized()
            self.assertLess((i.geom.normal - n).norm(), 1e-13, 'step %d: closest-point normal at q_m' % step)
            if st.pos[0] > edge[0]:
                self.assertLess(abs((st.pos - edge).norm() - r), 2e-6 * r, 'step %d: on the circle about the edge' % step)
            cos_last_contact = i.geom.normal[2]
        self.assertLess(st.angVel.norm() * r, 1e-15, 'frictionless: no spin')
        expected = (2 + v0 ** 2 / (G * r)) / 3
        self.assertLess(cos_last_contact, 0.9, 'the normal turned over the edge')
        self.assertAlmostEqual(cos_last_contact, expected, delta=2e-3, msg='released at cosθ* = (2 + v0²/(g r))/3')


class TestBoxSignedGap(unittest.TestCase):
    """The box functor itself, run by an InteractionLoop followed by a NewtonIntegrator without
    gravity (so nothing moves but what the test moves). A contact exists (sphere just above the top
    of a box 4 mm thick, normal +z); its centre is then put 3 mm below the top face, past the
    mid-plane, as the half-step predictor can do in an impact. YADE's Ig2_Box_Sphere_ScGeom takes
    the nearest face, the bottom one: normal −z, a mirrored contact. Ig2_Box_Sphere_CDScGeom keeps
    the face the previous normal points out of: normal +z, penetration depth r + 3 mm (the signed
    gap −(r + 3 mm))."""

    def scene(self, functor):
        O.reset()
        mat = scenes.material(0.5)
        box = O.bodies.append(utils.box((0, 0, -0.002), (0.2, 0.2, 0.002), fixed=True, material=mat))
        s = O.bodies.append(utils.sphere((0, 0, 0.01 + 0.0001), 0.01, material=mat))
        eng = yadecd.engines(gravity=(0, 0, 0))[:3]
        if functor is not None:
            eng[2].geomDispatcher.functors = [functor]
        O.engines = eng + [NewtonIntegrator(gravity=(0, 0, 0))]
        O.dt = 1e-4
        return box, s

    def test_centre_past_the_mid_plane(self):
        depth = 0.003
        for name, functor, normal, pen in (
                ('Ig2_Box_Sphere_CDScGeom', None, Vector3(0, 0, 1), 0.01 + depth),
                ('YADE Ig2_Box_Sphere_ScGeom', Ig2_Box_Sphere_ScGeom(), Vector3(0, 0, -1), 0.01 + 0.004 - depth)):
            box, s = self.scene(functor)
            # touching the top (YADE's functor needs an overlap to create the contact)
            O.bodies[s].state.pos = Vector3(0, 0, 0.01 if functor is None else 0.0099)
            O.step()
            self.assertLess((contact(box, s).geom.normal - Vector3(0, 0, 1)).norm(), 1e-15, name + ': first contact +z')
            O.bodies[s].state.pos = Vector3(0.001, 0.002, -depth)
            O.step()
            g = contact(box, s).geom
            self.assertLess((g.normal - normal).norm(), 1e-15, name + ': normal %s' % normal)
            self.assertAlmostEqual(g.penetrationDepth, pen, delta=1e-15, msg=name + ': penetration depth')

    def test_new_contact_with_centre_inside_takes_the_nearest_face(self):
        """The limit: a sphere created with its centre inside the box has no previous normal; it gets
        YADE's nearest face (here the bottom one, 1 mm away: normal −z, depth r + 1 mm)."""
        box, s = self.scene(None)
        O.bodies[s].state.pos = Vector3(0, 0, -0.003)
        O.step()
        g = contact(box, s).geom
        self.assertLess((g.normal - Vector3(0, 0, -1)).norm(), 1e-15)
        self.assertAlmostEqual(g.penetrationDepth, 0.011, delta=1e-15)


class TestBoxMoving(unittest.TestCase):
    """A fixed box moved kinematically (``state.vel`` = V, fixed=True) hits a free sphere at rest
    (no gravity, μ = 0): the box's mass is infinite, so the contact law gives the sphere the
    normal velocity V_N (e_n = 0: relative normal velocity 0 after the impact) or 2 V_N (e_n = 1:
    relative normal velocity reversed), and none of the box's tangential velocity (frictionless)."""

    def push(self, en, V=Vector3(0.5, 0, 0.2)):
        r = 0.01
        box, mat = box_scene(mu=0.0, center=(-0.1, 0, 0), extents=(0.05, 0.2, 0.2), gravity=(0, 0, 0), en=en,
                             tolerance=1e-12)
        O.bodies[box].state.vel = V
        s = O.bodies.append(utils.sphere((r, 0, 0), r, material=mat))  # 5 cm from the face x = −0.05
        st = O.bodies[s].state
        for step in range(1500):
            O.step()
            face = O.bodies[box].state.pos[0] + 0.05
            self.assertGreater(st.pos[0] - face - r, -1e-9 * r, 'en=%g step %d: in the box' % (en, step))
        return st, face, r

    def test_inelastic_push(self):
        st, face, r = self.push(0.0)
        self.assertAlmostEqual(st.vel[0], 0.5, delta=1e-12, msg='sphere moves with the box: u_N = V_N')
        self.assertLess(abs(st.vel[1]) + abs(st.vel[2]), 1e-15, 'no tangential velocity from a frictionless box')
        self.assertLess(abs(st.pos[0] - face - r), 1e-9 * r, 'and stays on its face')

    def test_elastic_push(self):
        st, face, r = self.push(1.0)
        self.assertAlmostEqual(st.vel[0], 1.0, delta=1e-12, msg='e_n = 1: u_N = 2 V_N')
        self.assertLess(abs(st.vel[1]) + abs(st.vel[2]), 1e-15)
        self.assertGreater(st.pos[0] - face - r, 0.01, 'and leaves it')


if __name__ == '__main__':
    unittest.main()

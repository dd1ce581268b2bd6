"""Periodic cells under Contact Dynamics, with YADE's conventions (NewtonIntegrator's and Cell's).

- A contact across the boundary is a contact with body 2's image at x₂ + H·cellDist, which
  moves at v₂ + L·H_prev·cellDist (Cell.intrShiftVel); the solve sees exactly that image.
- A velocity gradient set by the user takes effect at the next step, every body's velocity
  jumping by ΔL·x (homoDeform > 0) and, with homoDeform > 1, gaining the convective term h·L·v:
  bodies that move with the mean field keep doing so.
- Walls, facets and boxes have no periodic image: refused, by name.
"""
from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
import math
import unittest

import numpy as np
from yade import O, utils, Vector3, Matrix3
from yade.wrapper import (ForceResetter, InsertionSortCollider, Bo1_Sphere_Aabb, NewtonIntegrator, PyRunner)

import yadecd
from yadecd import scenes


def history(ids, steps):
    """Velocities and positions of ``ids`` after each of ``steps`` steps."""
    out = []
    for _ in range(steps):
        O.step()
        out.append([list(O.bodies[i].state.vel) + list(O.bodies[i].state.pos) for i in ids])
    return np.array(out)


class TestCollisionAcrossTheBoundary(unittest.TestCase):
    """Two spheres meeting across the periodic boundary collide as they do in open space: the
    same velocities at every step (to round-off) and positions one period apart; after the
    impact, the textbook binary collision with restitution e (normal x):
    v₁' = v₁ − (1+e) m₂ (v₁−v₂)/(m₁+m₂), v₂' = v₂ + (1+e) m₁ (v₁−v₂)/(m₁+m₂)."""

    def run_both(self, **kw):
        scenes.binary_collision((1.0, 0, 0), (-0.5, 0, 0), gap=2e-4, **kw)
        open_space = history((0, 1), 60)
        masses = [O.bodies[i].state.mass for i in (0, 1)]
        scenes.binary_collision((1.0, 0, 0), (-0.5, 0, 0), gap=2e-4, period=0.2, **kw)
        periodic = history((0, 1), 60)
        return open_space, periodic, masses

    def test_inelastic_and_elastic(self):
        for e in (0.0, 0.6, 1.0):
            with self.subTest(e=e):
                a, b, (m1, m2) = self.run_both(en=e)
                np.testing.assert_allclose(b[:, :, :3], a[:, :, :3], rtol=0, atol=1e-12)
                shift = np.array([0.2 - 0.01, 0, 0])                      # body 1 sits at period − r1
                np.testing.assert_allclose(b[:, 0, 3:] - shift, a[:, 0, 3:], rtol=0, atol=1e-12)
                np.testing.assert_allclose(b[:, 1, 3:] - shift + [0.2, 0, 0], a[:, 1, 3:], rtol=0, atol=1e-12)
                v1, v2 = 1.0, -0.5
                v1e = v1 - (1 + e) * m2 * (v1 - v2) / (m1 + m2)
                v2e = v2 + (1 + e) * m1 * (v1 - v2) / (m1 + m2)
                self.assertAlmostEqual(b[-1, 0, 0], v1e, delta=1e-12)
                self.assertAlmostEqual(b[-1, 1, 0], v2e, delta=1e-12)

    def test_oblique_with_friction(self):
        a, b, _ = self.run_both(offset=0.008, mu=0.3, en=0.4)
        np.testing.assert_allclose(b[:, :, :3], a[:, :, :3], rtol=0, atol=1e-12)


class TestImageVelocity(unittest.TestCase):
    """Uniaxial compression of the cell along y, L = diag(0, −ε̇, 0), bodies moving with the mean
    field (v = L x after the first step's jump): a sphere near the top face and another near the
    bottom face approach each other through the boundary at ε̇·(y₂ + L_y − y₁), the velocity of
    the image relative to body 1. The step they land in closes the gap (U_N = −2 g_m/h); from
    the next step (closed, inelastic, frictionless) the image's relative normal velocity
    v₂ + L·H_prev·cellDist − v₁ is zero and the momentum of the pair is unchanged (homoDeform 1:
    no convective term). (Later the image, whose velocity L·H shrinks with the cell, draws away
    from body 1, whose velocity no convective term changes: the contact opens, as it should.)"""

    def test_contact_through_the_image_stops_the_approach(self):
        O.reset()
        Ly, r, rate = 0.1, 0.01, 2.0
        mat = scenes.material(0.0)
        b1 = O.bodies.append(utils.sphere((0.05, Ly - r - 1e-4, 0.05), r, material=mat))
        b2 = O.bodies.append(utils.sphere((0.05, r + 1e-4, 0.05), r, material=mat))
        O.periodic = True
        O.cell.setBox(0.1, Ly, 0.1)
        O.cell.homoDeform = 1                      # no convective term: momentum is the impulses'
        O.engines = yadecd.engines(gravity=(0, 0, 0), tolerance=1e-14, maxIter=10000)
        O.dt = 1e-5
        O.cell.velGrad = Matrix3(0, 0, 0, 0, -rate, 0, 0, 0, 0)
        touched, checked = None, False
        for step in range(2000):                  # they meet after about 2e-4 m / (ε̇ · 0.0202 m) = 500 steps
            p_before = sum((O.bodies[i].state.mass * O.bodies[i].state.vel for i in (b1, b2)), Vector3(0, 0, 0))
            O.step()
            i = O.interactions[b1, b2] if O.interactions.has(b1, b2) else None
            if touched is None:
                if i is not None and i.isReal and i.phys.normalForce.norm() > 0:
                    touched = step                # the landing step closes the gap: U_N = −2 g_m/h ≠ 0
                continue
            self.assertTrue(i is not None and i.isReal, 'the contact with the image was lost')
            # from the next step on the contact is closed: no relative normal velocity with the image
            self.assertNotEqual(tuple(i.cellDist), (0, 0, 0))
            shift_vel = O.cell.velGrad * (O.cell.prevHSize * Vector3(*i.cellDist))
            v1, v2 = O.bodies[i.id1].state.vel, O.bodies[i.id2].state.vel
            n = i.geom.normal
            self.assertAlmostEqual(n.dot(v2 + shift_vel - v1), 0, delta=1e-12)
            p_after = sum((O.bodies[j].state.mass * O.bodies[j].state.vel for j in (b1, b2)), Vector3(0, 0, 0))
            self.assertLess((p_after - p_before).norm(), 1e-15)
            self.assertGreater(i.phys.normalForce.norm(), 0, 'the closed contact pushes')
            checked = True
            break
        touched = checked
        self.assertTrue(touched, 'the spheres never met through the boundary')


class TestContactFreeShear(unittest.TestCase):
    """Simple shear, L = γ̇ e_x ⊗ e_y, set at step 0 on spheres at rest far apart: the first
    step's jump gives each v = L x, and then (L² = 0, no convective change) x(t) = x₀ + t·L·x₀.
    NewtonIntegrator does the same: positions and velocities agree to round-off at every step."""

    def build(self, cd):
        O.reset()
        O.periodic = True
        O.cell.setBox(0.2, 0.2, 0.2)
        mat = scenes.material(0.5)
        for x in ((0.03, 0.03, 0.03), (0.13, 0.08, 0.1), (0.07, 0.17, 0.15)):
            O.bodies.append(utils.sphere(x, 0.01, material=mat))
        if cd:
            O.engines = yadecd.engines(gravity=(0, 0, 0))
        else:
            O.engines = [ForceResetter(), InsertionSortCollider([Bo1_Sphere_Aabb()]), NewtonIntegrator(damping=0)]
        O.dt = 1e-4
        O.cell.velGrad = Matrix3(0, 0.5, 0, 0, 0, 0, 0, 0, 0)

    def test_moves_as_under_newton(self):
        out = {}
        for cd in (True, False):
            self.build(cd)
            x0 = [np.array(b.state.pos) for b in O.bodies]
            out[cd] = history(range(3), 300)
            out[cd, 'H'] = np.array(O.cell.hSize)
        np.testing.assert_allclose(out[True], out[False], rtol=0, atol=1e-13)
        np.testing.assert_allclose(out[True, 'H'], out[False, 'H'], rtol=0, atol=1e-15)
        t = 300 * 1e-4
        for k in range(3):            # the exact affine motion: x = x0 + t L x0, v = L x0
            L = np.array([[0, 0.5, 0], [0, 0, 0], [0, 0, 0]])
            np.testing.assert_allclose(out[True][-1, k, 3:], x0[k] + t * L @ x0[k], rtol=0, atol=1e-13)
            np.testing.assert_allclose(out[True][-1, k, :3], L @ x0[k], rtol=0, atol=1e-13)


class TestPeriodicBadInput(unittest.TestCase):

    def test_box_in_a_periodic_cell(self):
        """A box has no periodic image: refused, naming it, before anything moves. (A wall is
        refused earlier by YADE's own collider: its bound spans the cell.)"""
        O.reset()
        O.periodic = True
        O.cell.setBox(0.1, 0.1, 0.1)
        box = O.bodies.append(utils.box((0.05, 0.05, 0.02), (0.01, 0.01, 0.01), fixed=True))
        s = O.bodies.append(utils.sphere((0.05, 0.05, 0.05), 0.01))
        O.engines = yadecd.engines(gravity=(0, 0, -9.81))
        O.dt = 1e-4
        with self.assertRaises(ValueError) as cm:
            O.step()
        self.assertIn('body #%d' % box, str(cm.exception))
        self.assertIn('periodic', str(cm.exception))
        self.assertEqual(tuple(O.bodies[s].state.pos), (0.05, 0.05, 0.05))


def press(a, b, f=5.0):
    """Opposite forces of ``f`` [N] on ``a`` and ``b`` along the line from ``a`` to the image of
    ``b`` it touches (the interaction's cellDist)."""
    i = O.interactions[a, b]
    d = O.bodies[b].state.pos + O.cell.hSize * Vector3(*i.cellDist) - O.bodies[a].state.pos
    n = d / d.norm()
    O.forces.addF(a, f * n)
    O.forces.addF(b, -f * n)


class TestCellFlip(unittest.TestCase):
    """A flippable cell (Cell.flipFlippable) is re-based by YADE when the shear makes a more compact
    base possible (at γ = 0.5): hSize changes, every cellDist is re-expressed, and prevHSize is set
    to the new hSize, one step ahead of the step's start. The lattice is the same, so the motion
    must be too. In a cell sheared to γ = 0.45 and shearing on (L = γ̇ e_x ⊗ e_z, h·γ̇ = 0.01, so
    the cell flips at the sixth step), after a first step that gives A the mean field, sphere B is
    placed so that A touches the image of B through the z boundary
    along a tilted normal (±45° in the x–z plane), moving with A, the two pressed together by
    opposite central forces of 5 N (L² = 0: the contact holds them at rest relative to each other). A flip that misplaced the image at the step's middle by h·L·H·cellDist (6e-4 m
    along x, ±4e-4 m along the normal: what YADE's prevHSize = hSize after a flip gives) opens
    the loaded contact for a step or closes it deeper (measured with the engine's flip handling
    switched off: velocities differ by up to 2 m/s). With and without flips, A and B move
    identically to round-off through the flip, the contact loaded."""

    def run_shear(self, flip, sense, steps=20):
        O.reset()
        O.periodic = True
        O.cell.hSize = Matrix3(0.12, 0, 0.054, 0, 0.12, 0, 0, 0, 0.12)
        mat = scenes.material(0.5)
        n = Vector3(sense, 0, 1).normalized()
        a = O.bodies.append(utils.sphere((0.06, 0.06, 0.1), 0.01, material=mat))
        import __main__
        __main__.press = press                 # PyRunner commands run in __main__
        O.engines = yadecd.engines(gravity=(0, 0, 0), tolerance=1e-14, maxIter=10000,
                                   extra=[PyRunner(iterPeriod=1, command='press(%d, %d)' % (a, a + 1))])
        O.dt = 1e-3
        O.cell.flipFlippable = flip
        O.cell.velGrad = Matrix3(0, 0, 10.0, 0, 0, 0, 0, 0, 0)
        O.engines[-2].dead = True
        O.step()        # the cell takes its velocity gradient and A the mean field; then B, at rest relative to A
        O.engines[-2].dead = False
        image = O.bodies[a].state.pos + 0.02 * n
        b = O.bodies.append(utils.sphere(tuple(image - O.cell.hSize * Vector3(0, 0, 1)), 0.01, material=mat))
        O.bodies[b].state.vel = O.bodies[a].state.vel - O.cell.velGrad * (O.cell.hSize * Vector3(0, 0, 1))
        out, cell_dists, loads = [], set(), []
        for _ in range(steps):
            O.step()
            out.append([list(O.bodies[i].state.vel) + list(O.bodies[i].state.pos) + list(O.bodies[i].state.angVel) for i in (a, b)])
            i = O.interactions[a, b]
            cell_dists.add(tuple(i.cellDist))
            loads.append(i.phys.normalForce.norm())
        return np.array(out), np.array(O.cell.hSize), cell_dists, loads

    def test_flip_changes_nothing(self):
        for sense in (1, -1):
            with self.subTest(sense=sense):
                plain, h_plain, dist_plain, loads = self.run_shear(False, sense)
                flipped, h_flipped, dist_flipped, _ = self.run_shear(True, sense)
                self.assertEqual(len(dist_plain), 1)
                self.assertEqual(len(dist_flipped), 2, 'the cell never flipped: the test would not test it')
                self.assertGreater(min(loads[:10]), 1.0, 'the contact is not loaded at the flip')
                np.testing.assert_allclose(h_plain[:, 2] - h_flipped[:, 2], h_plain[:, 0], rtol=0, atol=1e-12)
                np.testing.assert_allclose(flipped, plain, rtol=0, atol=1e-11)   # round-off of H·F (1e-12 measured)


class TestPeriTriaxController(unittest.TestCase):
    """YADE's PeriTriaxController in strain control (stressMask 0: it writes velGrad's diagonal
    each step, before the integrator, from the strain left to its goal) drives a contact-free
    periodic gas of 30 spheres to the isotropic strain −0.05 under CD exactly as under
    NewtonIntegrator: the same cell (trsf) to round-off, the cell's strain log(trsf_ii) reaching
    the goal within the controller's own 1e-6, and the bodies following it as under
    NewtonIntegrator but for the two integrators' difference (midpoint against leapfrog, 1e-6). (Its doneHook never fires in a contact-free scene, under either integrator: the
    unbalanced force it also requires is NaN without contacts. In stress control, dynCell, the
    rigid packing makes the cell bounce instead: docs/method.md, Periodic cells.)"""

    def build(self, cd):
        from yade import pack
        from yade.wrapper import PeriTriaxController
        O.reset()
        O.periodic = True
        O.cell.setBox(0.1, 0.1, 0.1)
        sp = pack.SpherePack()
        sp.makeCloud((0, 0, 0), (0.1, 0.1, 0.1), rMean=0.004, rRelFuzz=0.2, num=30, periodic=True, seed=2)
        mat = scenes.material(0.5, 2500.0)
        for c, r in sp:
            O.bodies.append(utils.sphere(c, r, material=mat))
        ctrl = PeriTriaxController(goal=(-0.05, -0.05, -0.05), stressMask=0, maxStrainRate=(2, 2, 2), maxUnbalanced=10,
                                   doneHook='O.pause()', label='ctrl')
        if cd:
            O.engines = yadecd.engines(gravity=(0, 0, 0), extra=[ctrl])
        else:
            O.engines = [ForceResetter(), InsertionSortCollider([Bo1_Sphere_Aabb()]), ctrl, NewtonIntegrator(damping=0)]
        O.dt = 1e-4

    def test_strain_control_as_under_newton(self):
        out = {}
        for cd in (True, False):
            self.build(cd)
            O.run(2000, True)
            out[cd] = (O.iter, np.array(O.cell.trsf), np.array([list(b.state.pos) + list(b.state.vel) for b in O.bodies]))
            self.assertEqual(len([i for i in O.interactions if i.isReal]), 0, 'the gas must stay contact-free')
        np.testing.assert_allclose(np.log(np.diag(out[True][1])), -0.05, rtol=0, atol=1e-6)
        np.testing.assert_allclose(out[True][1], out[False][1], rtol=0, atol=1e-14)
        # bodies: CD moves positions by the midpoint rule q_f = q_i + h(u_i + u_f)/2 (paper §II.3),
        # NewtonIntegrator by leapfrog q_f = q_i + h·u_f; with the mean field changing at every
        # step (the controller's L) they differ by h/2·Δu per step, and the next jump ΔL·x carries
        # that into the velocities: measured 1e-6 (m, m/s) over a 5e-3 m affine motion
        np.testing.assert_allclose(out[True][2], out[False][2], rtol=0, atol=2e-6)


if __name__ == '__main__':
    unittest.main()

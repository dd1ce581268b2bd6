"""Failure boundaries of CD and MD, and the CD/MD comparison library (py/yadecd/compare.py).

What the CD engine must report when it cannot deliver (never a silent wrong answer), what the
MD builder really builds, and that compare.run() names failures as documented. Fast (a few
seconds); run inside YADE (``bash tests/run.sh -k Compare``).
"""
import math
import unittest

from yade import O, Vector3
from yade.wrapper import NewtonIntegrator, ContactDynamicsIntegrator, Law2_ScGeom_FrictPhys_CundallStrack

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
import yadecd
from yadecd import compare, scenes

G = 9.81
# the μ = 0 residual bug of earlier builds: residual of r = 0 against a separating velocity ≠ 0


def floor_error(ids, m):
    f = O.interactions[0, ids[0]].phys.normalForce.norm()
    return abs(f / (len(ids) * m * G) - 1)


class TestCompareCDFailures(unittest.TestCase):
    """The CD solver's failure boundaries: it must say so when it stops short."""

    def test_max_iter_too_small_is_reported(self):
        """A 40-sphere column, cold start, plain Gauss–Seidel (ω = 1), maxIter = 20 ≪ the ~8000
        sweeps it needs at tol 1e-6: every step is flagged (converged False, nUnconverged counts
        the steps) and the floor force is indeed wrong; with enough sweeps the same step
        converges and is right."""
        sc = scenes.column(40, tolerance=1e-6, maxIter=20, relaxation=1.0, warnUnconverged=False)
        cd = yadecd.integrator()
        for k in range(3):
            O.step()
            self.assertFalse(cd.converged)
            self.assertEqual(cd.iterations, 20)
            self.assertEqual(cd.nUnconverged, k + 1)
            self.assertGreater(cd.residual, cd.tolerance)
        self.assertGreater(floor_error(sc['ids'], sc['m']), 1e-2, 'the unconverged answer is really wrong')
        sc = scenes.column(40, tolerance=1e-6, maxIter=100000, relaxation=1.0, warnUnconverged=False)
        cd = yadecd.integrator()
        O.step()
        self.assertTrue(cd.converged)
        self.assertEqual(cd.nUnconverged, 0)
        self.assertLess(floor_error(sc['ids'], sc['m']), 1e-4)

    def test_converged_means_accurate_force(self):
        """Whenever a step of the 40-column reports converged at tol 1e-6, the floor force is
        within 1e-4 (docs/data/column_convergence.csv: cold error ≈ 2·tol); unconverged steps
        are exactly those counted."""
        sc = scenes.column(40, tolerance=1e-6, maxIter=2000, relaxation=1.0, momentum=False, warnUnconverged=False)
        cd = yadecd.integrator()
        flagged = 0
        for _ in range(10):
            O.step()
            if cd.converged:
                self.assertLess(floor_error(sc['ids'], sc['m']), 1e-4)
            else:
                flagged += 1
        self.assertEqual(cd.nUnconverged, flagged)
        self.assertGreater(flagged, 0, 'maxIter=2000 must be too small for the cold start of this column')
        self.assertLess(flagged, 10, 'the warm start must eventually converge within 2000 sweeps')

    def test_momentum_converges_where_plain_gs_stalls(self):
        """The same cold 40-column with Nesterov momentum (the default): every step converges
        within the 2000 sweeps that plain Gauss–Seidel overruns, to the same floor-force accuracy."""
        sc = scenes.column(40, tolerance=1e-6, maxIter=2000, warnUnconverged=False)
        cd = yadecd.integrator()
        self.assertTrue(cd.momentum)
        for _ in range(10):
            O.step()
            self.assertTrue(cd.converged)
            self.assertLess(floor_error(sc['ids'], sc['m']), 1e-4)
        self.assertEqual(cd.nUnconverged, 0)

    def test_stall_named_by_compare(self):
        r = compare.run('column', 'CD', {'n': 10}, dt=1e-3, tolerance=1e-6, maxIter=20, T=0.02, repeats=1)
        self.assertEqual(r['status'], 'stalls')
        self.assertGreater(r['unconverged_steps'], 0)

    def test_fast_projectile_does_not_tunnel(self):
        """1000 m/s towards a wall with h = 1 ms (one metre per step, 50 diameters): CD lands it
        on the wall and bounces it (e_n = 1) at the same speed, without interpenetration; the
        position is the midpoint scheme's, exactly (the 'drifts' of the comparison at this step,
        not a crossing)."""
        r = compare.run('projectile', 'CD', {'speed': 1000.0}, dt=1e-3, repeats=1)
        self.assertNotIn(r['status'], ('tunnels', 'explodes'))
        self.assertLess(r['vel_error'], 1e-12)
        self.assertLess(r['overlap_max_rel'], 1e-9)
        # Moreau's midpoint scheme bounces at the midpoint q_m = q_i + h/2·u_i (gap 0.35 - 0.5 m < 0)
        # and ends at q_m + h/2·u_f: back at its start gap 0.35 m, moving away at 1000 m/s, where
        # the continuous solution (after T = 1 step = 1 ms) is at 0.65 m: a lag of 0.3 m = 15 d
        self.assertAlmostEqual(r['pos_error'], 0.3 / 0.02, delta=1e-9)
        sc = scenes.projectile(1000.0, dt=1e-3)
        compare.set_cd(en=1.0)
        O.step()
        s = O.bodies[sc['sphere']].state
        self.assertAlmostEqual(s.pos[2] - sc['r'], 0.35, delta=1e-12)
        self.assertAlmostEqual(s.vel[2], 1000.0, delta=1e-9)
        r = compare.run('projectile', 'CD', {'speed': 10.0}, dt=1e-5, repeats=1)
        self.assertEqual(r['status'], 'ok')
        # inelastic (the builder's e_n = 0): stops on the wall, centre at r
        sc = scenes.projectile(100.0, dt=1e-3)
        compare.set_cd()
        O.run(10, True)
        s = O.bodies[sc['sphere']].state
        self.assertAlmostEqual(s.pos[2], sc['r'], delta=1e-6 * sc['r'])
        self.assertLess(abs(s.vel[2]), 1e-9)

    def test_frictionless_gap_contact_converges(self):
        """With μ = 0 an open gap contact must not block convergence: the natural-map residual
        of r = 0 with a separating velocity is 0, and a step with a frictionless resting pair
        and a gap contact converges at once. (Before the fix, the residual equalled the gap
        offset 2g/h and every such step ran to maxIter, counted unconverged.)"""
        e = ContactDynamicsIntegrator.naturalMapResidual(Vector3(0, 0, 0), Vector3(6, 0, 0), 0.0, 1.0)
        self.assertEqual(e.norm(), 0.0)
        from yade import utils
        O.reset()
        mat = scenes.material(0.0)
        O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
        O.bodies.append(utils.sphere((0, 0, 0.01), 0.01, material=mat))
        O.bodies.append(utils.sphere((0.0203, 0, 0.01), 0.01, material=mat))  # 0.3 mm gap: a gap contact
        O.engines = yadecd.engines(gravity=(0, 0, -G), maxIter=50, warnUnconverged=False)
        O.dt = 1e-4
        O.step()
        cd = yadecd.integrator()
        self.assertEqual(cd.nContacts, 3)
        self.assertTrue(cd.converged)
        self.assertLess(cd.iterations, 50)


class TestCompareMD(unittest.TestCase):
    """The MD builder runs YADE's soft-contact MD on the scene's bodies, and its failures are
    named."""

    def test_md_builder_is_md(self):
        """A sphere resting on a wall, linear law: settles with overlap m g / kn (kn = E r for a
        sphere on a wall) within 1 %; the engines are YADE's, not CD's."""
        sc = scenes.column(1)
        dt = compare.to_md(young=1e7, safety=0.5, damping=0.7)
        self.assertFalse(any(isinstance(e, ContactDynamicsIntegrator) for e in O.engines))
        self.assertTrue(isinstance(O.engines[-1], NewtonIntegrator))
        self.assertTrue(any(isinstance(f, Law2_ScGeom_FrictPhys_CundallStrack) for f in O.engines[2].lawDispatcher.functors))
        self.assertAlmostEqual(dt, 0.5 * sc['r'] * math.sqrt(1000 / 1e7), delta=1e-12)
        O.run(4000, True)
        i = O.interactions[0, sc['ids'][0]]
        self.assertAlmostEqual(i.phys.kn, 1e7 * sc['r'], delta=1e-6 * 1e7 * sc['r'])
        overlap = sc['r'] - O.bodies[sc['ids'][0]].state.pos[2]
        self.assertAlmostEqual(overlap / (sc['m'] * G / i.phys.kn), 1, delta=0.01)
        self.assertLess(O.bodies[sc['ids'][0]].state.vel.norm(), 1e-6)

    def test_to_md_refuses_a_running_scene(self):
        scenes.column(2)
        O.step()
        with self.assertRaises(RuntimeError):
            compare.to_md()

    def test_md_explodes_above_critical_step(self):
        """A 10-column with O.dt = 3·PWaveTimeStep (above the ≈ 2·PWave limit of a sphere
        between two springs) blows up and is named 'explodes'; at 0.5 it is fine."""
        r = compare.run('column', 'MD', {'n': 10}, young=1e7, safety=3.0, damping=0.4, T=0.1, repeats=1)
        self.assertEqual(r['status'], 'explodes')
        r = compare.run('column', 'MD', {'n': 10}, young=1e7, safety=0.5, damping=0.4, T=0.2, repeats=1)
        self.assertEqual(r['status'], 'ok')
        self.assertLess(r['force_error'], 1e-3)

    def test_md_tunnels(self):
        """100 m/s against a wall, E = 1e6 Pa: 0.8 diameters per step, the sphere crosses the
        wall and compare.run() names it 'tunnels'."""
        r = compare.run('projectile', 'MD', {'speed': 100.0}, young=1e6, safety=0.5, repeats=1)
        self.assertEqual(r['status'], 'tunnels')

    def test_binary_restitution_same_measure(self):
        """Head-on collision, e = 0.5: CD's post-collision velocities are exact (positions lag
        by at most h·|v1 − v2|); Hertz–Mindlin with en = 0.5 is within 1 % (its damping
        model's restitution)."""
        r = compare.run('binary', 'CD', {'en': 0.5}, dt=1e-4, repeats=1)
        self.assertLess(r['vel_error'], 1e-12)
        self.assertLess(r['pos_error'] * 0.02, 1e-4 * 1.5)
        self.assertEqual(r['status'], 'ok')
        if compare.HAVE_HERTZ:
            r = compare.run('binary', 'MD', {'en': 0.5}, law='hertz', young=1e7, safety=0.5, repeats=1)
            self.assertNotIn(r['status'], ('tunnels', 'explodes'))
            self.assertAlmostEqual(r['restitution'], 0.5, delta=0.01)


class TestLoadedOverlaps(unittest.TestCase):
    """compare_pile.loaded_overlaps on constructed pairs of fixed spheres under YADE's linear MD:
    the overlap from positions of the pairs that carry a force (a pair within reach of the
    collider but not touching is left out), over the mean diameter."""

    def test_constructed_pairs(self):
        from yade import utils
        from yadecd.compare.pile import loaded_overlaps
        from yadecd.compare.md import md_engines
        O.reset()
        mat = scenes.material(0.4, 1000.0)
        r, d1, d2 = 1e-3, 4e-6, 1e-6
        pairs = [((0, 0, 0), (2 * r - d1, 0, 0)), ((0, 0.01, 0), (0, 0.01, 2 * r - d2)),
                 ((0, 0.02, 0), (2 * r + 1e-5, 0.02, 0))]          # the third pair: a gap, no force
        for a, b in pairs:
            for x in (a, b):
                O.bodies.append(utils.sphere(x, r, fixed=True, material=mat))
        O.engines = md_engines(gravity=(0, 0, 0))
        O.engines[1].verletDist = 5e-5                                  # the third pair is found by the collider
        O.dt = 1e-7
        O.step()
        self.assertEqual(O.interactions.countReal(), 2)
        omax, omean, n = loaded_overlaps()
        self.assertEqual(n, 2)
        self.assertAlmostEqual(omax, d1 / (2 * r), delta=1e-12)
        self.assertAlmostEqual(omean, (d1 + d2) / 2 / (2 * r), delta=1e-12)

    def test_cd_allowance_and_open_contacts(self):
        """Under CD: a grain standing on a fixed grain with a construction overlap (kept as its
        allowance: counted only with beyond_allowance=False), and an open near contact (real,
        no force: left out)."""
        from yade import utils
        from yadecd.compare.pile import loaded_overlaps
        O.reset()
        mat = scenes.material(0.4, 1000.0)
        r, delta = 1e-3, 3e-6
        O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
        O.bodies.append(utils.sphere((0, 0, r), r, fixed=True, material=mat))
        O.bodies.append(utils.sphere((0, 0, 3 * r - delta), r, material=mat))            # on it, overlapping by delta
        O.bodies.append(utils.sphere((0.01, 0, r), r, material=mat))                     # on the wall
        O.bodies.append(utils.sphere((0.01 + 2 * r + 1e-6, 0, r), r, fixed=True, material=mat))  # 1 µm away
        O.engines = yadecd.engines(gravity=(0, 0, -9.81))
        O.dt = 1e-4
        O.run(3, True)
        grain_pairs = [i for i in O.interactions if i.isReal and i.id1 > 0 and i.id2 > 0]
        self.assertEqual(len(grain_pairs), 2, 'the standing pair and the open near pair')
        omax, omean, n = loaded_overlaps(beyond_allowance=False)
        self.assertEqual(n, 1)
        self.assertAlmostEqual(omax, delta / (2 * r), delta=1e-6 * r / (2 * r))
        omax, omean, n = loaded_overlaps(beyond_allowance=True)
        self.assertLess(omax, 1e-6)                    # CD adds no overlap beyond the allowance (positionTolerance)


if __name__ == '__main__':
    unittest.main()

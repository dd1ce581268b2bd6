"""Bad input: every case raises a clear Python exception naming the culprit, and leaves the
scene as it was (a failed step moves nothing)."""
from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
import math
import unittest

from yade import O, utils
from yade import Vector3, Matrix3
from yade.wrapper import (ContactDynamicsIntegrator, Ip2_FrictMat_FrictMat_CDPhys,
                          PyRunner)

import yadecd
from yadecd import scenes


def snapshot():
    # repr, so that a NaN compares equal to itself
    return [repr((b.state.pos, b.state.vel, b.state.ori, b.state.angVel)) for b in O.bodies]


class TestBadInput(unittest.TestCase):
    def assertStepFails(self, exc, *words):
        before, it = snapshot(), O.iter
        with self.assertRaises(exc) as cm:
            O.step()
        for w in words:
            self.assertIn(w, str(cm.exception))
        self.assertEqual(snapshot(), before, 'a failed step must leave positions and velocities unchanged')
        self.assertEqual(O.iter, it)
        return cm.exception

    def test_attributes(self):
        for kw, word in ((dict(tolerance=-1), 'tolerance'), (dict(tolerance=float('nan')), 'tolerance'),
                         (dict(maxIter=0), 'maxIter'), (dict(alertSpeedFactor=0.5), 'alertSpeedFactor'),
                         (dict(alertRatio=float('nan')), 'alertRatio'), (dict(sweepOrder=6), 'sweepOrder'),
                         (dict(slabs=0), 'slabs'), (dict(slabs=65), 'slabs'),
                         (dict(parallelMinContacts=-1), 'parallelMinContacts')):
            with self.assertRaises(ValueError) as cm:
                ContactDynamicsIntegrator(**kw)
            self.assertIn(word, str(cm.exception))
        for order in (0, 2, 3):  # retired schedules: refused with the reason
            with self.assertRaises(ValueError) as cm:
                ContactDynamicsIntegrator(sweepOrder=order)
            self.assertIn('retired', str(cm.exception))
        cd = ContactDynamicsIntegrator()
        with self.assertRaises(ValueError):
            cd.tolerance = 0
        scenes.column(2)  # a problem file that cannot be written fails the step, by name, changing nothing
        yadecd.integrator().problemFile = '/nonexistent-dir/step.cdp'
        self.assertStepFails(ValueError, 'problemFile', '/nonexistent-dir/step.cdp')
        for kw, word in ((dict(en=-0.1), 'en'), (dict(en=float('nan')), 'en'), (dict(en=1.5), 'en'), (dict(et=2), 'et')):
            with self.assertRaises(ValueError) as cm:
                Ip2_FrictMat_FrictMat_CDPhys(**kw)
            self.assertIn(word, str(cm.exception))

    def test_local_problem_helpers(self):
        """solveLocal refuses a W that is not symmetric positive definite (a non-symmetric one, and
        an indefinite symmetric one with a positive diagonal, which an LDLT factorisation accepts)
        and a negative or infinite mu; naturalMapResidual refuses rho <= 0. A valid call still
        solves: an isolated sticking contact gets r = −W⁻¹b exactly."""
        CDI = ContactDynamicsIntegrator
        b = Vector3(-1, 0.1, 0)
        for W, word in ((Matrix3(2, 1, 0, 0, 2, 0, 0, 0, 2), 'symmetric positive definite'),
                        (Matrix3(1, 2, 0, 2, 1, 0, 0, 0, 1), 'symmetric positive definite')):
            with self.assertRaisesRegex(ValueError, word):
                CDI.solveLocal(W, b, 0.5)
        for mu in (-0.1, float('inf')):
            with self.assertRaisesRegex(ValueError, 'mu must be'):
                CDI.solveLocal(Matrix3(1, 0, 0, 0, 1, 0, 0, 0, 1), b, mu)
        with self.assertRaisesRegex(ValueError, 'rho must be'):
            CDI.naturalMapResidual(Vector3(1, 0, 0), Vector3(0, 0, 0), 0.5, 0.0)
        r, status = CDI.solveLocal(Matrix3(1, 0, 0, 0, 1, 0, 0, 0, 1), b, 0.5)
        self.assertEqual(status, 1)
        self.assertEqual(tuple(r), (1.0, -0.1, 0.0))

    def test_time_step(self):
        scenes.column(2)
        for dt in (0.0, float('nan'), float('inf')):
            O.dt = dt
            self.assertStepFails(ValueError, 'O.dt')
        # a negative O.dt is refused by YADE itself (it would switch to a time stepper)
        with self.assertRaises(RuntimeError):
            O.dt = -1e-4

    def test_friction(self):
        """A friction angle outside [0, π/2) fails the step naming the contact: negative, NaN, π/2
        itself, and π + 0.1, whose tangent (0.1) would otherwise pass for a coefficient."""
        for angle in (-0.1, float('nan'), math.pi / 2, math.pi + 0.1):
            sc = scenes.column(2)
            O.materials[0].frictionAngle = angle
            self.assertStepFails(ValueError, 'friction', '#0', '#%d' % sc['ids'][0])

    def test_first_bad_contact_of_many_is_named(self):
        """Among more interactions than one thread's share (at least 4096: the gather checks them in
        parallel blocks), the contact named is the first bad one in the container's order, whatever
        the thread count: two contacts given a NaN friction coefficient, the later one in the
        container is not the one named."""
        scenes.fcc_block(1000)
        O.step()
        self.assertGreaterEqual(len(O.interactions), 4096)
        real = [i for i in O.interactions if i.isReal]
        early, late = real[len(real) // 3], real[-1]
        for i in (late, early):
            i.phys.tangensOfFrictionAngle = float('nan')
        e = self.assertStepFails(ValueError, 'friction coefficient nan', '(#%d, #%d)' % (early.id1, early.id2))
        self.assertNotIn('(#%d, #%d)' % (late.id1, late.id2), str(e))

    def test_mass_and_inertia(self):
        sc = scenes.column(2)
        O.bodies[sc['ids'][1]].state.mass = 0
        self.assertStepFails(ValueError, 'mass', '#%d' % sc['ids'][1])
        sc = scenes.column(2)
        O.bodies[sc['ids'][1]].state.inertia = Vector3(1, -1, 1)
        self.assertStepFails(ValueError, 'inertia', '#%d' % sc['ids'][1])

    def test_unsupported_shape_pair(self):
        """A dynamic box on the floor wall: no CD functor for Wall–Box, so the step fails by name."""
        scenes.column(1)
        b = O.bodies.append(utils.box((0, 0, 0.005), (0.01, 0.01, 0.01), fixed=False))
        self.assertStepFails(ValueError, 'Box', 'Wall', '#%d' % b)

    def test_nan_state(self):
        sc = scenes.column(2)
        O.bodies[sc['ids'][1]].state.vel = Vector3(float('nan'), 0, 0)
        self.assertStepFails(ValueError, 'NaN', '#%d' % sc['ids'][1])

    def test_nan_appearing_in_step(self):
        """A NaN force added during the step (by a PyRunner) is caught before anything moves."""
        sc = scenes.column(2)
        bad = sc['ids'][0]
        O.engines = O.engines[:-1] + [PyRunner(command='O.forces.addF(%d, (float(\"nan\"),0,0))' % bad, iterPeriod=1, initRun=True)] + O.engines[-1:]
        self.assertStepFails(RuntimeError, 'NaN', '#%d' % bad)

    def test_damping(self):
        scenes.column(1)
        yadecd.integrator().damping = 0.2
        self.assertStepFails(ValueError, 'damping')

    def test_inherited_attributes_not_honoured(self):
        """NewtonIntegrator's attributes that Contact Dynamics ignores are refused by name when
        set away from their defaults, before anything moves; at their defaults a step runs."""
        cases = (('mask', 1, 'mask=1'),
                 ('exactAsphericalRot', False, 'exactAsphericalRot'), ('normalizeEvery', 10, 'normalizeEvery=10'),
                 ('niterOmelyan1998', 5, 'niterOmelyan1998=5'), ('kinSplit', True, 'kinSplit'),
                 ('dampGravity', False, 'dampGravity'))
        for name, value, word in cases:
            with self.subTest(attribute=name):
                scenes.column(2)
                setattr(yadecd.integrator(), name, value)
                self.assertStepFails(ValueError, word, "NewtonIntegrator's default")
        scenes.column(2)
        cd = yadecd.integrator()
        cd.rotAlgorithm = 'Omelyan1998'
        self.assertStepFails(ValueError, 'rotAlgorithm')
        scenes.column(2)
        O.step()

    def test_recovers_after_fix(self):
        """After an error is fixed the simulation continues normally."""
        sc = scenes.column(2)
        O.dt = float('nan')
        with self.assertRaises(ValueError):
            O.step()
        O.dt = 1e-4
        O.run(10, True)
        self.assertEqual(O.iter, 10)
        # at rest to the solver tolerance: velocity error ≤ tolerance·‖q‖ ≈ tolerance·g·h per
        # step, hence a drift below 10·tolerance·g·h²·steps
        bound = 10 * yadecd.integrator().tolerance * 9.81 * O.dt ** 2 * O.iter
        self.assertAlmostEqual(O.bodies[sc['ids'][0]].state.pos[2], 0.01, delta=bound)


if __name__ == '__main__':
    unittest.main()

"""The plane-shear measurements (yadecd.compare.shear) on constructed cases with known answers:
the slab volume of spheres cut by two planes (spherical caps), and the bulk shear rate and solid
fraction of a constructed sample with an exact linear velocity profile; and the runs' checkpoints
on a small packing: an interrupted CD run resumed gives the same samples, bit for bit."""
import math
import os
import shutil
import tempfile
import unittest

import numpy as np

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yade import O, utils, Vector3
from yadecd.analysis import rheology
from yadecd.compare import shear


class TestSlabVolume(unittest.TestCase):

    def test_caps(self):
        """r = 1: wholly inside 4π/3; wholly outside 0; cut through the centre 2π/3; a cap of
        height h = 0.5 π h²(3r − h)/3 = 5π/24; a slab of width 2a through the centre
        π(2a r² − 2a³/3)."""
        r = np.ones(5)
        z = np.array([0.0, 5.0, 0.0, 0.0, 0.0])
        cases = [(-2, 2), (-2, 2), (0, 2), (0.5, 3), (-0.25, 0.25)]
        want = [4 * math.pi / 3, 0.0, 2 * math.pi / 3, 5 * math.pi / 24, math.pi * (0.5 - 2 * 0.25 ** 3 / 3)]
        for k, ((z0, z1), w) in enumerate(zip(cases, want)):
            self.assertAlmostEqual(float(shear.slab_volume(z[k:k + 1], r[k:k + 1], z0, z1)[0]), w, delta=1e-14)

    def test_additive(self):
        """Adjacent slabs add up to the whole sphere, whatever the cut."""
        rng = np.random.default_rng(1)
        z, r = rng.uniform(-1, 1, 50), rng.uniform(0.1, 0.5, 50)
        cut = rng.uniform(-1, 1, 50)
        total = shear.slab_volume(z, r, -3, cut) + shear.slab_volume(z, r, cut, 3)
        np.testing.assert_allclose(total, 4 * math.pi / 3 * r ** 3, rtol=1e-13)


class TestMeasure(unittest.TestCase):

    def test_linear_profile_and_fraction(self):
        """Grains on a column with v_x = 3·z (exactly linear): the bulk rate is 3; the central
        half of a gap of 1 holds whole grains of radius 0.05 at z = 0.3…0.7: φ = their volume over
        the slab's; no contact: no wall force."""
        O.reset()
        O.periodic = True
        O.cell.setBox(1, 1, 4)
        bottom, _ = O.bodies.appendClumped([utils.sphere((0.5, 0.5, 0), 0.05)])
        top, members = O.bodies.appendClumped([utils.sphere((0.5, 0.5, 1.0), 0.05)])
        grains = []
        for z in (0.1, 0.3, 0.4, 0.5, 0.6, 0.7, 0.9):
            g = O.bodies.append(utils.sphere((0.5, 0.5, z), 0.05))
            O.bodies[g].state.vel = Vector3(3 * z, 0, 0)
            grains.append(O.bodies[g])
        m = shear.measure(O.bodies[bottom], O.bodies[top], grains, set(members))
        self.assertAlmostEqual(m['gap'], 1.0, delta=1e-15)
        self.assertAlmostEqual(m['gamma_dot'], 3.0, delta=1e-12)
        self.assertAlmostEqual(m['phi'], 5 * 4 * math.pi / 3 * 0.05 ** 3 / 0.5, delta=1e-14)
        self.assertEqual((m['fx'], m['fz'], m['n_contacts']), (0.0, 0.0, 0))


class TestCheckpoint(unittest.TestCase):
    """A run interrupted after its checkpoint and resumed from it measures the same samples as a
    run never interrupted: bit for bit under CD (the archive holds the whole state, and the wall
    force is summed exactly, independent of the interaction container's order, which a load does
    not keep); under MD the same physical state, its force sums in another order (round-off)."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix='cd-shear-')
        cls.pack = os.path.join(cls.tmp, 'packing.yade.gz')
        shear.packing(cls.pack, n=300, seed=1, settle_steps=200, log=lambda m: None)     # 4 d × 4 d cell, ≈ 30 s

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def interrupted(self, method, name, after=15, **options):
        """A run to strain 0.3 (30 samples) stopped by an error after ``after`` samples (its
        checkpoint every 10), then resumed with the rows measured so far."""
        stem, got = os.path.join(self.tmp, name), []

        class Stop(Exception):
            pass

        def on(row):
            got.append(row)
            if len(got) == after:
                raise Stop()

        with self.assertRaises(Stop):
            shear.run(self.pack, method, 0.1, strain=0.3, log=lambda m: None, on_sample=on, checkpoint=stem, checkpoint_every=10,
                      **options)
        state = shear.checkpoint_state(stem)
        self.assertEqual((state['samples'], state['final']), (10, False))
        return stem, got

    def test_cd_resume_is_bit_identical_and_extends(self):
        info, straight = shear.run(self.pack, 'cd', 0.1, strain=0.3, log=lambda m: None)
        stem, got = self.interrupted('cd', 'cd_run')
        info2, resumed = shear.run(self.pack, 'cd', 0.1, strain=0.3, log=lambda m: None, checkpoint=stem, done_rows=got,
                                   checkpoint_every=10)
        self.assertEqual(len(resumed), 30)
        self.assertEqual(info2['steps'], info['steps'])
        for a, b in zip(straight, resumed):      # every column but the wall time, nan included
            self.assertTrue(np.array_equal(np.array(a[:-1]), np.array(b[:-1]), equal_nan=True), (a, b))
        self.assertTrue(shear.checkpoint_state(stem)['final'])
        self.assertEqual(len([f for f in os.listdir(self.tmp) if f.startswith('cd_run.ckpt_')]), 1)   # older archives removed
        info3, longer = shear.run(self.pack, 'cd', 0.1, strain=0.4, log=lambda m: None, checkpoint=stem, done_rows=resumed)
        self.assertEqual((len(longer), info3['steps'], info3['strain']), (40, 4 * info['steps'] // 3, 0.4))
        self.assertEqual(longer[:30], resumed)
        self.assertAlmostEqual(longer[-1][2], 0.4, delta=0.011)     # the wall's travel over the gap

    def test_resume_refuses_other_settings_or_missing_rows(self):
        stem, got = self.interrupted('cd', 'cd_refuse', after=12)
        with self.assertRaisesRegex(ValueError, r'checkpoint .*cd_refuse.ckpt.json is of cd at I=0.1 with .*en_cd.*0.1'):
            shear.run(self.pack, 'cd', 0.1, strain=0.3, log=lambda m: None, checkpoint=stem, done_rows=got, en_cd=0.1)
        with self.assertRaisesRegex(ValueError, 'holds 10 samples, but 9 rows were given'):
            shear.run(self.pack, 'cd', 0.1, strain=0.3, log=lambda m: None, checkpoint=stem, done_rows=got[:9])

    def test_md_tangential_damping_and_coulomb_bound(self):
        """YADE's Hertz–Mindlin law adds its tangential viscous force to a sticking contact's elastic
        force without bounding the sum (docs/compare.md): with the reference e_t = e_n = 0.1 some
        loaded contacts carry |F_t| > μ·F_n; with e_t = 1 (``es_md=1``: no tangential damping) none
        does, to the law's rounding (rheology.coulomb_excess, relative tolerance 1e-9). Bad values
        of the MD options are refused by name."""
        def excess(**options):
            shear.build(self.pack, 'md', 0.1, **options)
            O.run(300, True)
            fn, ft = zip(*[(i.phys.normalForce.norm(), i.phys.shearForce.norm()) for i in O.interactions if i.isReal])
            return rheology.coulomb_excess(fn, ft, shear.REFERENCE['mu'], rtol=1e-9)

        damped, bounded = excess(), excess(es_md=1.0)
        self.assertGreater(bounded['loaded'], 100)
        self.assertEqual(bounded['over'], 0.0)
        self.assertGreater(damped['over'], 0.0)
        self.assertGreater(damped['tangential_share'], 0.0)
        with self.assertRaisesRegex(ValueError, 'es_md is a restitution coefficient'):
            shear.build(self.pack, 'md', 0.1, es_md=1.5)
        with self.assertRaisesRegex(ValueError, 'safety is the MD time step'):
            shear.build(self.pack, 'md', 0.1, safety=0.0)

    def test_md_resumes_the_same_state(self):
        info, straight = shear.run(self.pack, 'md', 0.1, strain=0.3, log=lambda m: None)
        stem, got = self.interrupted('md', 'md_run')
        info2, resumed = shear.run(self.pack, 'md', 0.1, strain=0.3, log=lambda m: None, checkpoint=stem, done_rows=got)
        self.assertEqual((len(resumed), info2['steps']), (30, info['steps']))
        self.assertEqual(resumed[:10], got[:10])
        self.assertEqual(resumed[10][:3], straight[10][:3])           # step, time and wall travel: the same steps
        self.assertAlmostEqual(resumed[10][3] / straight[10][3], 1, delta=1e-12)   # the gap, one sample on
        self.assertAlmostEqual(resumed[-1][3] / straight[-1][3], 1, delta=1e-6)    # and twenty samples on


if __name__ == '__main__':
    unittest.main()

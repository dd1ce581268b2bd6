"""The plane-shear measurements (yadecd.compare.shear) on constructed cases with known answers:
the slab volume of spheres cut by two planes (spherical caps), and the bulk shear rate and solid
fraction of a constructed sample with an exact linear velocity profile."""
import math
import unittest

import numpy as np

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yade import O, utils, Vector3
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


if __name__ == '__main__':
    unittest.main()

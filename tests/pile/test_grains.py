"""Grain shapes of a pile (yadecd.pile.grains): the union's volume and inertia against closed
forms, the shapes' constants against the integration, random orientations, and the resting
height of a clump dropped on a vertical, on constructed cases with known answers."""
import math
import unittest

import numpy as np

from repo_package import REPO  # noqa: F401  (first: this checkout's yadecd)
from yadecd.pile import grains


def lens(r1, r2, d):
    """Volume of the intersection of two spheres of radii r1, r2 with centres d apart."""
    if d >= r1 + r2:
        return 0.0
    return math.pi * (r1 + r2 - d) ** 2 * (d * d + 2 * d * (r1 + r2) - 3 * (r1 - r2) ** 2) / (12 * d)


class TestUnionMoments(unittest.TestCase):
    """Volume, centre of mass and inertia tensor of a union of spheres (unit density)."""

    def test_one_sphere(self):
        v, c, T = grains.union_moments([[0.3, -0.2, 0.7]], [2.0], n=1024)
        self.assertAlmostEqual(v / (4 / 3 * math.pi * 8), 1, delta=3e-6)
        np.testing.assert_allclose(c, [0.3, -0.2, 0.7], atol=1e-12)
        np.testing.assert_allclose(T, 2 / 5 * (4 / 3 * math.pi * 8) * 4 * np.eye(3), rtol=3e-6, atol=1e-9)

    def test_disjoint_spheres_parallel_axes(self):
        """Two apart spheres of radii 1 and 0.5 on the x axis: the centre of mass and the parallel
        axis theorem in closed form."""
        r, x = np.array([1.0, 0.5]), np.array([0.0, 3.0])
        m = 4 / 3 * math.pi * r ** 3
        xc = (m * x).sum() / m.sum()
        v, c, T = grains.union_moments(np.column_stack([x, [0, 0], [0, 0]]), r, n=1024)
        self.assertAlmostEqual(v / m.sum(), 1, delta=3e-6)
        self.assertAlmostEqual(c[0], xc, delta=1e-5)
        own = (2 / 5 * m * r ** 2).sum()
        exact = np.diag([own, own + (m * (x - xc) ** 2).sum(), own + (m * (x - xc) ** 2).sum()])
        np.testing.assert_allclose(T, exact, rtol=1e-5, atol=1e-6)

    def test_overlap_counted_once(self):
        """Two unequal overlapping spheres: the union is their volumes less the lens."""
        v, _, _ = grains.union_moments([[0, 0, 0], [0.4, 0.5, 0.6]], [1.0, 0.7], n=1024)
        d = math.sqrt(0.4 ** 2 + 0.5 ** 2 + 0.6 ** 2)
        exact = 4 / 3 * math.pi * (1 + 0.7 ** 3) - lens(1.0, 0.7, d)
        self.assertAlmostEqual(v / exact, 1, delta=3e-6)

    def test_shape_constants(self):
        """Every shape's volume and principal moments are those of its members' union, its centre
        of mass at the origin and its frame principal (the off-diagonal moments vanish)."""
        for name, s in grains.SHAPES.items():
            with self.subTest(shape=name):
                v, c, T = grains.union_moments(s['offsets'], np.ones(len(s['offsets'])), n=1024)
                self.assertAlmostEqual(v / s['volume'], 1, delta=3e-6)
                np.testing.assert_allclose(c, 0, atol=1e-9)
                np.testing.assert_allclose(np.diag(T), s['inertia'], rtol=3e-6)
                np.testing.assert_allclose(T - np.diag(np.diag(T)), 0, atol=1e-5)
        self.assertAlmostEqual(grains.SHAPES['dimer']['volume'], 8 / 3 * math.pi - lens(1, 1, 0.5 * 2), delta=1e-12)

    def test_shape_geometry(self):
        self.assertAlmostEqual(grains.aspect_ratio('dimer'), 1.5, delta=2e-3)
        self.assertEqual(grains.aspect_ratio('sphere'), 1.0)
        self.assertAlmostEqual(grains.circumradius('dimer'), 1.5, delta=1e-12)
        self.assertAlmostEqual(grains.circumradius('tetra'), 1 + 1.5 * math.sqrt(6) / 4, delta=1e-12)
        for name in grains.SHAPES:   # a grain has the volume of the sphere of its diameter
            a = grains.member_radius(name, 0.004)
            self.assertAlmostEqual(grains.SHAPES[name]['volume'] * a ** 3 / (math.pi / 6 * 0.004 ** 3), 1, delta=1e-12)
            m, inertia = grains.mass_properties(name, a, 1000.0)
            self.assertAlmostEqual(m, 1000 * math.pi / 6 * 0.004 ** 3, delta=1e-18)
            self.assertEqual(inertia.shape, (3,))

    def test_unknown_shape(self):
        with self.assertRaisesRegex(ValueError, "'cube' is not known: use one of dimer, sphere, tetra"):
            grains.shape('cube')


class TestRandomRotation(unittest.TestCase):

    def test_uniform_rotations(self):
        """Proper rotations; their mean over many draws vanishes (Haar measure: E[R] = 0) and the
        image of a fixed axis covers the sphere evenly (E[(R e)(R e)ᵀ] = I/3)."""
        rng = np.random.default_rng(5)
        Rs = np.array([grains.random_rotation(rng) for _ in range(20000)])
        np.testing.assert_allclose(np.einsum('kij,kil->kjl', Rs, Rs), np.broadcast_to(np.eye(3), Rs.shape), atol=1e-12)
        np.testing.assert_allclose(np.linalg.det(Rs), 1, atol=1e-12)
        np.testing.assert_allclose(Rs.mean(axis=0), 0, atol=4 * math.sqrt(1 / 3 / 20000))
        e = Rs[:, :, 0]
        np.testing.assert_allclose(e.T @ e / len(e), np.eye(3) / 3, atol=0.01)


class TestRestingHeight(unittest.TestCase):
    """Lowest height at which a rigid set of spheres, lowered on a vertical, rests without overlap."""

    def test_dimer_on_the_plane(self):
        a = 0.001
        flat = np.array([[-0.5 * a, 0, 0], [0.5 * a, 0, 0]])
        upright = flat[:, [1, 2, 0]]
        self.assertEqual(grains.resting_height(0, 0, flat, [a, a], np.zeros((0, 3)), []), a)
        self.assertAlmostEqual(grains.resting_height(0, 0, upright, [a, a], np.zeros((0, 3)), []), 1.5 * a, delta=1e-18)

    def test_one_member_lands_on_a_sphere(self):
        """A flat dimer over a sphere that lies under its +x member only: it rests on it at
        z_j + sqrt((a + R)² − d²) with d the member's horizontal distance to the sphere; a sphere too
        far from both members is ignored."""
        a, R = 0.001, 0.002
        flat = np.array([[-0.5 * a, 0, 0], [0.5 * a, 0, 0]])
        obstacle = np.array([[0.5 * a + 0.0004, 0.0003, R], [0.01, 0, R]])
        z = grains.resting_height(0, 0, flat, [a, a], obstacle, [R, R])
        self.assertAlmostEqual(z, R + math.sqrt((a + R) ** 2 - 0.0005 ** 2), delta=1e-15)

    def test_sphere_is_the_papers_rule(self):
        """One member at offset 0: resting on the sphere met, the plane under a floating grain free."""
        c, rj, r = np.array([[0.0, 0.0, 0.003]]), np.array([0.003]), 0.002
        z = grains.resting_height(0.004, 0, np.zeros((1, 3)), [r], c, rj)
        self.assertAlmostEqual(z, 0.003 + math.sqrt(0.005 ** 2 - 0.004 ** 2), delta=1e-15)
        self.assertEqual(grains.resting_height(0.004, 0, np.zeros((1, 3)), [r], np.array([[0, 0, 0.02]]), rj), r)

    def test_never_overlaps_and_is_lowest(self):
        """Random tetra clumps dropped among random spheres: at the height found no member
        overlaps a sphere or the plane, and a little lower one does."""
        rng = np.random.default_rng(11)
        a = 0.001
        for trial in range(200):
            centres = np.column_stack([rng.uniform(-0.004, 0.004, (30, 2)), rng.uniform(0.001, 0.008, 30)])
            radii = rng.uniform(0.0008, 0.0015, 30)
            off = grains.shape('tetra')['offsets'] * a @ grains.random_rotation(rng).T
            x, y = rng.uniform(-0.002, 0.002, 2)
            z = grains.resting_height(x, y, off, np.full(4, a), centres, radii)
            members = np.array([x, y, z]) + off

            def gap(dz):
                m = members - [0, 0, dz]
                dist = np.linalg.norm(m[:, None, :] - centres[None, :, :], axis=2) - a - radii[None, :]
                return min(dist.min(), (m[:, 2] - a).min())
            self.assertGreater(gap(0), -1e-12, 'trial %d' % trial)
            self.assertLess(gap(1e-9), 0, 'trial %d' % trial)


if __name__ == '__main__':
    unittest.main()

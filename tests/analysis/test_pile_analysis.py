"""Sand-pile analysis (py/yadecd/analysis/) on constructed snapshots with known answers.

Pure numpy: yadecd imports without YADE, so these tests run inside YADE
(``bash tests/run.sh``) as well as with ``/usr/bin/python3 -m unittest`` from tests/. Every test
states the formula it checks; "exact" tolerances are 1e-12 relative (round-off only).
"""
import json
import math
import os
import tempfile
import unittest

import numpy as np

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd import analysis as pa




EXACT = 1e-12


# ---------------------------------------------------------------------------------------------
# constructed snapshots

class Builder:
    """Accumulates grains and contacts, then produces a snapshot dict (SI)."""

    def __init__(self, rho=1000.0, g=9.81, time=1.0):
        self.rho, self.g, self.time = rho, g, time
        self.grains = []      # (pos, radius, vel, fixed, birth, id)
        self.contacts = []    # (id1, id2, point, normal, force)
        self.next_id = 7      # ids need not be row numbers

    def grain(self, pos, radius=1e-3, vel=(0, 0, 0), fixed=False, birth=0.0):
        gid = self.next_id
        self.next_id += 3
        self.grains.append((pos, radius, vel, fixed, -1.0 if fixed else birth, gid))
        return gid

    def contact(self, id1, id2, point, force, normal=(0, 0, 1)):
        self.contacts.append((id1, id2, point, normal, force))

    def snapshot(self):
        g = self.grains
        c = self.contacts
        return {'time': self.time, 'g': self.g, 'rho': self.rho,
                'pos': np.array([x[0] for x in g], float).reshape(-1, 3),
                'radius': np.array([x[1] for x in g], float),
                'vel': np.array([x[2] for x in g], float).reshape(-1, 3),
                'fixed': np.array([x[3] for x in g], bool),
                'birth': np.array([x[4] for x in g], float),
                'ids': np.array([x[5] for x in g], np.int64),
                'c_id1': np.array([x[0] for x in c], np.int64),
                'c_id2': np.array([x[1] for x in c], np.int64),
                'c_point': np.array([x[2] for x in c], float).reshape(-1, 3),
                'c_normal': np.array([x[3] for x in c], float).reshape(-1, 3),
                'c_force': np.array([x[4] for x in c], float).reshape(-1, 3)}


def at(r, phi, z):
    """Cartesian point of meridian coordinates (r, z) at azimuth phi."""
    return (r * math.cos(phi), r * math.sin(phi), z)


def meridian_vector(vr, vz, phi, vphi=0.0):
    """Cartesian vector with radial vr, vertical vz and azimuthal vphi parts at azimuth phi."""
    return (vr * math.cos(phi) - vphi * math.sin(phi), vr * math.sin(phi) + vphi * math.cos(phi), vz)


def add_straddling(b, q, n, F_minus, phi, delta=4e-4, swap=False, vphi=0.0):
    """Two grains at meridian points q ± delta·n (azimuth phi) touching at q, with force F_minus
    = (Fr, Fz) exerted by the + grain on the - grain (plus an azimuthal part vphi, to be
    ignored). swap=True stores the contact with the - grain as body 1 (YADE: c_force acts on
    body 2, so the stored force is then -F)."""
    q, n = np.asarray(q, float), np.asarray(n, float)
    (rp, zp), (rm, zm) = q + delta * n, q - delta * n
    plus = b.grain(at(rp, phi, zp), delta)
    minus = b.grain(at(rm, phi, zm), delta)
    F = np.array(meridian_vector(F_minus[0], F_minus[1], phi, vphi))
    normal = np.array(meridian_vector(-n[0], -n[1], phi))
    if swap:
        b.contact(minus, plus, at(q[0], phi, q[1]), -F, -normal)
    else:
        b.contact(plus, minus, at(q[0], phi, q[1]), F, normal)


def stress_band(b, seg, sigma, rng, K=12, avoid=0.25):
    """Contacts crossing the band of ``seg`` carrying sigma·n in total: K contacts, each with
    force sigma·n·area/K, placed along the segment at fractions within [0.05, 0.5-avoid] and
    [0.5+avoid, 0.95] (away from the middle, where a crossing band may pass)."""
    d, n, length, area = pa.band_geometry(*seg)
    T = np.asarray(sigma) @ n
    fractions = np.r_[np.linspace(0.05, 0.5 - avoid, K // 2), np.linspace(0.5 + avoid, 0.95, K - K // 2)]
    p0 = np.asarray(seg[0], float)
    for f in fractions:
        q = p0 + f * length * d
        add_straddling(b, q, n, T * area / K, rng.uniform(0, 2 * math.pi), swap=rng.random() < 0.5,
                       vphi=rng.normal())
    return T


# ---------------------------------------------------------------------------------------------
# tests

class TestLoad(unittest.TestCase):
    def test_roundtrip_and_lookup(self):
        """load_snapshot returns the saved arrays; contacts refer to grains by YADE id (not row);
        list_snapshots sorts snap_<time>.npz by the time in the name."""
        b = Builder()
        a = b.grain((0.01, 0, 0.02))
        c = b.grain((0.01, 0, 0.018))
        b.contact(c, a, (0.01, 0, 0.019), (0, 0, 2.0))
        snap = b.snapshot()
        with tempfile.TemporaryDirectory() as d:
            for t in (12.5, 3.0):
                np.savez(os.path.join(d, 'snap_%08.3f.npz' % t), **snap)
            found = pa.list_snapshots(d)
            self.assertEqual([t for t, _ in found], [3.0, 12.5])
            s = pa.load_snapshot(found[0][1])
        np.testing.assert_array_equal(s['pos'], snap['pos'])
        np.testing.assert_array_equal(pa.body_index(s, [c, a, 999]), [1, 0, -1])
        self.assertEqual(s['c_force'].shape, (1, 3))
        self.assertEqual(s['time'], 1.0)


class TestBand(unittest.TestCase):
    def annulus_snapshot(self):
        """Horizontal annulus 0.01 ≤ r ≤ 0.03 at z = 0.02 (n = +e_z) with three crossing
        contacts and four that must be ignored."""
        b = Builder()
        z = 0.02
        # kept: force on the lower grain by the upper one, as (R_r, R_z) after projection
        add_straddling(b, (0.02, z), (0, 1), (0.3, -2.0), 0.0)
        add_straddling(b, (0.015, z), (0, 1), (-0.5, -1.0), math.pi / 2, swap=True)
        add_straddling(b, (0.025, z), (0, 1), (0.6, -0.4), math.pi, vphi=0.7)
        # ignored: both centres above; crossing outside the band (r > r1 and r < r0); wall
        up1, up2 = b.grain(at(0.02, 1.0, 0.023)), b.grain(at(0.021, 1.0, 0.0245))
        b.contact(up1, up2, at(0.0205, 1.0, 0.02375), (5, 5, 5))
        add_straddling(b, (0.035, z), (0, 1), (9.0, -9.0), 2.0)
        add_straddling(b, (0.005, z), (0, 1), (9.0, -9.0), 2.5)
        lone = b.grain(at(0.02, 3.0, 0.021))
        b.contact(lone, 99999, at(0.02, 3.0, 0.0199), (9, 9, 9))
        return b.snapshot()

    def test_annulus(self):
        """Horizontal annulus: n = (0, 1), area = pi·(r1² - r0²), T = sum(R_r, R_z)/area over
        the 3 crossing contacts inside the band (azimuthal parts, same-side pairs, contacts
        projecting outside the segment and contacts with unknown bodies ignored)."""
        snap = self.annulus_snapshot()
        res = pa.band_force_density(snap, (0.01, 0.02), (0.03, 0.02))
        area = math.pi * (0.03 ** 2 - 0.01 ** 2)
        self.assertEqual(res.count, 3)
        np.testing.assert_allclose(res.n, (0, 1), atol=0)
        self.assertAlmostEqual(res.area / area, 1, delta=EXACT)
        np.testing.assert_allclose(res.T, np.array([0.3 - 0.5 + 0.6, -2.0 - 1.0 - 0.4]) / area, rtol=EXACT)

    def test_reversed_segment(self):
        """Reversing the segment reverses n and the force density: n -> -n, T -> -T (the force
        of the other side), area unchanged."""
        snap = self.annulus_snapshot()
        fwd = pa.band_force_density(snap, (0.01, 0.02), (0.03, 0.02))
        rev = pa.band_force_density(snap, (0.03, 0.02), (0.01, 0.02))
        np.testing.assert_allclose(rev.n, -fwd.n, atol=0)
        np.testing.assert_allclose(rev.T, -fwd.T, rtol=EXACT)
        self.assertEqual(rev.count, fwd.count)

    def test_cylinder(self):
        """Cylinder r = 0.02, 0.01 ≤ z ≤ 0.03 drawn downward: n = +e_r, area = 2·pi·r·L,
        T = force of the outer grains on the inner ones / area, R_r taken along e_r of each
        contact point's own meridian half-plane."""
        b = Builder()
        forces = [(-1.0, 0.2), (-2.0, -0.3), (-0.5, 0.0), (-1.5, 1.0)]
        for k, (F, zc) in enumerate(zip(forces, (0.012, 0.018, 0.024, 0.029))):
            add_straddling(b, (0.02, zc), (1, 0), F, 0.4 + 1.5 * k, swap=k % 2 == 1, vphi=3.0)
        add_straddling(b, (0.02, 0.035), (1, 0), (7.0, 7.0), 0.1)      # above the band
        snap = b.snapshot()
        res = pa.band_force_density(snap, (0.02, 0.03), (0.02, 0.01))
        area = 2 * math.pi * 0.02 * 0.02
        np.testing.assert_allclose(res.n, (1, 0), atol=1e-17)
        self.assertAlmostEqual(res.area / area, 1, delta=EXACT)
        self.assertEqual(res.count, 4)
        np.testing.assert_allclose(res.T, np.sum(forces, axis=0) / area, rtol=EXACT)

    def test_cone_area_and_normal(self):
        """Cone band (0.01, 0.05) -> (0.04, 0.03): d = (3, -2)/sqrt(13), n = (2, 3)/sqrt(13)
        (up and out), area = pi·(r0 + r1)·L with L = 0.01·sqrt(13)."""
        d, n, L, area = pa.band_geometry((0.01, 0.05), (0.04, 0.03))
        s13 = math.sqrt(13)
        np.testing.assert_allclose(n, np.array([2, 3]) / s13, rtol=EXACT)
        self.assertAlmostEqual(L / (0.01 * s13), 1, delta=EXACT)
        self.assertAlmostEqual(area / (math.pi * 0.05 * 0.01 * s13), 1, delta=EXACT)
        with self.assertRaises(ValueError):
            pa.band_geometry((-0.01, 0), (0.01, 0))


def sigma_pairs_snapshot(sigma, seed=1):
    """Pairs of bands crossing at P = (0.03, 0.025) with contacts built from the meridian stress
    ``sigma`` (2x2, tension positive) so that each band carries exactly T = sigma·n."""
    rng = np.random.default_rng(seed)
    b = Builder()
    angle_pairs = [(0, -90), (20, -60), (-30, 45), (10, 80), (-75, 5)]
    pairs, T = [], []
    for a1, a2 in angle_pairs:
        centre = (0.03, 0.025 + 0.05 * len(pairs))     # separate the pairs vertically
        s1, s2 = pa.band_segment(centre, a1, 0.02), pa.band_segment(centre, a2, 0.02)
        T.append((stress_band(b, s1, sigma, rng), stress_band(b, s2, sigma, rng)))
        pairs.append((s1, s2))
    return b.snapshot(), pairs, T


class TestReciprocity(unittest.TestCase):
    def test_symmetric_stress(self):
        """Bands built from a symmetric meridian stress sigma carry T = sigma·n on each cone of
        any inclination, and n·T' = n·sigma·n' = n'·sigma·n = n'·T: relative difference
        |n·T' - n'·T|/sqrt(|T||T'|) at round-off for every pair."""
        sigma = np.array([[-120.0, 35.0], [35.0, -300.0]])
        snap, pairs, T = sigma_pairs_snapshot(sigma)
        res = pa.reciprocal_cuts(snap, pairs)
        for k, ((s1, s2), (T1, T2)) in enumerate(zip(pairs, T)):
            band1 = pa.band_force_density(snap, *s1)
            np.testing.assert_allclose(band1.T, T1, rtol=EXACT)
            n1 = pa.band_geometry(*s1)[1]
            n2 = pa.band_geometry(*s2)[1]
            self.assertAlmostEqual(res['nT2'][k] / (n1 @ sigma @ n2), 1, delta=EXACT)
            self.assertAlmostEqual(res['n2T'][k] / (n2 @ sigma @ n1), 1, delta=EXACT)
        self.assertEqual(res['n_pairs'], len(pairs))
        self.assertTrue(np.all(res['count'] == 12) and np.all(res['count2'] == 12))
        self.assertLess(res['rel_mean'], EXACT)
        self.assertLess(res['rel'].max(), EXACT)

    def test_statistic_on_asymmetric_tensor(self):
        """With a non-symmetric 'stress' s, the statistic equals |n·s·n' - n'·s·n| /
        sqrt(|s·n||s·n'|) pair by pair, and rel_mean is its mean."""
        s = np.array([[-100.0, 60.0], [-20.0, -250.0]])
        snap, pairs, _ = sigma_pairs_snapshot(s, seed=2)
        res = pa.reciprocal_cuts(snap, pairs)
        expect = []
        for s1, s2 in pairs:
            n1, n2 = pa.band_geometry(*s1)[1], pa.band_geometry(*s2)[1]
            a, b = n1 @ s @ n2, n2 @ s @ n1
            expect.append(abs(a - b) / math.sqrt(np.linalg.norm(s @ n1) * np.linalg.norm(s @ n2)))
        np.testing.assert_allclose(res['rel'], expect, rtol=1e-10)
        self.assertAlmostEqual(res['rel_mean'] / np.mean(expect), 1, delta=1e-10)

    def test_pairs_generator(self):
        """reciprocal_pairs: C(4, 2) = 6 pairs per centre, segments of the given length centred
        on the point; a centre too close to the axis is skipped."""
        pairs = pa.reciprocal_pairs([(0.03, 0.02), (0.001, 0.02)], length=0.01)
        self.assertEqual(len(pairs), 6)
        for seg1, seg2 in pairs:
            for p0, p1 in (seg1, seg2):
                np.testing.assert_allclose((p0 + p1) / 2, (0.03, 0.02), rtol=EXACT)
                self.assertAlmostEqual(np.hypot(*(p1 - p0)), 0.01, delta=1e-15)


class TestCylindricalCuts(unittest.TestCase):
    def test_directions(self):
        """Cylindrical cut at (r, z) built from stress sigma: T = sigma·e_r = (s_rr, s_rz); its
        angle from the vertical is atan(|s_rr|/|s_rz|) and its inclination, the line oriented
        outward, atan2(-s_rz, -s_rr) for s_rr < 0."""
        sigma = np.array([[-100.0, 40.0], [40.0, -300.0]])
        rng = np.random.default_rng(3)
        b = Builder()
        h = 0.01
        radii, heights = [0.02, 0.05], [0.02, 0.06]
        for r in radii:
            for z in heights:
                stress_band(b, ((r, z + h / 2), (r, z - h / 2)), sigma, rng, K=8, avoid=0.0)
        res = pa.cylindrical_cut_directions(b.snapshot(), radii, heights, h)
        np.testing.assert_allclose(res['Tr'], -100.0, rtol=EXACT)
        np.testing.assert_allclose(res['Tz'], 40.0, rtol=EXACT)
        np.testing.assert_allclose(res['angle_from_vertical_deg'], math.degrees(math.atan(100 / 40)), rtol=EXACT)
        np.testing.assert_allclose(res['inclination_deg'], math.degrees(math.atan2(-40, 100)), rtol=EXACT)
        self.assertTrue(np.all(res['count'] == 8))


class TestGroundPressure(unittest.TestCase):
    def floor_snapshot(self):
        """Four pile-on-paving contacts in rings 0, 0, 1 and 3 (width 1 cm) plus contacts to be
        ignored (pile-pile, paving-paving, wall)."""
        b = Builder(rho=1000.0, g=9.81)
        pave = [b.grain(at(0.005 * k, 0.3 * k, 0.0), 2e-3, fixed=True) for k in range(8)]
        pile = [b.grain(at(0.005 * k, 0.3 * k, 0.004), 2e-3) for k in range(8)]
        # (pile grain is body 1): force on paving by pile
        b.contact(pile[0], pave[0], at(0.004, 0.3, 0.002), (0.1, -0.2, -3.0))
        # (paving is body 1): force on the pile grain by the paving = -(force on paving)
        b.contact(pave[1], pile[1], at(0.006, 2.0, 0.002), (0.0, 0.0, 1.5))
        b.contact(pile[2], pave[2], at(0.015, 4.0, 0.002), (0.5, 0.0, -2.0))
        b.contact(pave[3], pile[3], at(0.035, 5.0, 0.002), (0.0, 0.3, 0.7))
        b.contact(pile[4], pile[5], at(0.005, 1.0, 0.003), (0, 0, -50.0))
        b.contact(pave[4], pave[5], at(0.005, 1.0, 0.001), (0, 0, -50.0))
        b.contact(pile[6], 424242, at(0.005, 1.0, 0.001), (0, 0, -50.0))
        return b.snapshot()

    def test_ring_pressures(self):
        """p_k = sum(load)/(pi·w²·((k+1)² - k²)), load = -F_z on the paving grain:
        ring 0: (3.0 + 1.5)/(pi w²), ring 1: 2.0/(3 pi w²), ring 2: 0, ring 3: 0.7/(7 pi w²);
        hydrostatic = rho_bulk·g·H; fractions p/(rho·g·H)."""
        snap = self.floor_snapshot()
        w = 0.01
        res = pa.ground_pressure(snap, w, n_sectors=4, rho_bulk=615.0, H=0.055)
        A = math.pi * w * w * np.array([1, 3, 5, 7])
        expect = np.array([4.5, 2.0, 0.0, 0.7]) / A
        np.testing.assert_allclose(res['pressure_Pa'], expect, rtol=EXACT)
        np.testing.assert_array_equal(res['n_contacts'], [2, 1, 0, 1])
        np.testing.assert_allclose(res['r_mid'], [0.005, 0.015, 0.025, 0.035], rtol=EXACT)
        self.assertAlmostEqual(res['hydrostatic_Pa'] / (615.0 * 9.81 * 0.055), 1, delta=EXACT)
        np.testing.assert_allclose(res['p_over_rho_grain_g_H'], expect / (1000.0 * 9.81 * 0.055), rtol=EXACT)
        self.assertAlmostEqual(res['total_load_N'], 4.5 + 2.0 + 0.7, delta=1e-14)

    def test_sector_error(self):
        """Error of ring 0 with 4 sectors: loads 3.0 (phi 0.3, sector 0) and 1.5 (phi 2.0,
        sector 1); sector pressures 4·(3, 1.5, 0, 0)/(pi w²); err = std(ddof=1)/sqrt(4)."""
        res = pa.ground_pressure(self.floor_snapshot(), 0.01, n_sectors=4, rho_bulk=1.0, H=1.0)
        sp = 4 * np.array([3.0, 1.5, 0.0, 0.0]) / (math.pi * 1e-4)
        self.assertAlmostEqual(res['err_Pa'][0] / (sp.std(ddof=1) / 2), 1, delta=EXACT)
        self.assertAlmostEqual(res['sector_pressure_Pa'][0].mean() / res['pressure_Pa'][0], 1, delta=EXACT)

    def test_r_max(self):
        """r_max = 0.02 keeps rings 0 and 1 only (the contact at r = 0.035 falls outside)."""
        res = pa.ground_pressure(self.floor_snapshot(), 0.01, r_max=0.02, rho_bulk=1.0, H=1.0)
        self.assertEqual(len(res['pressure_Pa']), 2)
        self.assertAlmostEqual(res['total_load_N'], 7.2, delta=1e-14)   # total over all rings


def cone_snapshot(H=0.055, alpha_deg=26.0, cap=None, foot=False, rng=None):
    """Grains whose tops lie exactly on z = H - r·tan(alpha) (centre at top - radius), on rings
    of radius r and many azimuths, plus buried grains below; ``cap`` = height fraction of a flat
    rounded apex replacing the cone above it; ``foot`` adds flat floor grains beyond the base."""
    rng = rng or np.random.default_rng(0)
    b = Builder()
    t = math.tan(math.radians(alpha_deg))
    R = H / t
    rad = 1.5e-3
    for r in np.arange(0.0005, R, 0.0011):
        top = H - r * t
        if cap is not None:
            top = min(top, cap * H)
        for phi in rng.uniform(0, 2 * math.pi, 6 + int(r * 600)):
            b.grain(at(r, phi, top - rad), rad)
            b.grain(at(r, phi, top - 4 * rad), rad)                # buried below it
    if foot:
        for r in np.arange(R + 0.002, R + 0.03, 0.002):
            for phi in np.linspace(0, 2 * math.pi, 40, endpoint=False):
                b.grain(at(r, phi, 0.0), rad)
    return b.snapshot(), R


class TestProfile(unittest.TestCase):
    def test_perfect_cone(self):
        """Tops on a straight line of slope 26°: fitted slope = 26° to round-off, base radius
        = H/tan 26°, apex height H, every sector slope = 26° (spread at round-off)."""
        snap, R = cone_snapshot()
        res = pa.profile_and_slope(snap, bin_width=0.002, z_floor=0.0)
        self.assertAlmostEqual(res['slope_deg'], 26.0, delta=26 * EXACT)
        self.assertAlmostEqual(res['base_radius'] / R, 1, delta=1e-11)
        self.assertAlmostEqual(res['H_cone'] / 0.055, 1, delta=1e-11)
        self.assertLess(res['slope_err_deg'], 1e-9)              # every bootstrap resample is exact
        self.assertEqual(res['slope_note'], '')
        self.assertEqual(len(res['slope_sector_deg']), 8)
        np.testing.assert_allclose(res['slope_sector_deg'], 26.0, rtol=EXACT)
        self.assertLess(res['H'], 0.055)
        self.assertGreater(res['H'], 0.055 - 0.0006 * math.tan(math.radians(26)))

    def test_rounded_apex_and_foot_left_out(self):
        """A flat cap at 0.9 H and a flat floor layer beyond the base: the cap grains near the
        flank are outliers the bisquare fit gives no weight, the foot lies below the 2 d
        thickness rule: the slope is still 26° to round-off; H is the cap height 0.9·0.055."""
        snap, R = cone_snapshot(cap=0.9, foot=True)
        res = pa.profile_and_slope(snap, bin_width=0.002, z_floor=0.0)
        self.assertAlmostEqual(res['slope_deg'], 26.0, delta=26 * EXACT)
        self.assertAlmostEqual(res['base_radius'] / R, 1, delta=1e-11)
        self.assertAlmostEqual(res['H'] / (0.9 * 0.055), 1, delta=EXACT)

    def test_floor_level(self):
        """floor_level = median of the paving tops z + radius: tops 0.002, 0.0027, 0.0025 ->
        0.0025; 0 without paving."""
        b = Builder(rho=1000.0)
        for k, (z, r) in enumerate(((0.001, 0.001), (0.0012, 0.0015), (0.0005, 0.002))):
            b.grain((0.05 + k * 0.01, 0, z), r, fixed=True)
        self.assertAlmostEqual(pa.floor_level(b.snapshot()), 0.0025, delta=1e-15)
        b2 = Builder()
        b2.grain((0, 0, 0.3))
        self.assertEqual(pa.floor_level(b2.snapshot()), 0.0)


class TestRest(unittest.TestCase):
    """rest_speed: a grain standing alone on the floor wall may roll (its horizontal speed is not
    counted); a grain touching another grain, a grain in flight and a vertical motion on the wall
    all count; unloaded (open) contacts do not make a grain touch anything."""

    def test_constructed(self):
        wall = 0                                               # id 0: no grain of the snapshot
        b = Builder()
        roller = b.grain((0, 0, 1e-3), vel=(1e-3, 2e-4, 0))
        b.contact(wall, roller, (0, 0, 0), (0, 0, 0.01))
        resting = b.grain((0.01, 0, 1e-3), vel=(0, 0, 1e-12))
        paving = b.grain((0.012, 0, 1e-3), fixed=True, vel=(5, 5, 5))     # fixed: never counted
        b.contact(wall, resting, (0.01, 0, 0), (0, 0, 0.01))
        b.contact(paving, resting, (0.011, 0, 1e-3), (-0.001, 0, 0.001))
        near = b.grain((0.002, 0, 1e-3), vel=(0, 0, 0))
        b.contact(roller, near, (0.001, 0, 1e-3), (0, 0, 0))  # open contact within the alert distance
        snap = b.snapshot()
        np.testing.assert_array_equal(pa.wall_only_grains(snap), [True, False, False, False])
        self.assertEqual(pa.rest_speed(snap), 1e-12)
        snap['vel'][0, 2] = 3e-9                               # the roller lifts off: that counts
        self.assertEqual(pa.rest_speed(snap), 3e-9)
        snap['vel'][0, 2] = 0
        snap['c_force'][3] = (0, 0, 0.001)                     # the roller now pushes on a grain
        self.assertFalse(pa.wall_only_grains(snap)[0])
        self.assertAlmostEqual(pa.rest_speed(snap), math.hypot(1e-3, 2e-4), delta=1e-15)
        flight = Builder()
        flight.grain((0, 0, 0.05), vel=(0, 0, -0.3))          # no contact at all: in flight
        self.assertEqual(pa.rest_speed(flight.snapshot()), 0.3)
        self.assertEqual(pa.rest_speed(Builder().snapshot()), 0.0)


class TestFabricSpeedFossil(unittest.TestCase):
    def test_orientation_histogram(self):
        """theta = angle of the normal (as a line) from the vertical: normals +z and -z -> bin 0,
        35° -> bin 3, horizontal -> last bin (9 bins of 10°); floor contacts excluded by
        default; density = counts/(N·(cos a - cos b))."""
        b = Builder()
        g = [b.grain((0.01 * k, 0, 0.01)) for k in range(6)]
        paving = b.grain((0, 0, 0), fixed=True)
        s35, c35 = math.sin(math.radians(35)), math.cos(math.radians(35))
        for k, n in enumerate([(0, 0, 1), (0, 0, -1), (s35, 0, c35), (0, 1, 0)]):
            b.contact(g[k], g[k + 1], (0.01 * k + 0.005, 0, 0.01), (1, 1, 1), n)
        b.contact(g[0], paving, (0, 0, 0.005), (0, 0, -1), (0, 0, -1))
        res = pa.contact_orientation_histogram(b.snapshot(), n_bins=9)
        np.testing.assert_array_equal(res['theta_counts'], [2, 0, 0, 1, 0, 0, 0, 0, 1])
        e = np.radians(res['theta_edges_deg'])
        self.assertAlmostEqual(res['theta_density'][0] / (2 / (4 * (1 - math.cos(e[1])))), 1, delta=EXACT)
        self.assertEqual(res['n_contacts'], 4)

    def test_fabric(self):
        """Fabric F = mean n⊗n: the six ±axis normals give F = I/3 and anisotropy 0; all
        normals vertical give F = e_z⊗e_z and anisotropy sqrt(3/2·D:D) = 1."""
        axes = np.vstack([np.eye(3), -np.eye(3)])
        iso = pa.fabric_tensor(axes)
        np.testing.assert_allclose(iso['fabric'], np.eye(3) / 3, atol=1e-16)
        self.assertLess(iso['anisotropy'], 1e-15)
        vert = pa.fabric_tensor([(0, 0, 1), (0, 0, -1)])
        self.assertAlmostEqual(vert['anisotropy'], 1, delta=EXACT)
        self.assertAlmostEqual(vert['fabric_zz'], 1, delta=EXACT)

    def test_meridian_orientation(self):
        """psi = orientation of the normal in the meridian plane of the contact point, from
        +e_r towards +e_z, folded into (-90, 90]: a normal along -e_r at azimuth 90° -> 0;
        normal (0, -1, 1)/sqrt(2) at azimuth 90° (e_r = +y) -> psi = 135° folded to -45°."""
        b = Builder()
        g = [b.grain((0, 0.01 * k, 0.01)) for k in range(3)]
        b.contact(g[0], g[1], (0, 0.02, 0.01), (1, 1, 1), (0, -1, 0))
        b.contact(g[1], g[2], (0, 0.02, 0.01), (1, 1, 1), (0, -math.sqrt(0.5), math.sqrt(0.5)))
        res = pa.contact_orientation_histogram(b.snapshot(), n_bins=9)
        edges = res['psi_edges_deg']
        k0 = np.searchsorted(edges, 0.0, side='right') - 1
        k45 = np.searchsorted(edges, -45.0, side='right') - 1
        self.assertEqual(res['psi_counts'][k0], 1)
        self.assertEqual(res['psi_counts'][k45], 1)

    def test_speed_levels(self):
        """Thresholds vmax·0.18^k, k = 1..4; class = number of thresholds ≥ speed (0 black,
        4 white); fixed grains (speed 0) are white."""
        b = Builder()
        vmax = 0.236
        speeds = [vmax, 1.01 * 0.18 * vmax, 0.99 * 0.18 * vmax, 0.5 * 0.18 ** 2 * vmax,
                  0.5 * 0.18 ** 3 * vmax, 0.5 * 0.18 ** 4 * vmax, 0.0]
        for v in speeds:
            b.grain((0, 0, 0), vel=(0.6 * v, 0, -0.8 * v))
        b.grain((0, 0, 0), fixed=True)
        res = pa.speed_levels(b.snapshot())
        self.assertAlmostEqual(res['vmax'] / vmax, 1, delta=EXACT)
        np.testing.assert_allclose(res['thresholds'], vmax * 0.18 ** np.arange(1, 5), rtol=EXACT)
        np.testing.assert_array_equal(res['level'], [0, 0, 1, 2, 3, 4, 4, 4])
        np.testing.assert_allclose(res['grey'][:3], [0, 0, 0.25])

    def test_fossil(self):
        """Fossil layer = non-fixed grains with t1 ≤ birth ≤ t2."""
        b = Builder()
        for t in (1.0, 15.5, 17.0, 18.7, 19.0):
            b.grain((0, 0, 0), birth=t)
        b.grain((0, 0, 0), fixed=True)
        np.testing.assert_array_equal(pa.fossil_layer(b.snapshot(), 15.5, 18.7),
                                      [False, True, True, True, False, False])
        np.testing.assert_array_equal(pa.fossil_layer(b.snapshot(), -2, 0.5), [False] * 6)


# ---------------------------------------------------------------------------------------------
# a synthetic run for the whole pipeline

def lattice_pile(H=0.025, alpha_deg=26.0, spacing=0.004, t_end=10.0, seed=0):
    """A simple-cubic lattice pile of touching grains (radius spacing/2) filling the cone
    z ≤ H - r·tan(alpha) on a fixed paving layer at z = 0, with the forces of independent
    columns: each vertical contact carries the weight of the grains above it in its column,
    horizontal contacts carry 0.4 of the vertical force below them, so the floor carries exactly
    the pile weight. Births grow with height, speeds are small except on the surface."""
    rng = np.random.default_rng(seed)
    b = Builder(rho=1000.0, g=9.81, time=t_end)
    rad = spacing / 2
    mass = b.rho * 4 / 3 * math.pi * rad ** 3
    t = math.tan(math.radians(alpha_deg))
    n = int(H / t / spacing) + 3
    site = {}
    for i in range(-n, n + 1):
        for j in range(-n, n + 1):
            r = spacing * math.hypot(i, j)
            site[i, j, 0] = b.grain((i * spacing, j * spacing, 0.0), rad, fixed=True)
            k = 1
            while k * spacing <= H - r * t:
                z = k * spacing
                speed = 0.2 if (k + 1) * spacing > H - r * t else 1e-4
                site[i, j, k] = b.grain((i * spacing, j * spacing, z), rad,
                                        vel=rng.normal(0, speed, 3), birth=t_end * 0.9 * z / H + rng.uniform(0, 0.5))
                k += 1
    row = {gid: k for k, gid in enumerate(g[5] for g in b.grains)}
    for (i, j, k), gid in site.items():
        above = sum(1 for kk in range(k + 1, k + 400) if (i, j, kk) in site)
        if (i, j, k + 1) in site:        # vertical: body 1 below, force on the upper grain (body 2)
            f = mass * b.g * above
            b.contact(gid, site[i, j, k + 1], (i * spacing, j * spacing, (k + 0.5) * spacing), (0, 0, f), (0, 0, 1))
        if k == 0:
            continue
        for di, dj in ((1, 0), (0, 1)):
            other = site.get((i + di, j + dj, k))
            if other is not None:
                f = 0.4 * mass * b.g * (above + 1) * (1 + 0.2 * rng.random())
                point = ((i + di / 2) * spacing, (j + dj / 2) * spacing, k * spacing)
                b.contact(gid, other, point, (f * di, f * dj, 0.0), (di, dj, 0))
    return b, row


def write_run(run_dir, times=(6.0, 10.0)):
    """A run directory: snap_<t>.npz for each time (the pile restricted to grains born by then,
    with their contacts) and run.json."""
    b, _ = lattice_pile(t_end=max(times))
    full = b.snapshot()
    for t in times:
        keep = full['fixed'] | (full['birth'] <= t)
        ids = set(full['ids'][keep].tolist())
        ck = np.array([a in ids and c in ids for a, c in zip(full['c_id1'], full['c_id2'])], bool)
        snap = {k: (v[keep] if k in ('pos', 'radius', 'vel', 'fixed', 'birth', 'ids') else
                    v[ck] if k.startswith('c_') else v) for k, v in full.items()}
        snap['time'] = t
        np.savez(os.path.join(run_dir, 'snap_%08.3f.npz' % t), **snap)
    with open(os.path.join(run_dir, 'run.json'), 'w') as f:
        json.dump({'synthetic': True, 'rho': 1000.0}, f)


def have_matplotlib():
    try:
        import matplotlib  # noqa: F401
        return True
    except ImportError:
        return False


@unittest.skipUnless(have_matplotlib(), 'matplotlib not available')
class TestPipeline(unittest.TestCase):
    def test_analyse_synthetic_run(self):
        """Whole pipeline on a lattice pile: every figure and summary.json written; the floor
        load equals the pile weight (sum of column weights, exact to round-off); the slope of
        a staircase cone of 26° lies within a few degrees of 26°."""
        from yadecd.analysis import report as pf
        with tempfile.TemporaryDirectory() as d:
            write_run(d)
            out = os.path.join(d, 'fig')
            s = pf.analyse(d, out, fossil=(2.0, 4.0), band_length=0.008)
            for name in s['figures'] + ['summary.json']:
                self.assertGreater(os.path.getsize(os.path.join(out, name)), 1000, name)
            with open(os.path.join(out, 'summary.json')) as f:
                saved = json.load(f)
        self.assertEqual(len(s['figures']), 8)
        self.assertAlmostEqual(saved['floor_load_over_weight'], 1, delta=1e-12)
        self.assertLess(abs(saved['slope_deg'] - 26), 4)
        self.assertEqual(saved['fig2_times_s'], [6.0, 10.0])
        for key in ('slope_err_deg', 'H_cm', 'base_radius_m', 'p_center_Pa', 'p_center_dPa',
                    'p_peak_Pa', 'p_peak_radius_m', 'hydrostatic_Pa', 'rho_bulk_kg_m3'):
            self.assertIsNotNone(saved[key], key)
        self.assertGreater(saved['reciprocity']['n_pairs'], 0)
        self.assertTrue(saved['run_parameters']['synthetic'])


    @unittest.skipUnless(os.path.exists('/usr/bin/python3'), 'needs /usr/bin/python3')
    def test_command_line_without_yade(self):
        """scripts/pile_figures.py RUN --fossil T1 T2 --out DIR runs under /usr/bin/python3 with
        'yade' and 'yadecd' made unimportable (it must load the modules from their files)."""
        import subprocess
        script = os.path.join(SCRIPTS, 'pile_figures.py')
        with tempfile.TemporaryDirectory() as d:
            write_run(d)
            trap = os.path.join(d, 'trap')
            for name in ('yade', 'yadecd'):
                os.makedirs(os.path.join(trap, name))
                with open(os.path.join(trap, name, '__init__.py'), 'w') as f:
                    f.write('raise ImportError("%s must not be imported")\n' % name)
            env = dict(os.environ, PYTHONPATH=trap, MPLBACKEND='Agg')
            out = os.path.join(d, 'out')
            proc = subprocess.run(['/usr/bin/python3', script, d, '--fossil', '2', '4', '--out', out],
                                  env=env, capture_output=True, text=True, timeout=300)
            self.assertEqual(proc.returncode, 0, proc.stderr)
            self.assertIn('slope', proc.stdout)
            with open(os.path.join(out, 'summary.json')) as f:
                self.assertEqual(json.load(f)['fossil_layers_s'], [[2.0, 4.0]])

if __name__ == '__main__':
    unittest.main()

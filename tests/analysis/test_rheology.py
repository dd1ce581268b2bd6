"""The rheology fits (yadecd.analysis.rheology) on constructed runs with known laws: exact
points give the law back exactly; noisy points with honest error bars give it within two of
the fit's own errors; an outlier with a tiny error bar inflates χ² and the errors instead of
pinning the fit; fewer than three points give no fit; the records of a directory are read."""
import json
import math
import os
import shutil
import tempfile
import unittest

import numpy as np

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd.analysis import rheology


def record(method, I, mu, phi, mu_err=0.002, phi_err=0.001):
    return dict(method=method, I=I, I_err=0.0, mu=mu, mu_err=mu_err, phi=phi, phi_err=phi_err)


class TestFits(unittest.TestCase):

    def test_exact_law(self):
        I = [0.003, 0.01, 0.03, 0.1]
        rs = [record('cd', i, 0.38 + 0.9 * i, 0.59 - 0.35 * i) for i in I]
        f = rheology.fit_laws(rs, 'cd')
        for key, want in (('mu_s', 0.38), ('b', 0.9), ('phi_c', 0.59), ('a', 0.35)):
            self.assertAlmostEqual(f[key], want, delta=1e-12)
        self.assertEqual(f['points'], 4)
        self.assertLess(f['chi2_mu'], 1e-20)

    def test_noisy_law_within_its_errors(self):
        rng = np.random.default_rng(4)
        I = np.array([0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1])
        hits = 0
        for _ in range(200):
            rs = [record('md', i, 0.38 + 0.9 * i + rng.normal(0, 0.004), 0.59 - 0.35 * i + rng.normal(0, 0.002), 0.004, 0.002)
                  for i in I]
            f = rheology.fit_laws(rs, 'md')
            hits += abs(f['mu_s'] - 0.38) < 2 * f['mu_s_err'] and abs(f['a'] - 0.35) < 2 * f['a_err']
        self.assertGreater(hits / 200, 0.85)        # two 95 % intervals jointly: about 0.9

    def test_outlier_inflates_the_errors(self):
        I = [0.003, 0.01, 0.03, 0.1]
        clean = [record('cd', i, 0.38 + 0.9 * i, 0.59) for i in I]
        bad = [dict(r) for r in clean]
        bad[1]['mu'] += 0.05                       # 25 error bars off
        f = rheology.fit_laws(bad, 'cd')
        self.assertGreater(f['chi2_mu'], 100)
        self.assertGreater(f['mu_s_err'], 10 * rheology.fit_laws([dict(r, mu=r['mu'] + 1e-4 * k) for k, r in enumerate(clean)], 'cd')['mu_s_err'])

    def test_too_few_points_and_other_methods(self):
        rs = [record('cd', 0.01, 0.39, 0.58), record('cd', 0.1, 0.45, 0.55), record('md', 0.03, 0.4, 0.57)]
        f = rheology.fit_laws(rs, 'cd')
        self.assertTrue(math.isnan(f['mu_s']))
        self.assertEqual(f['points'], 2)

    def test_literature_law(self):
        mu_s, mu_2, I0 = rheology.LITERATURE['jop2006'][:3]
        self.assertAlmostEqual(float(rheology.mu_of_I(I0, mu_s, mu_2, I0)), 0.5 * (mu_s + mu_2), delta=1e-15)
        self.assertAlmostEqual(float(rheology.mu_of_I(1e-9, mu_s, mu_2, I0)), mu_s, delta=1e-8)


class TestRecords(unittest.TestCase):

    def test_load_and_table(self):
        tmp = tempfile.mkdtemp(prefix='cd-rheology-')
        try:
            for method, I in (('cd', 0.01), ('md', 0.01), ('cd', 0.1)):
                bm = lambda m, e: dict(mean=m, sem=e, drift_z=0.1)   # noqa: E731
                rec = dict(method=method, I=I, n=2000, steps=1000, wall_s=10.0, dt=1e-5, ti=1e-3, p=2500.0,
                           summary=dict(samples=200, I=bm(I, 1e-4), mu=bm(0.4, 0.003), phi=bm(0.58, 0.001),
                                        normal_stress=bm(2500.0, 10.0), sweeps=50.0))
                with open(os.path.join(tmp, '%s_I%g_n2000_s1.json' % (method, I)), 'w') as f:
                    json.dump(rec, f)
            rs = rheology.load_records(tmp)
            self.assertEqual([(r['method'], r['I']) for r in rs], [('cd', 0.01), ('cd', 0.1), ('md', 0.01)])
            text = rheology.table_markdown(rs)
            self.assertEqual(len(text.strip().splitlines()), 5)
            self.assertIn('| CD | 0.01 ± 0.0001 | 0.4000 ± 0.0030 | 0.5800 ± 0.0010 |', text)
            self.assertNotIn('not steady', text)
            self.assertEqual(rheology.drift_cell(dict(mu_drift=0.5, phi_drift=-4.9, I_drift=None)), '0.5, -4.9, – (not steady)')
            path = rheology.figure(rs, os.path.join(tmp, 'f.png'), {'cd': rheology.fit_laws(rs, 'cd')})
            self.assertGreater(os.path.getsize(path), 1000)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def test_variants_are_compared_not_fitted(self):
        """A run off the reference protocol (here CD with e_n = 0.1, MD with E = 1e6·p) is left out of
        the table of reference runs, of the fits and of the figure, and compared with the reference
        run of its method at the same nominal I: Δμ = 0.43 − 0.38 = 0.05 with σ = hypot(0.003, 0.004)
        = 0.005, z = 10; a variant without a reference run gets dashes. Unknown options are refused."""
        tmp = tempfile.mkdtemp(prefix='cd-rheology-')
        try:
            bm = lambda m, e: dict(mean=m, sem=e, drift_z=0.1)   # noqa: E731

            def write(name, method, I, mu, mu_err, options):
                rec = dict(method=method, I=I, n=2000, steps=1000, wall_s=10.0, dt=1e-5, ti=1e-3, p=2500.0, strain=3.0,
                           options=options, summary=dict(samples=200, I=bm(I, 1e-4), mu=bm(mu, mu_err), phi=bm(0.58, 0.001),
                                                         normal_stress=bm(2500.0, 10.0), sweeps=50.0, skip_strain=1.0))
                with open(os.path.join(tmp, name + '.json'), 'w') as f:
                    json.dump(rec, f)

            for k, I in enumerate((0.01, 0.03, 0.1)):       # reference CD runs on the line μ = 0.35 + I
                write('cd_I%g_n2000_s1' % I, 'cd', I, 0.35 + I, 0.003, dict(dgamma=5e-4, dt_max=0.05, tolerance=1e-3))
            write('cd_I0.03_n2000_s1_en0.1', 'cd', 0.03, 0.43, 0.004, dict(dgamma=5e-4, dt_max=0.05, tolerance=1e-3, en_cd=0.1))
            write('md_I0.03_n2000_s1_stiff', 'md', 0.03, 0.40, 0.004, dict(young_over_p=1e6, en_md=0.1))
            with open(os.path.join(tmp, 'cd_I0.3_n2000_s1.ckpt.json'), 'w') as f:     # a checkpoint: not a record
                json.dump(dict(method='cd', I=0.3, samples=20), f)
            rs = rheology.load_records(tmp)
            self.assertEqual(sorted(r['variant'] for r in rs), ['', '', '', 'en_cd=0.1', 'young_over_p=1e+06'])
            fit = rheology.fit_laws(rs, 'cd')
            self.assertEqual(fit['points'], 3)
            self.assertAlmostEqual(fit['mu_s'], 0.35, delta=1e-12)
            self.assertAlmostEqual(fit['b'], 1.0, delta=1e-10)
            self.assertTrue(math.isnan(rheology.fit_laws(rs, 'md')['mu_s']))
            self.assertEqual(len(rheology.table_markdown(rs).strip().splitlines()), 2 + 3)
            text = rheology.variants_markdown(rs)
            lines = text.strip().splitlines()
            self.assertEqual(len(lines), 2 + 2)
            cd_row = [line for line in lines if 'en_cd=0.1' in line][0]
            self.assertIn('| +0.0500 ± 0.0050 (z +10.0) | +0.0000 ± 0.0014 (z +0.0) |', cd_row)
            md_row = [line for line in lines if 'young_over_p' in line][0]
            self.assertIn('| – | – | – |', md_row)
            self.assertEqual(rheology.variants_markdown([r for r in rs if not r['variant']]), '')
            self.assertEqual(rheology.variant_of('md', {'en_md': 0.1}), '')
            # records made before an option existed have its reference value
            self.assertEqual(rheology.variant_of('md', {'young_over_p': 1e5, 'en_md': 0.1}), '')
            self.assertEqual(rheology.variant_of('md', {'young_over_p': 1e5, 'en_md': 0.1, 'es_md': 1.0, 'safety': 0.25}),
                             'es_md=1, safety=0.25')
            with self.assertRaisesRegex(ValueError, 'unknown cd shear option.*damping'):
                rheology.variant_of('cd', {'damping': 0.2})
        finally:
            shutil.rmtree(tmp, ignore_errors=True)


class TestCoulombExcess(unittest.TestCase):
    """rheology.coulomb_excess on constructed forces with known answers."""

    def test_known_excess(self):
        # mu = 0.5; loaded contacts: at the bound (not over), inside it (ratio 0.4), 20 % over, 100 % over;
        # an open contact (F_n = 0, F_t = 0) and one with F_n = 0 but F_t > 0 (not loaded: left out)
        fn = [2.0, 5.0, 1.0, 4.0, 0.0, 0.0]
        ft = [1.0, 1.0, 0.6, 4.0, 0.0, 3.0]
        e = rheology.coulomb_excess(fn, ft, 0.5)
        self.assertEqual(e['loaded'], 4)
        self.assertAlmostEqual(e['over'], 0.5, places=15)
        self.assertAlmostEqual(e['excess_mean'], (0.2 + 1.0) / 2, places=14)
        self.assertAlmostEqual(e['excess_max'], 1.0, places=14)
        self.assertAlmostEqual(e['mobilised'], (1.0 + 0.4 + 1.0 + 1.0) / 4, places=14)
        self.assertAlmostEqual(e['tangential_share'], (0.1 + 2.0) / (1.0 + 1.0 + 0.6 + 4.0), places=14)

    def test_tolerance_and_edges(self):
        # a rounding-level excess is within rtol; no loaded contact gives zeros and nan mobilisation
        e = rheology.coulomb_excess([1.0], [0.5 * (1 + 1e-9)], 0.5)
        self.assertEqual(e['over'], 0.0)
        self.assertEqual(rheology.coulomb_excess([1.0], [0.5 * (1 + 1e-3)], 0.5)['over'], 1.0)
        e = rheology.coulomb_excess([0.0, 0.0], [0.0, 1.0], 0.5)
        self.assertEqual((e['loaded'], e['over'], e['excess_mean']), (0, 0.0, 0.0))
        self.assertTrue(math.isnan(e['mobilised']))
        with self.assertRaisesRegex(ValueError, '2 normal and 1 tangential'):
            rheology.coulomb_excess([1.0, 1.0], [0.1], 0.5)
        with self.assertRaisesRegex(ValueError, 'non-negative'):
            rheology.coulomb_excess([-1.0], [0.1], 0.5)
        with self.assertRaisesRegex(ValueError, 'friction coefficient'):
            rheology.coulomb_excess([1.0], [0.1], 0.0)


class TestSolverWork(unittest.TestCase):

    def test_constructed_runs(self):
        """Samples every 20 steps at a strain of 1e-4 per step (10 000 steps per unit strain); a
        sample's sweeps per step alternate 100 and 300: over the window (0.01, 0.05] the 20
        samples average 200 sweeps, 2e6 sweeps per unit strain; a run at half the step with a
        quarter of the sweeps does half the work. Samples outside the window do not count; an
        empty window is refused."""
        def run(per_step, sweeps):
            return [dict(step=20.0 * k, strain=20 * per_step * k, sweeps=sweeps[k % 2]) for k in range(1, 61)]
        a = rheology.solver_work(run(1e-4, (100.0, 300.0)), 0.01, 0.05)
        self.assertEqual(a['samples'], 20)
        self.assertAlmostEqual(a['sweeps_per_step'], 200.0, delta=1e-12)
        self.assertAlmostEqual(a['steps_per_strain'], 1e4, delta=1e-6)
        self.assertAlmostEqual(a['sweeps_per_strain'], 2e6, delta=1e-3)
        b = rheology.solver_work(run(5e-5, (25.0, 75.0)), 0.01, 0.05)
        self.assertAlmostEqual(b['sweeps_per_strain'] / a['sweeps_per_strain'], 0.5, delta=1e-12)
        with self.assertRaisesRegex(ValueError, r'1 sample\(s\) in the strain window'):
            rheology.solver_work(run(1e-4, (1.0, 1.0)), 0.1185, 0.1205)


if __name__ == '__main__':
    unittest.main()

"""The size trend of a pile observable (yadecd.analysis.stats.size_trend): the slope of per-pile
values against log10 of the grain count, with a pooled Student-t interval and a Welch–Satterthwaite
one, on constructed ensembles whose answer is known: an exact line, the intervals' coverage with
the same and with a size-dependent scatter, the false-dip rate when nothing changes with size, and
the awkward parts of real ensembles (a size with one pile, unequal seed counts, an outlier, a
value that is not a number). Also the t quantile for any real degrees of freedom."""
import math
import unittest

import numpy as np

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd.analysis.stats import line_prediction, size_trend, t_cdf, t_quantile, t_quantile_975

SIZES = np.repeat([300, 1000, 2000, 5000], 8).astype(float)   # the sphere ensembles' design
BETA = 0.1                                                      # slope per decade of grains


class TestQuantile(unittest.TestCase):

    def test_known_values(self):
        # textbook values (Student's table): t_0.975 for 1, 2, 8 and 30 degrees of freedom, t_0.95 for 2
        for p, df, t in ((0.975, 1, 12.7062), (0.975, 2, 4.3027), (0.975, 8, 2.3060), (0.975, 30, 2.0423),
                         (0.95, 2, 2.9200)):
            self.assertAlmostEqual(t_quantile(p, df), t, places=4)
            self.assertAlmostEqual(t_quantile(1 - p, df), -t, places=4)
        for df in range(1, 31):
            self.assertAlmostEqual(t_quantile(0.975, df), t_quantile_975(df), places=3)

    def test_real_degrees_of_freedom(self):
        for df in (0.7, 3.5, 8.07, 14.6, 250.0):
            for p in (0.01, 0.3, 0.5, 0.9, 0.975):
                self.assertAlmostEqual(t_cdf(t_quantile(p, df), df), p, places=9)

    def test_refusals(self):
        for p, df in ((0, 3), (1, 3), (0.5, 0), (0.975, -1), (float('nan'), 3)):
            with self.assertRaisesRegex(ValueError, 't_quantile'):
                t_quantile(p, df)


class TestSizeTrend(unittest.TestCase):

    def test_exact_line(self):
        y = 0.3 - 0.2 * np.log10(SIZES)
        o = size_trend(SIZES, y)
        self.assertAlmostEqual(o['slope'], -0.2, places=12)
        self.assertAlmostEqual(o['intercept'], 0.3, places=12)
        self.assertAlmostEqual(o['slope_welch'], -0.2, places=12)
        self.assertLess(o['se'], 1e-12)
        self.assertEqual(o['se_welch'], 0.0)
        self.assertLess(o['confidence_t'], 1e-9)
        self.assertEqual(o['confidence_welch'], 0.0)
        self.assertEqual(o['sizes'], {300: 8, 1000: 8, 2000: 8, 5000: 8})
        self.assertEqual((o['n_piles'], o['single_sizes']), (32, []))

    def coverage(self, sd, beta, reps, seed):
        """Share of constructed ensembles whose 95 % intervals hold the true slope, and share whose
        one-sided confidence of a positive slope exceeds 0.95."""
        rng = np.random.default_rng(seed)
        hit_t = hit_w = pos_t = pos_w = 0
        for _ in range(reps):
            y = 0.05 + beta * np.log10(SIZES) + rng.normal(size=SIZES.size) * sd
            o = size_trend(SIZES, y)
            hit_t += o['ci95_t'][0] <= beta <= o['ci95_t'][1]
            hit_w += o['ci95_welch'][0] <= beta <= o['ci95_welch'][1]
            pos_t += o['confidence_t'] > 0.95
            pos_w += o['confidence_welch'] > 0.95
        return hit_t / reps, hit_w / reps, pos_t / reps, pos_w / reps

    # 1 000 constructed ensembles: a share's binomial error at 0.95 is 0.0069, at 0.05 the same;
    # the bands below are three of those errors wide on each side.

    def test_coverage_same_scatter(self):
        """Scatter 0.25 at every size (the 5000-grain piles' D): both intervals hold the slope 95 %
        of the time (the t interval exactly, in law)."""
        cov_t, cov_w, _, _ = self.coverage(0.25, BETA, 1000, seed=11)
        self.assertTrue(0.929 <= cov_t <= 0.971, cov_t)
        self.assertTrue(0.929 <= cov_w <= 0.971, cov_w)

    def test_coverage_scatter_falls_with_size(self):
        """Scatter 0.5·(300/N)^½, four times larger at 300 grains than at 5000: the pooled t
        interval is too short (it spreads the small piles' scatter over all), Welch's holds."""
        cov_t, cov_w, _, _ = self.coverage(0.5 * np.sqrt(300 / SIZES), BETA, 1000, seed=12)
        self.assertTrue(0.929 <= cov_w <= 0.971, cov_w)
        self.assertLess(cov_t, 0.929)

    def test_no_trend_false_alarms(self):
        """Nothing changes with size: a confidence above 95 % that the dip deepens comes 5 % of the time."""
        _, _, pos_t, pos_w = self.coverage(0.25, 0.0, 1000, seed=13)
        self.assertTrue(0.029 <= pos_t <= 0.071, pos_t)
        self.assertTrue(0.029 <= pos_w <= 0.071, pos_w)

    def test_awkward_ensembles(self):
        """A full pile alone at 14 000 grains, 2000-grain seeds missing, one value not a number and
        an outlier: the pooled fit is the least-squares line over the finite values (numpy's), the
        Welch fit the same over the sizes with two piles or more."""
        rng = np.random.default_rng(3)
        n = np.array([300] * 8 + [1000] * 8 + [2000] * 3 + [5000] * 8 + [14000], dtype=float)
        y = 0.1 * np.log10(n) + rng.normal(size=n.size) * 0.2
        y[9] = float('nan')
        y[20] = 3.0                                      # an outlier among the 5000-grain piles
        o = size_trend(n, y)
        ok = np.isfinite(y)
        b, a = np.polyfit(np.log10(n[ok]), y[ok], 1)
        self.assertAlmostEqual(o['slope'], b, places=12)
        self.assertAlmostEqual(o['intercept'], a, places=12)
        x = np.log10(n[ok])
        residuals = y[ok] - (a + b * x)
        se = math.sqrt((residuals ** 2).sum() / (x.size - 2) / ((x - x.mean()) ** 2).sum())   # the slope's standard error
        self.assertAlmostEqual(o['se'], se, places=12)
        self.assertEqual(o['sizes'], {300: 8, 1000: 7, 2000: 3, 5000: 8, 14000: 1})
        self.assertEqual((o['n_piles'], o['single_sizes']), (27, [14000]))
        rep = ok & (n < 14000)
        bw = np.polyfit(np.log10(n[rep]), y[rep], 1)[0]
        self.assertAlmostEqual(o['slope_welch'], bw, places=12)
        # the interval is symmetric about the slope, and the outlier's size dominates the Welch variance
        lo, hi = o['ci95_welch']
        self.assertAlmostEqual(0.5 * (lo + hi), bw, places=12)
        self.assertGreater(o['se_welch'], o['se'])
        self.assertLess(o['df_welch'], 20)

    def test_degenerate(self):
        o = size_trend([2000] * 8, np.linspace(0, 1, 8))
        self.assertTrue(math.isnan(o['slope']) and math.isnan(o['slope_welch']))
        o = size_trend([1000, 2000, 2000, 5000], [0.1, 0.2, 0.3, 0.2])  # one size replicated only
        self.assertTrue(math.isfinite(o['slope']) and math.isnan(o['slope_welch']))
        self.assertEqual(o['single_sizes'], [1000, 5000])
        with self.assertRaisesRegex(ValueError, '3 grain counts for 2 values'):
            size_trend([1, 2, 3], [0.0, 1.0])
        with self.assertRaisesRegex(ValueError, 'positive'):
            size_trend([0, 1000], [0.1, 0.2])


def small_design():
    """Seven piles at three log-sizes: x, y, the design matrix, the least-squares coefficients and
    the residual variance, computed directly (the reference for line_prediction)."""
    x = np.array([3.0, 3.0, 3.3, 3.3, 3.7, 3.7, 3.7])
    y = np.array([0.1, 0.3, -0.2, 0.2, -0.1, -0.4, 0.0])
    X = np.column_stack([np.ones_like(x), x])
    coef = np.linalg.lstsq(X, y, rcond=None)[0]
    return x, y, X, coef, ((y - X @ coef) ** 2).sum() / (len(x) - 2)


class TestLinePrediction(unittest.TestCase):
    """Where a line puts one new pile, with the interval a single new value may fall in."""

    def test_matrix_form(self):
        """The same as s²·(1 + x0ᵀ(XᵀX)⁻¹x0) from the design matrix, at a point inside and one far outside."""
        x, y, X, coef, s2 = small_design()
        for x0 in (3.4, 4.146):
            v = np.array([1.0, x0])
            p = line_prediction(x, y, x0)
            self.assertAlmostEqual(p['value'], v @ coef, places=12)
            self.assertAlmostEqual(p['se'], math.sqrt(s2 * (1 + v @ np.linalg.inv(X.T @ X) @ v)), places=12)
            self.assertAlmostEqual(p['ci95'][1] - p['value'], t_quantile(0.975, 5) * p['se'], places=12)
        # extrapolating is wider than interpolating
        self.assertGreater(line_prediction(x, y, 4.146)['se'], line_prediction(x, y, 3.4)['se'])

    def test_coverage_of_a_new_pile(self):
        """A new value at 14 000 grains from a line fitted on 1000-5000 grains (eight each): inside
        the 95 % interval 95 % of the time (1 000 draws; 0.929-0.971 is three binomial errors)."""
        rng = np.random.default_rng(21)
        x = np.log10(np.repeat([1000.0, 2000.0, 5000.0], 8))
        x0 = math.log10(14000)
        hits = 0
        for _ in range(1000):
            y = 0.2 - 0.1 * x + rng.normal(size=x.size) * 0.25
            p = line_prediction(x, y, x0)
            y0 = 0.2 - 0.1 * x0 + rng.normal() * 0.25
            hits += p['ci95'][0] <= y0 <= p['ci95'][1]
        self.assertTrue(0.929 <= hits / 1000 <= 0.971, hits)

    def test_mean_of_m_matrix_form(self):
        """The mean of m new values: s²·(1/m + x0ᵀ(XᵀX)⁻¹x0); m = 1 is the single value above."""
        x, y, X, coef, s2 = small_design()
        v = np.array([1.0, 4.146])
        for m in (1, 3, 8):
            p = line_prediction(x, y, 4.146, m=m)
            self.assertEqual(p['m'], m)
            self.assertAlmostEqual(p['value'], v @ coef, places=12)
            self.assertAlmostEqual(p['se'], math.sqrt(s2 * (1 / m + v @ np.linalg.inv(X.T @ X) @ v)), places=12)
        # more new piles averaged: narrower, but never below the line's own uncertainty
        self.assertLess(line_prediction(x, y, 4.146, m=3)['se'], line_prediction(x, y, 4.146)['se'])
        self.assertGreater(line_prediction(x, y, 4.146, m=3)['se'] ** 2, s2 * (v @ np.linalg.inv(X.T @ X) @ v))

    def test_coverage_of_the_mean_of_three_new_piles(self):
        """The mean of three new values at 14 000 grains (the three full-size seeds) from a line on
        1000-5000 grains, eight each: inside its 95 % interval 95 % of the time (1 000 draws,
        0.929-0.971), and the single-value interval would over-cover it (it is too wide)."""
        rng = np.random.default_rng(22)
        x = np.log10(np.repeat([1000.0, 2000.0, 5000.0], 8))
        x0 = math.log10(14000)
        hits = hits_single = 0
        for _ in range(1000):
            y = 0.2 - 0.1 * x + rng.normal(size=x.size) * 0.25
            p = line_prediction(x, y, x0, m=3)
            p1 = line_prediction(x, y, x0)
            y0 = (0.2 - 0.1 * x0 + rng.normal(size=3) * 0.25).mean()
            hits += p['ci95'][0] <= y0 <= p['ci95'][1]
            hits_single += p1['ci95'][0] <= y0 <= p1['ci95'][1]
        self.assertTrue(0.929 <= hits / 1000 <= 0.971, hits)
        self.assertGreater(hits_single / 1000, 0.975)

    def test_bad_m(self):
        for m in (0, -1, 2.5, True, '3'):
            with self.assertRaisesRegex(ValueError, 'm .new values averaged. must be a positive integer'):
                line_prediction([1.0, 2.0, 3.0], [0.0, 1.0, 1.5], 4.0, m=m)

    def test_degenerate(self):
        self.assertTrue(math.isnan(line_prediction([1.0, 2.0], [0.0, 1.0], 3.0)['value']))
        self.assertTrue(math.isnan(line_prediction([2.0, 2.0, 2.0], [0.0, 1.0, 2.0], 3.0)['se']))


if __name__ == '__main__':
    unittest.main()

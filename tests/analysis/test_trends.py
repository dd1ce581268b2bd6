"""Size trends per grain shape (yadecd.analysis.trends) on constructed per-run records whose
answer is known: values on an exact line of log10(grains) are fitted exactly over each size
range; a pile fed over another disc, a value a record lacks and a shape with one size are left
out; a range that leaves no pile out is not repeated in the table; the figures are written.
The estimator itself is tested in test_size_trend."""
import math
import os
import tempfile
import unittest

import numpy as np

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd.analysis import trends
from yadecd.analysis.stats import t_cdf
from yadecd.pile.protocol import DEFAULTS


def record(n, seed, epoch, D, slope, shape='sphere', feed=None):
    """A per-run record as the ensembles write it, with the floor loads of its D (ring 1, disc 1 − D)
    and one reciprocal pair and one cut (what the ensemble statistics read)."""
    r = {'run': '%s_n%d_s%d' % (shape, n, seed), 'n_grains': n, 'seed': seed, 'epoch': epoch,
         'grain_shape': shape, 'dip_D': D, 'slope_deg': slope, 'p_disc_Pa': 1.0 - D, 'p_ring_Pa': 1.0,
         'packing_fraction': 0.5, 'recip_rel': [0.05], 'recip_null': [0.1], 'recip_n_pairs': 1,
         'law_angle_layer': [5.0], 'law_angle_random': [6.0], 'law_n_cuts': 1, 'law_r_over_R': [0.3]}
    if feed is not None:
        r['feed_radius_m'] = feed
    return r


def constructed():
    """Spheres at 300-5000 grains, 3 seeds each: relaxed D = 0.4 - 0.1 log10 N + a seed offset that
    sums to zero at each size (so the line is exact), the 300-grain piles off that line by -0.5
    (their central peak) and without a slope; a pile fed over a 0.4 cm disc far off both lines;
    dimers at 1000 and 2000 grains; tetra at 1000 only."""
    recs = []
    for n in (300, 1000, 2000, 5000):
        for seed, off in zip((1, 2, 3), (-0.05, 0.0, 0.05)):
            D = 0.4 - 0.1 * math.log10(n) + off - (0.5 if n == 300 else 0.0)
            slope = None if n == 300 else 20 + 2 * math.log10(n) + off
            recs.append(record(n, seed, 'relaxed', D, slope))
    recs.append(record(2000, 9, 'relaxed', 5.0, 80.0, feed=0.004))
    recs.append(record(2000, 10, 'relaxed', 0.4 - 0.1 * math.log10(2000), 26.6,
                       feed=DEFAULTS['feed_radius']))      # the paper's disc, written out: kept
    for n in (1000, 2000):
        for seed in (1, 2):
            recs.append(record(n, seed, 'relaxed', 0.3 * math.log10(n) + 0.01 * seed, 30 + seed, 'dimer'))
    recs.append(record(1000, 1, 'relaxed', 0.0, 37.0, 'tetra'))
    return recs


class TestTrends(unittest.TestCase):

    def test_known_lines(self):
        t = trends.size_trends(constructed(), epochs=('relaxed',))
        self.assertEqual(sorted(t), ['dimer', 'sphere'])           # tetra: one size only
        sph_all = t['sphere']['all sizes']['relaxed']
        sph_big = t['sphere']['≥ 1000 grains']['relaxed']
        # from 1000 grains D lies on its line exactly (the extra 2000-grain pile lies on it too)
        self.assertAlmostEqual(sph_big['dip_D']['slope'], -0.1, places=12)
        self.assertAlmostEqual(sph_big['dip_D']['slope_welch'], -0.1, places=12)
        self.assertEqual(sph_big['dip_D']['sizes'], {1000: 3, 2000: 4, 5000: 3})
        # over all sizes the 300-grain peak tilts the line: the least-squares answer over those piles
        n = np.array([300] * 3 + [1000] * 3 + [2000] * 4 + [5000] * 3, dtype=float)
        D = 0.4 - 0.1 * np.log10(n) + np.array([-.05, 0, .05] * 2 + [-.05, 0, .05, 0] + [-.05, 0, .05])
        D[:3] -= 0.5
        self.assertAlmostEqual(sph_all['dip_D']['slope'], np.polyfit(np.log10(n), D, 1)[0], places=12)
        self.assertGreater(sph_all['dip_D']['slope'], 0)
        # the slope has no value at 300 grains: the same piles in both ranges
        self.assertEqual(sph_all['slope_deg']['sizes'], {1000: 3, 2000: 4, 5000: 3})
        self.assertAlmostEqual(sph_all['slope_deg']['slope'], 2.0, delta=0.02)   # 26.6 at 2000 is 0.001 off the line
        self.assertAlmostEqual(t['dimer']['all sizes']['relaxed']['dip_D']['slope'], 0.3, places=12)

    def test_table_and_figures(self):
        recs = constructed()
        with tempfile.TemporaryDirectory() as out:
            got = trends.analyse_trends(recs, out)
            self.assertEqual(sorted(os.listdir(out)), ['answer_table.md', 'size_trend.md', 'size_trend_dip.png', 'size_trend_slope.png'])
            for name in ('size_trend_dip.png', 'size_trend_slope.png'):
                self.assertGreater(os.path.getsize(os.path.join(out, name)), 10000)
            with open(os.path.join(out, 'size_trend.md')) as f:
                table = f.read()
        self.assertIn('sphere', got)
        first, largest = table.split('\n\n', 1)
        rows = [line for line in first.splitlines()[2:] if line.startswith('|')]
        # the largest size against the smaller sizes' line: spheres only (dimers have two sizes)
        self.assertIn('largest_against_line', largest)
        self.assertEqual([r.split(' | ')[:3] for r in largest.splitlines() if r.startswith('| sphere')],
                         [['| sphere', 'relaxed', 'central dip D'], ['| sphere', 'relaxed', 'flank slope']])
        # relaxed records only: spheres' D over both ranges, their slope once (the 300-grain piles have
        # none, so the second range would repeat it); dimers' D and slope once
        self.assertEqual(len(rows), 5)
        self.assertEqual(sum(r.startswith('| sphere | ≥ 1000 grains | relaxed | central dip D | -0.100 [')
                             for r in rows), 1)
        self.assertFalse(any('tetra' in r for r in rows))

    def test_answer_table(self):
        """One row per shape and size: pooled D = 1 − Σ disc / Σ ring over the piles (here 1 − 3/4 at
        1000 grains, 1 − 6/5 at 2000), the slope's mean and t interval, a single pile marked as such,
        a pile fed over another disc left out."""
        def full(n, seed, disc, ring, slope, feed=None, **extra):
            r = record(n, seed, 'relaxed', 1 - disc / ring, slope, feed=feed)
            r.update(p_disc_Pa=disc, p_ring_Pa=ring, **extra)
            return r
        recs = [full(1000, 1, 1.0, 2.0, 26.0), full(1000, 2, 2.0, 2.0, 27.0), full(2000, 1, 3.0, 2.5, 28.0),
                full(2000, 2, 3.0, 2.5, 28.0), full(2000, 3, 9.0, 1.0, 80.0, feed=0.004),
                full(14000, 1, 1.0, 2.0, 26.0, dip_ci95=[0.2, 0.8], dip_confidence=0.995)]
        rows = trends.answer_table_markdown(recs).splitlines()[2:]
        self.assertEqual(len(rows), 3)
        self.assertTrue(rows[0].startswith('| sphere | 1000 | 2 | 26.5° [20.1°, 32.9°] | +0.25 ['), rows[0])
        self.assertTrue(rows[1].startswith('| sphere | 2000 | 2 | 28.0° [28.0°, 28.0°] | -0.20 ['), rows[1])
        self.assertEqual(rows[2], '| sphere | 14000 | 1 | 26.0° | +0.50 [+0.20, +0.80] (over its sectors) | 99.5 % (one pile) | 0.500 |')

    def test_largest_against_line_known(self):
        """Piles at 1000-5000 grains on an exact line with offsets -0.05, 0, +0.05 (eight seeds' worth:
        the offsets repeat), three piles at 14 000 grains 0.1, 0.2 and 0.3 above the line: the line's
        value there, their mean 0.2 above it, the se of a mean of three, t and the one-sided p; a
        pile fed over another disc and the 300-grain piles (below min_grains) left out; dimers (two
        sizes) give none."""
        def line(n):
            return 0.4 - 0.1 * math.log10(n)
        offs = [-0.05, 0.0, 0.05] * 2
        recs = [record(n, i + 1, 'relaxed', line(n) + o, 26.0 + o) for n in (1000, 2000, 5000) for i, o in enumerate(offs)]
        recs += [record(14000, i + 1, 'relaxed', line(14000) + d, 26.0 + d) for i, d in enumerate((0.1, 0.2, 0.3))]
        recs += [record(300, 1, 'relaxed', 9.0, 26.0), record(5000, 9, 'relaxed', 9.0, 26.0, feed=0.004),
                 record(1000, 1, 'relaxed', 0.0, 30.0, 'dimer'), record(2000, 1, 'relaxed', 0.0, 30.0, 'dimer')]
        got = trends.largest_against_line(recs, 'relaxed', 'dip_D')
        self.assertEqual(list(got), ['sphere'])
        c = got['sphere']
        self.assertEqual((c['n_grains'], c['m'], c['df']), (14000, 3, 16))
        self.assertAlmostEqual(c['line'], line(14000), places=12)
        self.assertAlmostEqual(c['mean'] - c['line'], 0.2, places=12)
        x = np.log10(np.repeat([1000.0, 2000.0, 5000.0], 6))
        s = math.sqrt(6 * 3 * 0.05 ** 2 * 2 / 3 / 16)       # residuals: the offsets, sum of squares 18·(2/3)·0.05²
        se = s * math.sqrt(1 / 3 + 1 / 18 + (math.log10(14000) - x.mean()) ** 2 / ((x - x.mean()) ** 2).sum())
        self.assertAlmostEqual(c['se'], se, places=12)
        self.assertAlmostEqual(c['t'], 0.2 / se, places=10)
        self.assertAlmostEqual(c['p_above'], 1 - t_cdf(0.2 / se, 16), places=12)
        # the slope: a flat line at 26° plus the same offsets
        self.assertAlmostEqual(trends.largest_against_line(recs, 'relaxed', 'slope_deg')['sphere']['line'], 26.0, places=10)

    def test_largest_against_line_calibrated(self):
        """With the largest piles on the smaller sizes' line (the same scatter), p_above < 0.05 comes
        5 % of the time (1 000 constructed ensembles of this design, 0.029-0.071 is three binomial
        errors); with them 0.6 above it (two scatters), most of the time."""
        rng = np.random.default_rng(30)
        for shift, lo, hi in ((0.0, 0.029, 0.071), (0.6, 0.8, 1.0)):
            hits = 0
            for _ in range(1000):
                recs = [record(n, seed, 'relaxed', 0.2 - 0.1 * math.log10(n) + 0.25 * rng.normal(), 26.0)
                        for n in (1000, 2000, 5000) for seed in range(1, 9)]
                recs += [record(14000, seed, 'relaxed', 0.2 - 0.1 * math.log10(14000) + shift + 0.25 * rng.normal(), 26.0)
                         for seed in (1, 2, 3)]
                hits += trends.largest_against_line(recs, 'relaxed', 'dip_D')['sphere']['p_above'] < 0.05
            self.assertTrue(lo <= hits / 1000 <= hi, (shift, hits))

    def test_nothing_to_fit(self):
        recs = [record(1000, s, 'relaxed', 0.1 * s, 26.0) for s in (1, 2, 3)]
        self.assertEqual(trends.size_trends(recs), {})
        with tempfile.TemporaryDirectory() as out:
            self.assertEqual(trends.analyse_trends(recs, out), {})
            self.assertEqual(os.listdir(out), [])


if __name__ == '__main__':
    unittest.main()

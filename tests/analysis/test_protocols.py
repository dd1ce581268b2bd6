"""The protocol study's statistics (py/yadecd/protocol.py) on constructed samples with known
answers: Welch's interval against a hand computation, its coverage and power on synthetic
ensembles of the study's sizes (4 seeds against 8), missing values, single seeds, constant
samples, an outlier; the ensemble driver's time-step-aware epochs.

Pure numpy (runs inside YADE with ``bash tests/run.sh`` and with ``/usr/bin/python3 -m unittest``
from tests/).
"""
import json
import math
import os
import tempfile
import unittest

import numpy as np

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd.runs import ensemble as ens
from yadecd.analysis import protocols as pr


class TestWelch(unittest.TestCase):
    def test_hand_computed(self):
        # a: mean 2.5, variance 5/3; b: mean 6, variance 10. se² = 5/12 + 2; Welch df = 5.52 -> 5,
        # t(0.975, 5) = 2.5706: interval -3.5 ± 2.5706·1.554563 (the quantile table holds 2.571:
        # yadecd.analysis.t_quantile_975 is exact to 3 decimals, 6e-4 here)
        w = pr.welch([1, 2, 3, 4], [2, 4, 6, 8, 10])
        self.assertAlmostEqual(w['delta'], -3.5, places=12)
        self.assertAlmostEqual(w['se'], math.sqrt(5 / 12 + 2), places=12)
        self.assertAlmostEqual(w['df'], (29 / 12) ** 2 / ((5 / 12) ** 2 / 3 + 4 / 4), places=10)
        self.assertAlmostEqual(w['ci95'][0], -3.5 - 2.5706 * math.sqrt(29 / 12), delta=1e-3)
        self.assertAlmostEqual(w['ci95'][1], -3.5 + 2.5706 * math.sqrt(29 / 12), delta=1e-3)
        self.assertEqual(pr.verdict(w), 'same within scatter')
        self.assertAlmostEqual(w['std_ref'], math.sqrt(10), places=12)

    def test_coverage_and_power_at_study_size(self):
        """4 seeds against 8, unequal spreads: the interval holds the true shift in about 95 % of
        ensembles, and a shift of three reference spreads is seen. Welch's approximation is not
        exact with 4 samples: with the larger spread on the smaller sample its coverage is known to
        fall to about 94 % (rounding df down gives back a little); the estimate from 3000 trials has
        a standard error of 0.4 %."""
        rng = np.random.default_rng(7)
        trials, hit, seen, false_alarm = 3000, 0, 0, 0
        for _ in range(trials):
            ref = rng.normal(0.0, 1.0, 8)
            w = pr.welch(rng.normal(0.4, 1.5, 4), ref)
            hit += w['ci95'][0] <= 0.4 <= w['ci95'][1]
            seen += pr.verdict(pr.welch(rng.normal(3.0, 1.0, 4), ref)) == 'differs'
            false_alarm += pr.verdict(pr.welch(rng.normal(0.0, 1.0, 4), ref)) == 'differs'
        self.assertGreater(hit / trials, 0.93)
        self.assertLess(hit / trials, 0.985)
        self.assertGreater(seen / trials, 0.9)
        self.assertLess(false_alarm / trials, 0.06)

    def test_missing_values_and_single_seeds(self):
        w = pr.welch([1.0, None, float('nan'), 3.0], [0.0, 1.0, 2.0])
        self.assertEqual((w['n_test'], w['n_ref']), (2, 3))
        self.assertAlmostEqual(w['delta'], 1.0)
        one = pr.welch([5.0], [0.0, 1.0, 2.0])
        self.assertEqual(one['delta'], 4.0)
        self.assertTrue(math.isnan(one['se']))
        self.assertEqual(pr.verdict(one), 'not enough seeds')
        empty = pr.welch([None], [1.0, 2.0])
        self.assertTrue(math.isnan(empty['delta']))
        self.assertEqual(pr.verdict(empty), 'not enough seeds')

    def test_constant_samples(self):
        w = pr.welch([2.0, 2.0], [1.0, 1.0, 1.0])
        self.assertEqual(w['ci95'], (1.0, 1.0))
        self.assertEqual(pr.verdict(w), 'differs')
        self.assertEqual(pr.verdict(pr.welch([1.0, 1.0], [1.0, 1.0])), 'same within scatter')

    def test_outlier_widens_instead_of_shifting_the_verdict(self):
        """One wild seed in the setting: the mean moves, but so does the spread: no false 'differs'
        (the table shows the spread, so the reader sees the outlier)."""
        ref = [10.0, 10.5, 9.5, 10.2, 9.8, 10.1, 9.9, 10.0]
        w = pr.welch([10.1, 9.9, 10.0, 16.0], ref)
        self.assertEqual(pr.verdict(w), 'same within scatter')
        self.assertGreater(w['std_test'], 5 * w['std_ref'])


class TestCompare(unittest.TestCase):
    def test_units_of_spread(self):
        ref = [{'slope_deg': 0.0}, {'slope_deg': 2.0}]
        test = [{'slope_deg': 1.0}, {'slope_deg': 3.0}, {'slope_deg': None}]
        c = pr.compare(test, ref, keys=['slope_deg'])['slope_deg']
        self.assertAlmostEqual(c['delta_over_spread'], 1 / math.sqrt(2), places=12)
        self.assertAlmostEqual(c['mean_test'], 2.0)
        self.assertEqual(c['n_test'], 2)
        # df = 2 exactly: t(0.975, 2) = 4.3027, se = sqrt(2/2 + 2/2)
        self.assertAlmostEqual(c['resolution_over_spread'], 4.3027 * math.sqrt(2) / math.sqrt(2), places=3)

    def test_settings(self):
        self.assertEqual(pr.setting_options('h1e-3'), ['--dt', '0.001', '--tolerance', '0.001'])
        self.assertEqual(pr.setting_options('h1e-3_cm'), ['--dt', '0.001', '--tolerance', '0.001', '--correction-momentum'])
        self.assertEqual(pr.describe('h1e-3_cm'), 'h = 0.001 s, tolerance 0.001, correction momentum')
        with self.assertRaisesRegex(KeyError, 'h3e-3.*known: paper'):
            pr.setting_options('h3e-3')
        self.assertEqual(pr.setting_options('feed0.4'), ['--dt', '0.0002', '--tolerance', '0.001', '--feed-radius', '0.004'])
        self.assertEqual(pr.describe('feed0.4'), 'h = 0.0002 s, tolerance 0.001, feed radius 0.004')

    def test_reference_records(self):
        """The reference of a study: its size and shape, fed over the paper's disc (0.8 cm), at any time step."""
        base = {'n_grains': 2000, 'grain_shape': 'sphere'}
        self.assertTrue(pr.is_reference(base, 2000))                                       # an old record: the paper's disc
        self.assertTrue(pr.is_reference(dict(base, feed_radius_m=0.008, dt_s=1e-3), 2000))
        self.assertFalse(pr.is_reference(dict(base, feed_radius_m=0.004), 2000))
        self.assertFalse(pr.is_reference(base, 1000))
        self.assertFalse(pr.is_reference(base, 2000, 'dimer'))
        self.assertTrue(pr.is_reference(dict(base, grain_shape='dimer'), 2000, 'dimer'))


class TestEnsembleEpochs(unittest.TestCase):
    def test_options_reach_the_epochs(self):
        self.assertEqual(ens.option_value(['--dt', '1e-3', '--tolerance', '3e-3'], '--dt', 2e-4), 1e-3)
        self.assertEqual(ens.option_value(['--rate=100'], '--rate', 200.0), 100.0)
        self.assertEqual(ens.option_value([], '--dt', 2e-4), 2e-4)
        with self.assertRaisesRegex(ValueError, '--dt'):
            ens.option_value(['--dt'], '--dt', 2e-4)
        # 1000 grains at 100 per second with h = 1e-3: one grain every 10 steps, feed ends at 10 s
        cmd = ens.run_command('/repo', '/run', {'n_grains': 1000, 'seed': 1}, {'relax': 1.0, 'options': ['--rate', '100', '--dt', '1e-3']},
                           False)
        self.assertEqual(cmd[cmd.index('--epochs') + 1], '5.0000,10.0000,11.0000')
        self.assertEqual(ens.feed_time(1000, 200.0, 1e-3), ens.feed_time(1000, 200.0, 2e-4))

    def test_grain_shape_names_the_runs(self):
        """An ensemble of clump grains names its runs by the shape (records of several shapes can
        share a directory); spheres keep the paper's names."""
        import tempfile
        with tempfile.TemporaryDirectory() as root:
            e = ens.Ensemble(root)
            e.plan([300], [1, 2], 1.0, ['--grain-shape', 'dimer', '--dt', '1e-3'])
            self.assertEqual(sorted(e.runs()), ['dimer_n300_s1', 'dimer_n300_s2'])
        self.assertEqual(ens.run_name(300, 1), 'n300_s1')
        self.assertEqual(ens.option_text(['--grain-shape=tetra'], '--grain-shape', 'sphere'), 'tetra')
        with self.assertRaisesRegex(ValueError, '--grain-shape needs a value'):
            ens.option_text(['--grain-shape'], '--grain-shape', 'sphere')


class TestPaired(unittest.TestCase):
    """A run against its branch, one epoch: differences and their size in seed spreads."""

    def test_known_differences(self):
        ref = {'slope_deg': 27.0, 'packing_fraction': 0.60, 'H_m': 0.05, 'dip_D': None}
        branch = {'slope_deg': 27.5, 'packing_fraction': 0.59, 'H_m': float('nan'), 'dip_D': 0.1}
        spreads = {'slope_deg': 1.0, 'packing_fraction': 0.02, 'H_m': 0.001, 'dip_D': 0.0}
        r = pr.paired(ref, branch, spreads, keys=('slope_deg', 'packing_fraction', 'H_m', 'dip_D', 'n_contacts'))
        self.assertAlmostEqual(r['slope_deg']['delta'], 0.5)
        self.assertAlmostEqual(r['slope_deg']['delta_over_spread'], 0.5)
        self.assertAlmostEqual(r['packing_fraction']['delta_over_spread'], -0.5)
        # a missing value, a nan, a zero or absent spread: nan, never a number made up
        self.assertTrue(math.isnan(r['H_m']['delta']))
        self.assertTrue(math.isnan(r['dip_D']['ref']) and math.isnan(r['dip_D']['delta_over_spread']))
        self.assertTrue(math.isnan(r['n_contacts']['spread']))

    def test_spreads_and_table(self):
        summary = {'stats': {'2000_feed': {'slope_deg': {'std': 0.8, 'mean': 27.9}, 'n_runs': 8, 'seeds': [1, 2]}}}
        self.assertEqual(pr.ensemble_spreads(summary, '2000_feed'), {'slope_deg': 0.8})
        with self.assertRaisesRegex(KeyError, '2000_feed'):
            pr.ensemble_spreads(summary, '5000_feed')
        res = pr.paired({'H_m': 0.05}, {'H_m': 0.051}, {'H_m': 0.002}, keys=('H_m',))
        table = pr.paired_markdown([('t = 25 s', res)], '2000 grains')
        self.assertIn('| t = 25 s | apex height H | 5 cm | 5.1 cm | +0.1 cm | +0.50 |', table)



def write_run(root, name, params, floors):
    """A run directory: its run.json and one constructed floor per snapshot time {t: (dip, seed)}."""
    from yadecd.testing import synthetic as sy
    d = os.path.join(root, name)
    os.makedirs(d)
    with open(os.path.join(d, 'run.json'), 'w') as f:
        json.dump(params, f)
    for t, (dip, seed) in floors.items():
        snap, _ = sy.constructed_floor(dip=dip, seed=seed)
        snap['time'] = t
        np.savez_compressed(os.path.join(d, 'snap_%08.3f.npz' % t), **{k: v for k, v in snap.items() if k != 'path'})
    return d


class TestOnePileTwoProtocols(unittest.TestCase):
    """One pile (same grains, seed, feed) under two protocols from the start: what differs, the
    times shared, each difference against a direct measurement, and the refusals."""

    def setUp(self):
        self._tmp = tempfile.TemporaryDirectory()
        self.tmp = self._tmp.name
        # 10 grains at 5 per second: the feed ends at t = 2 s
        self.fast = {'n_grains': 10, 'rate': 5.0, 'seed': 1, 'dt': 1e-3, 'tolerance': 3e-3, 'wall_time_s': 5.0,
                     'sweep_order': 5}
        self.paper = {'n_grains': 10, 'rate': 5.0, 'seed': 1, 'dt': 2e-4, 'tolerance': 1e-3, 'wall_time_s': 50.0,
                      'schedule': 'slabs', 'relax': 0.0}
        self.summary = {'stats': {'10_feed': {'dip_D': {'std': 0.1}}, '10_relaxed': {'dip_D': {'std': 0.2}}}}

    def tearDown(self):
        self._tmp.cleanup()

    def test_pairing(self):
        # the renamed sweep order 5 is the schedule 'slabs'; relax absent is the protocol's 0; run time is not a setting
        self.assertEqual(pr.pairing(self.fast, self.paper), {'dt': (1e-3, 2e-4), 'tolerance': (3e-3, 1e-3)})
        self.assertEqual(pr.pairing(self.fast, dict(self.fast, relax=2.0)), {'relax': (0.0, 2.0)})
        self.assertEqual(pr.pairing(self.fast, dict(self.fast, wall_time_total_s=9.0, n_paving=3)), {})
        with self.assertRaisesRegex(ValueError, 'seed is 1 in one run and 2 in the other'):
            pr.pairing(self.fast, dict(self.paper, seed=2))
        with self.assertRaisesRegex(ValueError, 'feed_radius is 0.008 in one run and 0.004'):
            pr.pairing(self.fast, dict(self.paper, feed_radius=0.004))

    def test_compare_runs(self):
        from yadecd.analysis.ensemble import run_record
        a = write_run(self.tmp, 'fast', self.fast, {1.0: (0.3, 1), 2.0: (0.1, 2), 2.5: (0.2, 3)})
        b = write_run(self.tmp, 'paper', self.paper, {1.0: (0.0, 4), 2.5: (0.5, 5), 3.0: (0.1, 6)})
        res = pr.compare_runs(a, b, self.summary, '10', log=lambda s: None)
        self.assertFalse(res['branch'])
        self.assertEqual(res['start_s'], 0.0)
        self.assertEqual([e['time_s'] for e in res['epochs']], [1.0, 2.5])          # the shared times
        self.assertEqual([e['spread_group'] for e in res['epochs']], ['10_feed', '10_relaxed'])
        for e, spread in zip(res['epochs'], (0.1, 0.2)):
            name = 'snap_%08.3f.npz' % e['time_s']
            ra = run_record(os.path.join(a, name), self.fast)['dip_D']
            rb = run_record(os.path.join(b, name), self.paper)['dip_D']
            r = e['result']['dip_D']
            self.assertAlmostEqual(r['delta'], rb - ra, places=12)
            self.assertAlmostEqual(r['delta_over_spread'], (rb - ra) / spread, places=12)
        self.assertGreater(res['epochs'][1]['result']['dip_D']['delta'], 0.1)   # constructed dips 0.2 -> 0.5
        self.assertIn('paper against', res['text'])
        self.assertIn('dt 0.001 -> 0.0002, tolerance 0.003 -> 0.001', res['text'])
        self.assertIn('| epoch | observable | run | other | other − run |', res['text'])
        self.assertEqual(len(pr.compare_runs(a, b, self.summary, '10', times=[2.5], log=lambda s: None)['epochs']), 1)
        # a branch of another run is compared as a run of the same pile; a branch of this run after its branch point
        c = write_run(self.tmp, 'branch_of_else', dict(self.paper, branches=[{'source': '/x/else', 'time': 1.5, 'changes': {}}]),
                      {1.0: (0.0, 4), 2.5: (0.5, 5)})
        self.assertEqual([e['time_s'] for e in pr.compare_runs(a, c, self.summary, '10', log=lambda s: None)['epochs']], [1.0, 2.5])
        d = write_run(self.tmp, 'branch_of_fast', dict(self.fast, branches=[{'source': '/elsewhere/fast/', 'time': 1.5,
                                                                              'changes': {'tolerance': [1e-3, 3e-3]}}]),
                      {1.0: (0.0, 4), 2.5: (0.5, 5)})
        res = pr.compare_runs(a, d, self.summary, '10', log=lambda s: None)
        self.assertTrue(res['branch'])
        self.assertEqual([e['time_s'] for e in res['epochs']], [2.5])
        self.assertIn('tolerance 0.001 -> 0.003', res['text'])

    def test_refusals(self):
        a = write_run(self.tmp, 'fast', self.fast, {1.0: (0.3, 1)})
        same = write_run(self.tmp, 'same', dict(self.fast, wall_time_s=7.0), {1.0: (0.3, 2)})
        other_seed = write_run(self.tmp, 'seed2', dict(self.paper, seed=2), {1.0: (0.3, 2)})
        apart = write_run(self.tmp, 'apart', self.paper, {3.0: (0.3, 2)})
        with self.assertRaisesRegex(ValueError, 'ran the same protocol'):
            pr.compare_runs(a, same, self.summary, '10', log=lambda s: None)
        with self.assertRaisesRegex(ValueError, 'not one pile'):
            pr.compare_runs(a, other_seed, self.summary, '10', log=lambda s: None)
        with self.assertRaisesRegex(ValueError, 'share no snapshot'):
            pr.compare_runs(a, apart, self.summary, '10', log=lambda s: None)
        with self.assertRaisesRegex(ValueError, r'no snapshot at \[2.0\]'):
            pr.compare_runs(a, write_run(self.tmp, 'b', self.paper, {1.0: (0.1, 3)}), self.summary, '10', times=[2.0],
                            log=lambda s: None)
        with self.assertRaisesRegex(ValueError, 'holds no pile run'):
            pr.compare_runs(a, self.tmp, self.summary, '10', log=lambda s: None)


if __name__ == '__main__':
    unittest.main()

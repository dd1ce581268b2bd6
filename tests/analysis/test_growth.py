"""The dip while a pile grows (yadecd.analysis.growth, scripts/pile_growth.py) on a constructed run
directory whose floors have known dips: only the fed snapshots are measured, each as the ensembles
measure a pile (the same D as the dip estimator on that floor) with the grains it holds; records
are cached and measured again when a snapshot changes; the ensembles' reference keeps single
piles at the end of their feed, of the shape, over the paper's disc, at sizes with two piles."""
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import numpy as np

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd import analysis as pa
from yadecd.analysis import growth
from yadecd.analysis.ensemble import run_record
from yadecd.analysis.stats import mean_interval
from yadecd.testing import synthetic as sy

QUIET = dict(log=lambda s: None)


def write_snapshot(run_dir, t, dip, seed):
    snap, _ = sy.constructed_floor(dip=dip, seed=seed)
    snap['time'] = t
    path = os.path.join(run_dir, 'snap_%08.3f.npz' % t)
    np.savez_compressed(path, **{k: v for k, v in snap.items() if k != 'path'})
    return snap


class TestGrowth(unittest.TestCase):

    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix='cd-growth-')
        self.run = os.path.join(self.tmp, 'n10_s1')
        os.makedirs(self.run)
        with open(os.path.join(self.run, 'run.json'), 'w') as f:
            json.dump({'n_grains': 10, 'rate': 5.0, 'dt': 1e-3, 'seed': 1}, f)    # the feed ends at 2 s
        self.snaps = {t: write_snapshot(self.run, t, dip, seed) for t, dip, seed in ((1.0, 0.3, 1), (2.0, 0.1, 2), (2.5, 0.2, 3))}

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def test_fed_snapshots_measured(self):
        self.assertEqual([t for t, _ in growth.fed_snapshots(self.run)], [1.0, 2.0])
        recs = growth.growth_records(self.run, **QUIET)
        self.assertEqual([r['time_s'] for r in recs], [1.0, 2.0])
        for r in recs:
            snap = self.snaps[r['time_s']]
            self.assertEqual(r['grains_now'], int((~snap['fixed']).sum()))
            self.assertAlmostEqual(r['dip_D'], pa.central_dip(snap)['D'], places=12)
            self.assertEqual(r['run_name'], 'n10_s1')
        self.assertNotAlmostEqual(recs[0]['dip_D'], recs[1]['dip_D'], places=2)

    def test_cache(self):
        calls = []

        def counting(path, params):
            calls.append(os.path.basename(path))
            return run_record(path, params)
        cache = os.path.join(self.tmp, 'records')
        first = growth.growth_records(self.run, cache, measure=counting, **QUIET)
        self.assertEqual(len(calls), 2)
        again = growth.growth_records(self.run, cache, measure=counting, **QUIET)
        self.assertEqual(len(calls), 2)                                   # read back, not measured
        self.assertEqual([r['dip_D'] for r in again], [r['dip_D'] for r in first])
        write_snapshot(self.run, 2.0, 0.5, 7)                              # the 2 s snapshot replaced
        third = growth.growth_records(self.run, cache, measure=counting, **QUIET)
        self.assertEqual(calls[2:], ['snap_0002.000.npz'])
        self.assertNotAlmostEqual(third[1]['dip_D'], first[1]['dip_D'], places=3)

    def test_reference_table_figure(self):
        def rec(n, seed, D, epoch='feed', shape='sphere', feed=None):
            r = {'run': 'x', 'n_grains': n, 'seed': seed, 'epoch': epoch, 'grain_shape': shape, 'dip_D': D}
            if feed is not None:
                r['feed_radius_m'] = feed
            return r
        records = [rec(2000, s, 0.1 * s) for s in (1, 2, 3)] + [rec(5000, s, -0.2 + 0.05 * s) for s in (1, 2)]
        records += [rec(2000, 9, 5.0, epoch='relaxed'), rec(2000, 9, 5.0, shape='dimer'), rec(2000, 9, 5.0, feed=0.004),
                    rec(14000, 1, 0.5), rec(2000, 10, None)]
        ref = growth.fed_reference(records)
        self.assertEqual(list(ref), [2000, 5000])                          # 14 000: one pile only
        self.assertEqual(ref[2000], mean_interval([0.1 * s for s in (1, 2, 3)]))
        self.assertTrue(math.isclose(ref[5000]['mean'], -0.125))
        curves = {'n10_s1': growth.growth_records(self.run, **QUIET)}
        table = growth.growth_table_markdown(curves, ref)
        self.assertEqual(len([line for line in table.splitlines() if line.startswith('| n10_s1 |')]), 2)
        self.assertIn('| 2000 grains | 3 | +0.20 ± 0.10 [-0.05, +0.45] |', table)
        path = growth.fig_growth(curves, ref, os.path.join(self.tmp, 'growth.png'))
        self.assertGreater(os.path.getsize(path), 10000)

    def test_over_runs(self):
        """Three runs of seeds 1-3 with known D at t = 10 and 20 s: each time's row is the mean and
        t interval of the three values; a branch of seed 1 (another run with the same seed) is left
        out whatever its values; a time held by one run only (30 s) gets no row; a missing D is
        skipped, and a time left with one run then gets no row either."""
        def rec(seed, t, D):
            return {'seed': seed, 'time_s': t + 1e-12 * seed, 'dip_D': D, 'grains_now': int(200 * t)}
        curves = {'s1': [rec(1, 10.0, 0.1), rec(1, 20.0, 0.4), rec(1, 30.0, 0.9), rec(1, 40.0, 0.2)],
                  's2': [rec(2, 10.0, -0.3), rec(2, 20.0, 0.0), rec(2, 40.0, None)],
                  's1_branch': [rec(1, 10.0, 5.0), rec(1, 20.0, 5.0), rec(1, 30.0, 5.0)],
                  's3': [rec(3, 10.0, 0.2), rec(3, 20.0, 0.5)],
                  'empty': []}
        pooled = growth.over_runs(curves)
        self.assertEqual(list(pooled), [10.0, 20.0])
        self.assertEqual(pooled[10.0]['runs'], ['s1', 's2', 's3'])
        for t, vals in ((10.0, [0.1, -0.3, 0.2]), (20.0, [0.4, 0.0, 0.5])):
            want = mean_interval(vals)
            self.assertEqual(pooled[t]['n'], 3)
            self.assertAlmostEqual(pooled[t]['mean'], sum(vals) / 3, places=14)
            self.assertAlmostEqual(pooled[t]['ci95'][1], want['ci95'][1], places=14)
            self.assertEqual(pooled[t]['grains'], 200 * t)
        # D = 0.4, 0.0, 0.5: mean 0.3, variance 0.07, Student's t(0.975, 2) = 4.302653 (to the table's 3 decimals)
        self.assertAlmostEqual(pooled[20.0]['ci95'][1] - 0.3, 4.302653 * math.sqrt(0.07 / 3), delta=5e-4 * math.sqrt(0.07 / 3))
        table = growth.growth_table_markdown(curves, {}, pooled)
        self.assertIn('| 20.0 s | 4000 | 3 | +0.30 ± 0.26 [-0.36, +0.96] |', table)
        self.assertEqual(growth.over_runs(curves, min_runs=4), {})

    def test_command_line(self):
        script = os.path.join(SCRIPTS, 'pile_growth.py')
        out = os.path.join(self.tmp, 'out')
        r = subprocess.run([sys.executable, script, self.run, '--out', out], capture_output=True, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(sorted(os.listdir(out)), ['growth.md', 'growth_dip.png', 'records'])
        self.assertEqual(len(os.listdir(os.path.join(out, 'records'))), 2)
        docs = os.path.join(self.tmp, 'docs')
        for d in ('data', 'figures'):
            os.makedirs(os.path.join(docs, d))
        r = subprocess.run([sys.executable, script, self.run, '--out', out, '--docs', docs],
                           capture_output=True, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(out, 'growth.md')) as a, open(os.path.join(docs, 'data', 'growth.md')) as b:
            self.assertEqual(a.read(), b.read())
        self.assertTrue(os.path.isfile(os.path.join(docs, 'figures', 'ensemble', 'growth_dip.png')))
        r = subprocess.run([sys.executable, script, self.tmp, '--out', out], capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 2)
        self.assertIn('no run.json', r.stderr)


if __name__ == '__main__':
    unittest.main()

"""The work-trace estimators (yadecd.analysis.worktrace) on constructed traces with known answers:
a trace whose contacts fall silent at known sweeps, one all-zero sweep, sparse and empty bins, a
threshold exactly met (not exceeded), and a written-and-read trace in the cd_core_bench format."""
import json
import os
import sys
import tempfile
import unittest

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'py'))
from yadecd.analysis import worktrace as wt  # noqa: E402


def constructed(ns=30, nc=200, seed=0):
    """Contact k works (update 1.0, residual 2.0) until sweep stop[k], then is silent (update 1e-9,
    residual 1e-9); stop[k] = k % ns + 1 so each sweep loses the same number of contacts."""
    stop = np.arange(nc) % ns + 1
    s = np.arange(1, ns + 1)[:, None]
    working = s <= stop[None, :]
    change = np.where(working, 1.0, 1e-9).astype(np.float32)
    residual = np.where(working, 2.0, 1e-9).astype(np.float32)
    return change, residual, stop


class TestWorkTrace(unittest.TestCase):
    def test_threshold(self):
        # tol 1e-3, |q| 2, 400 contacts: 1e-3 * 2 / 20
        self.assertAlmostEqual(wt.threshold(dict(tolerance=1e-3, q_norm=2.0, contacts=400)), 1e-4, places=15)
        with self.assertRaises(ValueError):
            wt.threshold(dict(tolerance=1e-3, q_norm=2.0, contacts=0))

    def test_active_fraction_and_last_active(self):
        change, residual, stop = constructed()
        ns, nc = change.shape
        frac = wt.active_fraction(change, 0.5)
        expected = np.array([(stop >= s).mean() for s in range(1, ns + 1)])
        np.testing.assert_array_equal(frac, expected)
        np.testing.assert_array_equal(wt.last_active(change, 0.5), stop)
        # a threshold met exactly is not exceeded
        np.testing.assert_array_equal(wt.last_active(change, 1.0), np.zeros(nc, int))
        # sweeps asked past the end of the solve are NaN, not an error
        got = wt.active_fraction(residual, 1.0, [1, ns, ns + 5])
        self.assertEqual(got[0], 1.0)
        self.assertAlmostEqual(got[1], (stop >= ns).mean())
        self.assertTrue(np.isnan(got[2]))

    def test_top_share(self):
        row = np.zeros(100)
        row[:3] = [3.0, 2.0, 1.0]     # 9 + 4 + 1 = 14; the top 1 % is one contact
        self.assertAlmostEqual(wt.top_share(row, 0.01), 9 / 14)
        self.assertAlmostEqual(wt.top_share(row, 0.10), 1.0)
        self.assertTrue(np.isnan(wt.top_share(np.zeros(10), 0.1)))  # an all-zero sweep says nothing
        self.assertAlmostEqual(wt.top_share(np.ones(10), 0.01), 0.1)  # at least one contact

    def test_binned_mean_sparse_and_empty_bins(self):
        r = np.array([0.5] * 10 + [1.5] * 3)          # bin 0: 10 contacts, bin 1: 3 (sparse), bin 2: none
        z = np.zeros(13)
        v = np.array([1.0] * 5 + [3.0] * 5 + [100.0] * 3)
        mean, count = wt.binned_mean(r, z, v, [0, 1, 2, 3], [-1, 1], min_count=5)
        self.assertEqual(mean[0, 0], 2.0)
        self.assertTrue(np.isnan(mean[1, 0]))       # 3 contacts: too few to say
        self.assertTrue(np.isnan(mean[2, 0]))       # empty
        np.testing.assert_array_equal(count[:, 0], [10, 3, 0])

    def test_cylindrical(self):
        pts = np.array([[1.0, 0, 0.2], [-1.0, 0, 0.4], [0, 2.0, 0.0], [0, -2.0, 0.0]])
        r, z = wt.cylindrical(pts)
        np.testing.assert_allclose(r, [1, 1, 2, 2])
        np.testing.assert_allclose(z, [0.2, 0.4, 0, 0])
        r, z = wt.cylindrical(pts[:, [2, 0, 1]], up=(1, 0, 0))   # the same pile lying along x
        np.testing.assert_allclose(r, [1, 1, 2, 2])

    def test_round_trip_summary_and_figure(self):
        change, residual, stop = constructed(ns=40, nc=100)
        with tempfile.TemporaryDirectory() as tmp:
            prefix = os.path.join(tmp, 'step')
            np.save(prefix + '_change.npy', change)
            np.save(prefix + '_residual.npy', residual)
            rng = np.random.default_rng(3)
            pts = np.column_stack([rng.uniform(-0.1, 0.1, 100), rng.uniform(-0.1, 0.1, 100), rng.uniform(0, 0.05, 100)])
            with open(prefix + '_contacts.csv', 'w') as f:
                f.write('x,y,z,b1,b2,ref_radius\n')
                for p in pts:
                    f.write('%r,%r,%r,0,1,0.001\n' % tuple(p))
            # theta0 = 1e-3 * 5000 / 10 = 0.5: updates of 1.0 are above it, silent ones far below
            json.dump(dict(q_norm=5000.0, tolerance=1e-3, sweeps=40, contacts=100, up=[0, 0, 1]), open(prefix + '_meta.json', 'w'))
            tr = wt.load(prefix)
            self.assertEqual(tr['change'].shape, (40, 100))
            rows = wt.summary(tr, sweeps=(1, 10, 20, 99))
            self.assertEqual([r['sweep'] for r in rows], [1, 10, 20, 40])   # 99 is past the end; the last sweep is added
            for r in rows:
                self.assertAlmostEqual(r['update>1θ'], (stop >= r['sweep']).mean())
                self.assertAlmostEqual(r['update>10θ'], 0.0)                   # 1.0 < 10 θ0 = 5
            path = wt.figure(tr, os.path.join(tmp, 'f.png'))
            self.assertGreater(os.path.getsize(path), 10000)
            os.remove(prefix + '_meta.json')
            with self.assertRaises(FileNotFoundError):
                wt.load(prefix)


if __name__ == '__main__':
    unittest.main()

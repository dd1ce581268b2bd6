"""The slab schedule's time model (yadecd.analysis.scaling) on schedules with known critical paths."""
import os
import sys
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'py'))
from yadecd.analysis import scaling  # noqa: E402


class TestScaling(unittest.TestCase):
    def test_parse(self):
        self.assertEqual(scaling.parse_stages('10 20|5||0'), [[10, 20], [5], [], [0]])
        # a serial stage (cd_core_bench's 's:') is one thread's work
        self.assertEqual(scaling.parse_stages('10 20|s:5 7 9|s:'), [[10, 20], [21], []])
        for bad in ('', '1 x|2', '3|-1', 's:1 -2'):
            with self.assertRaises(ValueError):
                scaling.parse_stages(bad)

    def test_critical_path(self):
        st = scaling.parse_stages('100 100 100 100|30 10|7')
        # one core: every contact in turn
        self.assertEqual(scaling.critical_path(st, 1), 447)
        # two cores: 4 equal slabs in two rounds (200), the cuts' stage its larger range (30), the rest (7)
        self.assertEqual(scaling.critical_path(st, 2), 200 + 30 + 7)
        # four or more: the largest range of each stage
        self.assertEqual(scaling.critical_path(st, 4), 100 + 30 + 7)
        self.assertEqual(scaling.critical_path(st, 64), 137)
        # unequal ranges handed out statically: 3 ranges on 2 cores go as [50, 10] and [10]
        self.assertEqual(scaling.critical_path([[50, 10, 10]], 2), 60)
        self.assertEqual(scaling.critical_path([[10, 10, 50]], 2), 50)
        with self.assertRaises(ValueError):
            scaling.critical_path(st, 0)
        # a serial stage's ranges stay on one thread at any core count
        self.assertEqual(scaling.critical_path(scaling.parse_stages('100 100|s:30 10 7'), 64), 100 + 47)

    def test_solve_ms(self):
        st = [[1000, 1000], [500]]
        # 10 sweeps of (1000 + 500) updates at 40 ns = 0.6 ms, plus one parallel stage x 5 us x 10
        # sweeps on two cores (the one-range stage runs on the calling thread: no meeting)
        self.assertAlmostEqual(scaling.solve_ms(st, 2, 10, 40.0, barrier_us=5.0), 0.6 + 0.05)
        self.assertAlmostEqual(scaling.solve_ms(st, 1, 10, 40.0, barrier_us=5.0), 1.0)   # no meeting on one core


if __name__ == '__main__':
    unittest.main()

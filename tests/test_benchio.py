"""yadecd.benchio: the benchmark scripts' CSV output."""
import csv
import os
import tempfile
import unittest

import repo_package  # noqa: F401
from yadecd.benchio import sweeps_to, write_csv


class TestWriteCsv(unittest.TestCase):

    def test_rows_and_directory(self):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, 'new', 'bench.csv')
            said = []
            write_csv(path, [dict(case='a', ms=1.5), dict(case='b', ms=2)], log=said.append)
            with open(path) as f:
                self.assertEqual(list(csv.DictReader(f)), [dict(case='a', ms='1.5'), dict(case='b', ms='2')])
            self.assertEqual(said, ['wrote %s' % path])

    def test_no_rows(self):
        with tempfile.TemporaryDirectory() as d:
            with self.assertRaisesRegex(ValueError, 'no rows'):
                write_csv(os.path.join(d, 'x.csv'), [], log=lambda s: None)
            self.assertFalse(os.path.exists(os.path.join(d, 'x.csv')))


class TestSweepsTo(unittest.TestCase):
    """The first sweep at or below each threshold, on constructed residual histories."""

    def test_geometric(self):
        # r_k = 0.5^k: at or below 2^-m first at sweep m, exactly on the threshold included
        h = [0.5 ** k for k in range(1, 21)]
        self.assertEqual(sweeps_to(h, [0.5, 0.25, 2 ** -10, 0.3]), [1, 2, 10, 2])

    def test_non_monotone_and_never(self):
        # a bump after the first crossing does not move it; a threshold never reached is None
        h = [1.0, 0.2, 0.05, 0.3, 0.04, 0.011]
        self.assertEqual(sweeps_to(h, [0.1, 0.04, 0.01, 1.0]), [3, 5, None, 1])
        self.assertEqual(sweeps_to([], [0.1]), [None])

    def test_bad_threshold(self):
        for bad in (0, -1e-3, float('nan')):
            with self.assertRaisesRegex(ValueError, 'positive'):
                sweeps_to([0.5], [bad])


if __name__ == '__main__':
    unittest.main()

"""yadecd.io: atomic writes, JSON-ready values, CSV records with provenance; and
yadecd.analysis.stats.sweeps_to."""
import csv
import os
import subprocess
import sys
import tempfile
import unittest

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd.analysis.stats import sweeps_to
from yadecd.io import PROVENANCE_FIELDS, jsonable, rss_mb, write_csv, write_json_atomic


class TestWriteCsv(unittest.TestCase):

    def test_rows_and_directory(self):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, 'new', 'bench.csv')
            said = []
            write_csv(path, [dict(case='a', ms=1.5), dict(case='b', ms=2)], log=said.append, stamp=False)
            with open(path) as f:
                self.assertEqual(list(csv.DictReader(f)), [dict(case='a', ms='1.5'), dict(case='b', ms='2')])
            self.assertEqual(said, ['wrote %s' % path])
            self.assertEqual(os.listdir(os.path.dirname(path)), ['bench.csv'])    # no temporary left

    def test_every_row_says_where_and_when(self):
        # the default stamps each row with the machine, the commit and the date; a row that
        # carries its own value of a field keeps it
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, 'bench.csv')
            write_csv(path, [dict(case='a', ms=1.5), dict(case='b', ms=2, host='elsewhere')], log=lambda s: None)
            with open(path) as f:
                rows = list(csv.DictReader(f))
            self.assertEqual(list(rows[0])[:2], ['case', 'ms'])
            for r in rows:
                for k in PROVENANCE_FIELDS:
                    self.assertTrue(r[k], k)
                self.assertRegex(r['measured_utc'], r'^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ$')
            self.assertEqual(rows[1]['host'], 'elsewhere')
            self.assertNotEqual(rows[0]['host'], 'elsewhere')
            self.assertRegex(rows[0]['commit'], r'^([0-9a-f]{12}(\+dirty)?|unknown)$')


class TestJson(unittest.TestCase):

    def test_atomic_and_jsonable(self):
        import json
        import numpy as np
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, 'run.json')
            data = {'b': np.float64(2.5), 'a': [np.int64(3), float('nan'), np.array([1.0, np.inf])], 'ok': np.bool_(True)}
            write_json_atomic(path, data, sort_keys=True)
            with open(path) as f:
                text = f.read()
            self.assertEqual(json.loads(text), {'a': [3, None, [1.0, None]], 'b': 2.5, 'ok': True})
            self.assertLess(text.index('"a"'), text.index('"b"'))
            self.assertEqual(os.listdir(d), ['run.json'])
            self.assertEqual(jsonable((np.float32(0.5), {'x': np.int32(2)})), [0.5, {'x': 2}])

    def test_no_rows(self):
        with tempfile.TemporaryDirectory() as d:
            with self.assertRaisesRegex(ValueError, 'no rows'):
                write_csv(os.path.join(d, 'x.csv'), [], log=lambda s: None)
            self.assertFalse(os.path.exists(os.path.join(d, 'x.csv')))


class TestRss(unittest.TestCase):
    def test_this_process_and_another(self):
        """rss_mb reads VmRSS: this process's by default and by its pid agree within what the
        allocator moves between two reads; a child holding 200 MB more than an idle one is seen
        200 MB larger (within 20 MB)."""
        self.assertAlmostEqual(rss_mb(), rss_mb(os.getpid()), delta=5.0)
        self.assertGreater(rss_mb(), 1.0)
        code = 'import sys; b = bytearray(b"\\x01") * %d if sys.argv[1] == "big" else b""; sys.stdout.write("x"); sys.stdout.flush(); sys.stdin.read()'
        sizes = {}
        for kind in ('idle', 'big'):
            p = subprocess.Popen([sys.executable, '-c', code % (200 * 2 ** 20), kind], stdin=subprocess.PIPE,
                                 stdout=subprocess.PIPE)
            p.stdout.read(1)                     # the child has allocated and touched its memory
            sizes[kind] = rss_mb(p.pid)
            p.communicate(b'')
        self.assertAlmostEqual(sizes['big'] - sizes['idle'], 200.0, delta=20.0)


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

"""yadecd.benchio: the benchmark scripts' CSV output."""
import csv
import os
import tempfile
import unittest

import repo_package  # noqa: F401
from yadecd.benchio import write_csv


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


if __name__ == '__main__':
    unittest.main()

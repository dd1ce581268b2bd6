"""The engine's results are unchanged bit for bit: state hashes of yadecd.testing.statehash's cases equal
those recorded in tests/data/state_hashes.json before the solver-core refactor, for one thread (in
this process) and two threads (a YADE started with -j2). A change that alters results on purpose
records new hashes with scripts/state_hashes.py and says why in its commit."""
from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
import json
import os
import subprocess
import unittest

from yade import O
from yadecd.testing import statehash

with open(os.path.join(DATA, 'state_hashes.json')) as f:
    RECORDED = json.load(f)


class TestStateHashes(unittest.TestCase):

    def test_every_case_is_recorded(self):
        for threads in ('threads_1', 'threads_2'):
            self.assertEqual(sorted(RECORDED[threads]['cases']), sorted(statehash.CASES))

    def test_one_thread(self):
        self.assertEqual(O.numThreads, 1, 'the test runner runs YADE with one thread')
        ref = RECORDED['threads_1']['cases']
        for name in statehash.CASES:
            with self.subTest(case=name):
                digest, steps, contacts = statehash.run_case(name)
                self.assertEqual((steps, contacts), (ref[name]['steps'], ref[name]['contacts']))
                self.assertEqual(digest, ref[name]['sha256'])

    def test_two_threads(self):
        proc = subprocess.run([os.path.join(REPO, 'scripts', 'yade'), '-j2', '-n', '-x',
                               os.path.join(REPO, 'scripts', 'state_hashes.py'), '--compare',
                               os.path.join(DATA, 'state_hashes.json')],
                              capture_output=True, text=True, timeout=600, cwd=REPO)
        self.assertIn('state_hashes: 0 of %d cases differ' % len(statehash.CASES), proc.stdout, proc.stdout + proc.stderr)


if __name__ == '__main__':
    unittest.main()

"""Bad input to the command-line scripts that run without YADE: each refusal is a one-line
message naming the culprit (argparse's exit status 2), never a Python traceback, and it comes
before any work (no output written). One case per check the scripts make."""
import json
import os
import subprocess
import sys
import tempfile
import unittest

from repo_package import SCRIPTS  # noqa: F401  (first: this checkout's yadecd)


class TestScriptInput(unittest.TestCase):
    def setUp(self):
        self._tmp = tempfile.TemporaryDirectory()
        self.tmp = self._tmp.name
        self.nope = os.path.join(self.tmp, 'nope')
        self.empty = os.path.join(self.tmp, 'empty')
        os.makedirs(self.empty)

    def tearDown(self):
        self._tmp.cleanup()

    def refused(self, script, args, culprit):
        """Run ``script`` with ``args``: exit status 2, ``culprit`` in the message, no traceback,
        nothing written to the output paths the call names under tmp/out*."""
        r = subprocess.run([sys.executable, os.path.join(SCRIPTS, script)] + args, capture_output=True, text=True,
                           timeout=120)
        self.assertEqual(r.returncode, 2, '%s %s: %s' % (script, args, r.stderr))
        self.assertNotIn('Traceback', r.stderr)
        self.assertIn(culprit, r.stderr)
        self.assertEqual([n for n in os.listdir(self.tmp) if n.startswith('out')], [])
        return r.stderr

    def out(self, name='out'):
        return os.path.join(self.tmp, name)

    def test_missing_inputs(self):
        self.refused('pile_figures.py', [self.nope, '--out', self.out()], 'nope does not exist')
        self.refused('pile_plane_load.py', [self.nope + '.npz'], 'nope.npz does not exist')
        for cmd in ('analyse', 'status'):
            self.refused('pile_ensemble.py', [cmd, self.nope], 'nope is not a directory')
        self.refused('protocol_study.py', ['analyse', self.nope, '--out', self.out(), '--figure', self.out('out_fig')],
                     'nope is not a protocol study')
        self.refused('protocol_study.py', ['analyse', self.empty, '--out', self.out(), '--figure', self.out('out_fig')],
                     'holds no setting of a protocol study')
        self.refused('soak.py', [self.nope, '--plot-only', '--out', self.empty], 'needs soak.csv')

    def test_values_out_of_range(self):
        self.refused('pile_figures.py', [self.empty, '--half-thickness', '0', '--out', self.out()],
                     '--half-thickness must be a positive length')
        self.refused('pile_figures.py', [self.empty, '--ring-width', '-1', '--out', self.out()],
                     '--ring-width must be a positive length')
        self.refused('pile_finish.py', [self.empty, '--out', self.out(), '--tight', '2'], '--tight must lie in (0, 1)')
        self.refused('pile_finish.py', [self.empty, '--out', self.out(), '--threads', '0'],
                     '--max-iter and --threads must be positive')
        self.refused('estimator_check.py', ['--seeds', '1', '--out', self.out()], '--seeds must be at least 2')
        self.refused('fault_injection.py', ['--relax', '0', '--out', self.out()], 'must be positive')
        self.refused('yade_examples.py', ['--timeout', '0', '--out', self.out()], '--timeout must be a positive')
        self.refused('yade_examples.py', ['--only', 'nomatch_xyz', '--out', self.out()], "--only 'nomatch_xyz' matches no example")
        self.refused('protocol_study.py', ['run', self.out(), '--grain-shape', 'bogus'], "invalid choice: 'bogus'")

    def test_branch_comparison_inputs(self):
        run, branch = (os.path.join(self.tmp, x) for x in ('run', 'branch'))
        for d, p in ((run, {'n_grains': 10}), (branch, {'n_grains': 10, 'branches': [{'time': 1.0, 'changes': {}}]})):
            os.makedirs(d)
            with open(os.path.join(d, 'run.json'), 'w') as f:
                json.dump(p, f)
        self.refused('pile_branches.py', [run, branch, '--summary', self.nope + '.json', '--out', self.out()],
                     '--summary %s.json does not exist' % self.nope)
        summary = os.path.join(self.tmp, 'summary.json')
        with open(summary, 'w') as f:
            f.write('{}')
        self.refused('pile_branches.py', [run, branch, '--summary', summary, '--times', 'abc', '--out', self.out()],
                     "--times must be comma-separated times in seconds (got 'abc')")
        other = os.path.join(self.tmp, 'other')      # not a branch: must be the same pile (seed, grains, feed)
        os.makedirs(other)
        with open(os.path.join(other, 'run.json'), 'w') as f:
            json.dump({'n_grains': 10, 'seed': 2}, f)
        self.refused('pile_branches.py', [run, other, '--summary', summary, '--out', self.out()],
                     'not one pile under two protocols: seed is 1 in one run and 2 in the other')  # absent: the protocol's seed 1


if __name__ == '__main__':
    unittest.main()

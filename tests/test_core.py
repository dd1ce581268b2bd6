"""The core tier (tests/core/*.cpp, built as cd_core_tests by the top-level CMake): the solver's
YADE-independent parts checked against exact solutions without running YADE. This test runs the
binary so that the README's test command includes it, and fails (not skips) when it is missing."""
import os
import subprocess
import unittest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BINARY = os.path.join(REPO, 'build', 'cd_core_tests')


class TestCore(unittest.TestCase):

    def test_core_tier(self):
        self.assertTrue(os.path.exists(BINARY), '%s is missing: run scripts/setup.sh (it builds the plugin and the '
                                                'core tests)' % BINARY)
        proc = subprocess.run([BINARY], capture_output=True, text=True, timeout=120)
        self.assertEqual(proc.returncode, 0, proc.stdout + proc.stderr)
        self.assertRegex(proc.stdout, r'core: [1-9]\d* passed, 0 failed')


if __name__ == '__main__':
    unittest.main()

"""The core tier (tests/core/*.cpp, built as cd_core_tests by the top-level CMake): the solver's
YADE-independent parts checked without running YADE, against exact solutions and the engine's
own saved steps (tests/data/core). This test runs the binary so that the README's test command
includes it, and fails (not skips) when it is missing; it also runs the core benchmark
(cd_core_bench) once on a saved step, so that a broken benchmark is noticed (its times are not
checked: benchmarks are not tests)."""
from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
import os
import re
import subprocess
import unittest

BUILD = os.path.join(REPO, 'build')
CORE_DATA = os.path.join(DATA, 'core')


class TestCore(unittest.TestCase):

    def binary(self, name):
        path = os.path.join(BUILD, name)
        self.assertTrue(os.path.exists(path), '%s is missing: run scripts/setup.sh (it builds the plugin, the core tests '
                                              'and the core benchmark)' % path)
        return path

    def test_core_tier(self):
        proc = subprocess.run([self.binary('cd_core_tests'), CORE_DATA], capture_output=True, text=True, timeout=600)
        self.assertEqual(proc.returncode, 0, proc.stdout[-5000:] + proc.stderr[-2000:])
        m = re.search(r'core: (\d+) passed, 0 failed', proc.stdout)
        self.assertTrue(m, proc.stdout[-2000:])
        self.assertGreater(int(m.group(1)), 500)  # every saved step under every option: hundreds of checks

    def test_core_benchmark_runs(self):
        proc = subprocess.run([self.binary('cd_core_bench'), os.path.join(CORE_DATA, 'fcc108_boxed.cdp'), '--k1', '2', '--k2', '4',
                               '--repeat', '1'], capture_output=True, text=True, timeout=120)
        self.assertEqual(proc.returncode, 0, proc.stdout + proc.stderr)
        # a difference of two timings: on a busy machine it may be noise, which the benchmark reports as such
        self.assertRegex(proc.stdout, r'time per contact-sweep: ([0-9.]+ ns \(sweeps 2 and 4|not resolved \(the solve with 4 sweeps)')
        bad = subprocess.run([self.binary('cd_core_bench'), os.path.join(CORE_DATA, 'missing.cdp')], capture_output=True, text=True)
        self.assertEqual(bad.returncode, 1)
        self.assertIn('missing.cdp: cannot be opened', bad.stderr)


if __name__ == '__main__':
    unittest.main()

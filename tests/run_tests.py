"""Test runner executed inside YADE (``yade -n -x tests/run_tests.py [-k pattern]``)."""
import os
import sys
import unittest

# inside yade, __file__ is yade's executable: take the script's path from argv
here = os.path.dirname(os.path.abspath(sys.argv[0]))
sys.path.insert(0, here)
import repo_package  # noqa: E402,F401  (this repository's yadecd first on sys.path)
args = sys.argv[1:]
loader = unittest.TestLoader()
if len(args) >= 2 and args[0] == '-k':
    loader.testNamePatterns = ['*%s*' % args[1]]
suite = loader.discover(here, pattern='test_*.py', top_level_dir=here)
result = unittest.TextTestRunner(verbosity=2).run(suite)
sys.exit(0 if result.wasSuccessful() else 1)

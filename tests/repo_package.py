"""Imported first by the tests: puts this repository's py/ at the front of sys.path, so that
``yadecd`` is this repository's package, under plain Python (the analysis modules import without
YADE) and inside YADE alike (ahead of the copy the set-up installs). tests/run_tests.py does the
same before discovering the tests."""
import os
import sys

PY = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'py'))
if PY not in sys.path:
    sys.path.insert(0, PY)

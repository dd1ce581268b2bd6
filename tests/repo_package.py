"""Imported first by every test: puts this checkout's py/ at the front of sys.path, so that
``yadecd`` is this checkout's package under plain Python and inside YADE alike (ahead of the copy
the set-up installs into YADE), and names the checkout's places the tests use."""
import os
import sys

TESTS = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(TESTS)
PY = os.path.join(REPO, 'py')
DATA = os.path.join(TESTS, 'data')
SCRIPTS = os.path.join(REPO, 'scripts')
if PY not in sys.path:
    sys.path.insert(0, PY)

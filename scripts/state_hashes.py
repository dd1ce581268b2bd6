"""Record the engine's state hashes on the cases of ``yadecd.testing.statehash`` for this thread count.

    scripts/yade -j1 -n -x scripts/state_hashes.py --write tests/data/state_hashes.json
    scripts/yade -j2 -n -x scripts/state_hashes.py --write tests/data/state_hashes.json

Each call adds (or replaces) the hashes of its thread count in the file, with the commit and the
date; run it before a refactor of the solver, and ``tests/engine/test_state_hashes.py`` checks after it
that nothing changed. Without ``--write`` it prints the hashes and compares them with the file.
"""
import argparse
import json
import os
import subprocess
import sys
import time

from yade import O
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)
from yadecd.testing import statehash  # noqa: E402

ap = argparse.ArgumentParser(prog='state_hashes.py', description=__doc__.split('\n')[0])
ap.add_argument('--write', default=None, help='JSON file to add this thread count\'s hashes to')
ap.add_argument('--compare', default='tests/data/state_hashes.json')
a = ap.parse_args(sys.argv[1:])
threads = O.numThreads
rows = {}
for name in statehash.CASES:
    digest, steps, contacts = statehash.run_case(name)
    rows[name] = dict(sha256=digest, steps=steps, contacts=contacts)
    print('%-28s %s  steps %5d  contacts %5d' % (name, digest[:16], steps, contacts), flush=True)
if a.write:
    data = {}
    if os.path.exists(a.write):
        with open(a.write) as f:
            data = json.load(f)
    repo = os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0])))
    commit = subprocess.run(['git', '-C', repo, 'rev-parse', '--short', 'HEAD'], capture_output=True, text=True).stdout.strip()
    data['threads_%d' % threads] = dict(recorded=time.strftime('%Y-%m-%d'), commit=commit, cases=rows)
    with open(a.write, 'w') as f:
        json.dump(data, f, indent=1, sort_keys=True)
    print('state_hashes: %d cases for %d thread(s) written to %s' % (len(rows), threads, a.write))
elif os.path.exists(a.compare):
    with open(a.compare) as f:
        ref = json.load(f).get('threads_%d' % threads, {}).get('cases', {})
    bad = [n for n in rows if n in ref and ref[n]['sha256'] != rows[n]['sha256']]
    print('state_hashes: %d of %d cases differ from %s%s' % (len(bad), len(rows), a.compare, (': ' + ', '.join(bad)) if bad else ''))

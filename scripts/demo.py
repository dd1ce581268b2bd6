"""The main job on a small default scene: a small Moreau pile, then its figures.

    yade -n -x scripts/demo.py [--out DIR] [--n-grains N]

Builds a pile of a few hundred grains with the paper's protocol (scripts/pile.py) and writes
every figure of the analysis (scripts/pile_figures.py) into DIR/figures.
"""
import argparse
import os
import subprocess
import sys
import time
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

from yadecd import pile  # noqa: E402

ap = argparse.ArgumentParser(prog='demo.py')
ap.add_argument('--out', default='out/demo-pile')
ap.add_argument('--n-grains', type=int, default=300)
a = ap.parse_args(sys.argv[1:])
t0 = time.time()
print('demo: building a %d-grain Contact Dynamics pile in %s (paper protocol, about a minute)' % (a.n_grains, a.out))
pile.run(a.out, n_grains=a.n_grains, relax=0.5, snap_every=0.5, overwrite=True)  # the demo's own directory
repo = os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0])))
fig = os.path.join(a.out, 'figures')
subprocess.run(['/usr/bin/python3', os.path.join(repo, 'scripts', 'pile_figures.py'), a.out, '--out', fig], check=True)
print('demo done in %.0f s: figures and summary.json in %s' % (time.time() - t0, fig))

"""Build a large pile state for solver benchmarks in minutes (the size of the paper's deposited pile).

    scripts/yade -n -x scripts/bench/cone_pile.py --out out/cone14000 [--n-grains 14000]
                       [--slope 28] [--settle 0.1] [--seed 1] [--separate]

A dense random packing of the protocol's grains cut to a cone, set on the paving and settled by
the CD engine (``yadecd.pile.cone_state``). It writes ``run.json`` and one ``snap_*.npz`` that
``scripts/bench/solver_bench.py --snapshot`` times. Deposition by the paper's protocol would take
about 40 h here to reach 14 000 grains; this is a stand-in state for the solver, not a result.
"""
import argparse
import sys
import os
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd (README: which yadecd)

from yadecd import pile  # noqa: E402

parser = argparse.ArgumentParser(prog='cone_pile.py', description=__doc__.split('\n')[0])
parser.add_argument('--out', required=True, help='run directory (created)')
parser.add_argument('--n-grains', type=int, default=14000, help='grains aimed at (the cone keeps those of the packing inside it)')
parser.add_argument('--slope', type=float, default=28.0, help='cone slope [degrees]; deposited piles stand at 28.5-28.8 degrees while fed '
                    '(2000 grains, robust fit, docs/pile.md); the former 22 was the biased estimator\'s reading')
parser.add_argument('--settle', type=float, default=0.1, help='simulated settling time [s]')
parser.add_argument('--seed', type=int, default=1)
parser.add_argument('--separate', action='store_true', help='spread the packing apart so that no two grains overlap '
                    '(the state to start soft-contact MD from, scripts/bench/cd_md_fullsize.py)')
args = parser.parse_args(sys.argv[1:])
path = pile.cone_state(args.out, n_grains=args.n_grains, slope_deg=args.slope, settle=args.settle, seed=args.seed,
                       separate=args.separate)
print('cone pile state:', path)

"""CD against MD on a small pile: the pile protocol of scripts/pile.py run with
the CD engine and with YADE's linear soft contacts at several stiffnesses, side by side.

    scripts/yade -n -x scripts/compare_pile.py [--grains 300] [--relax 0.5] [--out out/compare_pile]
                                              [--cases cd,cd_plain,cd_loose,md_1e6,md_1e7,md_1e8] [--plot-only]
                                              [--grain-shape dimer]

Every case builds the same protocol (same seed, so the same feed positions) and is analysed by
the same pile analysis (yadecd.analysis.report.analyse). Recorded per case: wall time, steps, wall
time per simulated second, flank slope (none on piles below about 2 cm), chord angle, the former
slope estimator, apex height, central and peak ground pressure (also over the
hydrostatic ρ_bulk·g·H), floor load over pile weight, largest and mean grain–grain overlap over
the mean diameter at the end. Writes OUT/compare_pile.csv, OUT/compare_pile.png and copies both
to docs/data and docs/figures with --docs.
"""
import argparse
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

REPO = os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0])))  # inside YADE __file__ is the yade executable
from yadecd.compare import pile as compare_pile  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
parser.add_argument('--grains', type=int, default=300)
parser.add_argument('--relax', type=float, default=0.5)
parser.add_argument('--seed', type=int, default=1)
parser.add_argument('--grain-shape', default='sphere', help='grains of both methods (yadecd.pile.grains.SHAPES)')
parser.add_argument('--out', default=os.path.join(REPO, 'out', 'compare_pile'))
parser.add_argument('--cases', default='cd,cd_plain,cd_loose,md_1e6,md_1e7,md_1e8')
parser.add_argument('--plot-only', action='store_true', help='redraw from OUT/compare_pile.csv')
parser.add_argument('--docs', action='store_true', help='copy the CSV and figure into docs/')
sys.exit(compare_pile.main(parser.parse_args(sys.argv[1:]), REPO))

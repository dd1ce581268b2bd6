"""Contact Dynamics vs YADE's soft-contact MD, side by side, on scenes defined once.

    scripts/yade -n -x scripts/compare_cd_md.py              # full sweep, 2363 runs (~7 min, one core)
    scripts/yade -n -x scripts/compare_cd_md.py --quick      # 11 runs, a few seconds, to out/compare_quick
    scripts/yade -n -x scripts/compare_cd_md.py --resume     # run only what the CSV lacks
    scripts/yade -n -x scripts/compare_cd_md.py --plot-only  # redraw figures/summary from the CSV

Sweeps, for each scene case (yadecd.compare.cases defines the cases and their exact solutions,
yadecd.compare.measure the measurements, yadecd.compare.md the MD engines, yadecd.compare.run one run,
yadecd.compare.sweep this sweep; docs/compare.md reads the results):
  MD (linear Cundall-Strack, Hertz-Mindlin): Young's modulus x dt safety factor (x PWaveTimeStep,
     0.1 to 5: beyond 1 to find where it fails) x Cundall damping (rest scenes only; 0 for
     dynamic ones) x law; stiffer E (1e10, 1e11) on the dynamic scenes;
  CD: time step x Gauss-Seidel tolerance x over-relaxation (rest scenes), maxIter probes; the
     solver settings are pinned (the installed plugin's defaults may change).
Writes one CSV row per run (--csv, default docs/data/compare.csv), a summary of the costs at
equal accuracy and the failure boundaries (<csv stem>_summary.md), and per scene the error-vs-cost
chart with both Pareto fronts (compare_<scene>.png) and the stability chart (error against the
time step, MD interpenetration against E: compare_<scene>_stability.png) in --figs (default
docs/figures).
"""
import argparse
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

# inside yade, __file__ is yade's executable: take the script's path from argv
REPO = os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0])))
from yadecd import compare  # noqa: E402
from yadecd.compare import sweep as compare_sweep  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
ap.add_argument('--quick', action='store_true', help='tiny subset (< 1 min) into out/compare_quick')
ap.add_argument('--csv', default=None, help='CSV path (default docs/data/compare.csv; quick: out/compare_quick/compare.csv)')
ap.add_argument('--figs', default=None, help='figure directory (default docs/figures; quick: out/compare_quick)')
ap.add_argument('--scenes', nargs='+', default=None, help='only these scenes (%s)' % ', '.join(compare.SCENES))
ap.add_argument('--resume', action='store_true', help='keep rows already in the CSV, run only the missing ones')
ap.add_argument('--plot-only', action='store_true', help='no runs: redraw from the CSV')
ap.add_argument('--dry-run', action='store_true', help='list the runs and their step counts')
ap.add_argument('--momentum', action='store_true', help='CD runs with momentum (default: pinned to plain Gauss–Seidel, as docs/compare.md was measured)')
ap.add_argument('--max-wall', type=float, default=120.0, help='stop any single run after this many seconds of stepping')
a = ap.parse_args(sys.argv[1:])
a.csv = a.csv or os.path.join(REPO, *(('out', 'compare_quick', 'compare.csv') if a.quick else ('docs', 'data', 'compare.csv')))
a.figs = a.figs or os.path.join(REPO, *(('out', 'compare_quick') if a.quick else ('docs', 'figures')))
compare_sweep.sweep(a.csv, a.figs, plot_only=a.plot_only, dry_run=a.dry_run, quick=a.quick, scenes=a.scenes,
                    resume=a.resume, momentum=a.momentum, max_wall=a.max_wall)

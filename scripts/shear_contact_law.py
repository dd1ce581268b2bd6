"""The contact forces of a plane-shear run against Coulomb's bound |F_t| <= mu F_n: the share of the
loaded contacts beyond it and by how much (yadecd.analysis.rheology.coulomb_excess).

    scripts/yade -j1 -n -x scripts/shear_contact_law.py --packing out/shear/packing_n2000_s1.yade.gz \\
        --method md --I 0.03 --out docs/data/shear_contact_law.csv
    scripts/yade -j1 -n -x scripts/shear_contact_law.py ... --method md --es-md 1 --label 'MD, es = 1'

The packing is sheared as scripts/shear_rheology.py does (yadecd.compare.shear.build, the same
options and defaults) through --skip of nominal strain (the transient), then the contacts are read
--reads times, evenly, over --window of strain more. MD: the forces of YADE's Hertz-Mindlin law
(MindlinPhys.normalForce, .shearForce: the elastic and the viscous parts together), and the mean
overlap over the mean diameter (ScGeom.penetrationDepth; CD's grains do not overlap). CD: the contact
impulses over the step divided by the step (CDPhys.impulse split along the contact normal), which
the solver keeps within the bound up to its tolerance. One row per run is appended to --out (CSV).
"""
import argparse
import os
import sys
import time
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

import numpy as np  # noqa: E402
from yade import O  # noqa: E402

from yadecd.analysis import rheology  # noqa: E402
from yadecd.compare import shear  # noqa: E402
from yadecd.io import append_csv  # noqa: E402

CD, MD = rheology.PROTOCOL['cd'], rheology.PROTOCOL['md']
parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
parser.add_argument('--packing', required=True, help='a packing made by scripts/shear_rheology.py (.yade.gz)')
parser.add_argument('--method', choices=('cd', 'md'), required=True)
parser.add_argument('--I', type=float, default=0.03, help='nominal inertial number')
parser.add_argument('--skip', type=float, default=1.0, help='nominal strain sheared before the contacts are read')
parser.add_argument('--window', type=float, default=0.3, help='nominal strain over which the contacts are read')
parser.add_argument('--reads', type=int, default=30, help='how many times the contacts are read over the window')
parser.add_argument('--tolerance', type=float, default=CD['tolerance'], help='CD: solver tolerance')
parser.add_argument('--young-over-p', type=float, default=MD['young_over_p'], help="MD: Young's modulus over p")
parser.add_argument('--en-md', type=float, default=MD['en_md'], help='MD: normal restitution')
parser.add_argument('--es-md', type=float, default=MD['es_md'], help='MD: tangential restitution (1: no tangential viscous damping)')
parser.add_argument('--label', default='', help='the run in the output table (default: method and its options)')
parser.add_argument('--out', required=True, help='CSV file a row is appended to')
args = parser.parse_args(sys.argv[1:])
for value, name in ((args.skip, '--skip'), (args.window, '--window'), (args.reads, '--reads')):
    if not value > 0:
        sys.exit('%s must be positive, not %r' % (name, value))
if not os.path.exists(args.packing):
    sys.exit('no packing at %s (make one with scripts/shear_rheology.py)' % args.packing)

options = dict(tolerance=args.tolerance) if args.method == 'cd' else \
    dict(young_over_p=args.young_over_p, en_md=args.en_md, es_md=args.es_md)
start = time.time()
info = shear.build(args.packing, args.method, args.I, **options)
rate = info['V'] / info['gap0']
steps = lambda strain: max(1, int(round(strain / (rate * O.dt))))  # noqa: E731
O.run(steps(args.skip), True)
every = max(1, steps(args.window) // args.reads)
mu = shear.REFERENCE['mu']


def forces():
    """(F_n, |F_t|, overlap) of every real contact now [N, N, m]; the overlap is MD's only (CD: none)."""
    fn, ft, ov = [], [], []
    for i in O.interactions:
        if not i.isReal:
            continue
        if args.method == 'md':
            fn.append(i.phys.normalForce.norm())
            ft.append(i.phys.shearForce.norm())
            ov.append(i.geom.penetrationDepth)
        else:
            n = i.geom.normal
            jn = i.phys.impulse.dot(n)
            fn.append(max(jn, 0.0) / O.dt)
            ft.append((i.phys.impulse - jn * n).norm() / O.dt)
    return fn, ft, ov


fn, ft, overlaps = [], [], []
for _ in range(args.reads):
    O.run(every, True)
    a, b, c = forces()
    fn += a
    ft += b
    overlaps += c
e = rheology.coulomb_excess(np.array(fn), np.array(ft), mu)
variant = rheology.variant_of(args.method, options)
label = args.label or (args.method.upper() + (', ' + variant if variant else ', reference'))
row = dict(label=label, method=args.method, I=args.I, variant=variant, skip=args.skip, window=args.window, reads=args.reads,
           contacts_read=e['loaded'], over=e['over'], excess_mean=e['excess_mean'], excess_max=e['excess_max'],
           mobilised=e['mobilised'], tangential_share=e['tangential_share'],
           overlap_over_d=float(np.mean(overlaps)) / shear.REFERENCE['d'] if overlaps else float('nan'), wall_s=time.time() - start)
print('%s: %d loaded contacts read, %.1f %% beyond the bound by %.1f %% on average (at most %.0f %%), '
      'mean mobilised friction %.3f, %.2f %% of the tangential force beyond the bound' % (
          label, e['loaded'], 100 * e['over'], 100 * e['excess_mean'], 100 * e['excess_max'], e['mobilised'],
          100 * e['tangential_share']), flush=True)
append_csv(args.out, row, list(row), start=not os.path.exists(args.out))

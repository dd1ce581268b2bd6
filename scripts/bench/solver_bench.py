"""Solver benchmark harness: prints and saves (CSV) per-contact Gauss–Seidel cost of
the CD engine and of Siconos' NSGS on the same problems, and where a step's time goes.

    scripts/yade -n -x scripts/bench/solver_bench.py [--contacts 1e3,1e4,1e5] [--snapshot RUN/snap_*.npz]
                                                     [--out docs/data/solver_bench.csv] [--quick]

Measurements (one run, one machine: compare rows of the same run, as ratios):
- ``sweep``: ns per contact per sweep on an FCC block of about N contacts (the engine with its
  sphere fast path, and with ``sphereFastPath=False``), as the difference
  of two solves of K1 and K2 forced sweeps (tolerance unreachable) divided by (K2−K1)·contacts,
  so set-up, warm start and residual checks cancel. The same exported problem solved by
  Siconos NSGS with the same two sweep counts gives its figure the same way.
- ``CD coloured``: the same with ``schedule='colours'`` (colour by colour, parallel over O.numThreads
  threads: run the script with ``yade -j1`` and ``-j2`` for the speed-up); ``determinism``: a hash
  of all velocities after 5 coloured steps, which must not depend on the thread count.
- ``stage``: where the time of an ordinary step goes (collider, InteractionLoop = geometry and
  physics functors, and the integrator's stages), at the default tolerance, on the block and,
  with ``--snapshot``, on pile states rebuilt from a pile run's snapshots (warm-started steps),
  with the pile's default solver (momentum, slab sweep ``schedule='slabs'``, parallel over slabs; its
  velocity hash after the timed steps must not depend on the thread count) and with the height
  order, plain Gauss–Seidel, its general path and ω = 1.8, and the coloured sweep: sweeps per step
  and cost against contacts. ``--pile-variants`` picks the variants (large states: plain GS takes
  seconds a step). ``--feed`` keeps creating grains during those steps, as at the end of a deposition.
- ``CD momentum`` sweep rows: a sweep plus the momentum extrapolation pass.
- ``CD clumps`` (``--clumps``): the same FCC packing with its spheres paired into touching dimer
  clumps (``scenes.fcc_block(dimers=True)``): the cost per contact-sweep of clump contacts against
  the sphere contacts of the rows above, in the same run.
Each row records machine, threads, commit and date.
"""
import argparse
import hashlib
import os
import sys
import time

import numpy as np

from yade import O
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd (README: which yadecd)
import yadecd
from yadecd import scenes, pile  # noqa: E402
from yadecd.export import fclib  # noqa: E402
from yadecd.io import append_csv  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0]))))  # inside YADE __file__ is the yade executable

parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
parser.add_argument('--contacts', default='1e3,1e4,1e5', help='target contact counts of the FCC blocks')
parser.add_argument('--snapshot', nargs='*', default=[], help='pile snapshots .npz for the per-stage breakdown on pile states (several: sweeps and cost against contacts)')
parser.add_argument('--pile-steps', type=int, default=20, help='steps timed on the pile state')
parser.add_argument('--pile-variants', default='height,plain,general,relaxation,coloured',
                    help='solver variants timed on pile states besides the default: comma-separated subset of height,plain,general,relaxation,coloured')
parser.add_argument('--clumps', action='store_true', help='also time the same FCC packings made of dimer clumps (clump contacts against sphere contacts)')
parser.add_argument('--feed', action='store_true',
                    help='on pile states, keep creating grains by the pile protocol (rate, feed disc, creation rule) during the '
                         'warm-up and timed steps, as at the end of a deposition; the same grains for every variant')
parser.add_argument('--out', default=os.path.join(REPO, 'docs', 'data', 'solver_bench.csv'))
parser.add_argument('--quick', action='store_true', help='fewer sweeps (a smoke run)')
parser.add_argument('--no-siconos', action='store_true')
parser.add_argument('--no-block-steps', action='store_true', help='on the blocks, only the per-sweep figures (no step breakdown, no determinism run)')
args = parser.parse_args(sys.argv[1:])

PILE_VARIANTS = {  # the default row ('CD') is the pile's default solver: momentum, slab sweep
    'height': ('CD height order', dict(schedule='height')),
    'plain': ('CD plain GS', dict(momentum=False, schedule='height')),
    'general': ('CD plain GS general path', dict(momentum=False, sphereFastPath=False, schedule='height')),
    'relaxation': ('CD plain GS relaxation 1.8', dict(momentum=False, relaxation=1.8, schedule='height')),
    'coloured': ('CD coloured', dict(schedule='colours')),
}
unknown = set(v for v in args.pile_variants.split(',') if v) - set(PILE_VARIANTS)
if unknown:
    raise ValueError('--pile-variants: unknown %s (known: %s)' % (', '.join(sorted(unknown)), ', '.join(PILE_VARIANTS)))
K1, K2 = (5, 15) if args.quick else (20, 120)


COMMON = dict(threads=O.numThreads)
FIELDS = list(COMMON) + ['kind', 'scene', 'bodies', 'contacts', 'method', 'sweeps', 'quantity', 'value', 'unit']
append_csv(args.out, None, FIELDS, start=True)   # rows are appended as they come: a crash loses nothing


def record(**row):
    row = dict(COMMON, **row)
    append_csv(args.out, row, FIELDS)
    print('  '.join('%s=%s' % (k, ('%.4g' % v) if isinstance(v, float) else v) for k, v in row.items() if k not in COMMON), flush=True)


def stage_times(cd):
    """ns per stage of the integrator since the last reset, from its timingDeltas."""
    return {label: ns for label, ns, count in cd.timingDeltas.data}


def solve_time(cd, sweeps):
    """Seconds the integrator spent in solveImpulses during one step forced to ``sweeps``."""
    cd.tolerance, cd.maxIter = 1e-300, sweeps
    cd.timingDeltas.reset()
    O.step()
    assert cd.iterations == sweeps
    return stage_times(cd)['solveImpulses'] * 1e-9


def per_sweep(run):
    """(run(K2) − run(K1))/(K2 − K1), each the best of three."""
    t1 = min(run(K1) for _ in range(3))
    t2 = min(run(K2) for _ in range(3))
    return (t2 - t1) / (K2 - K1)


def siconos_time(pb, sweeps):
    s = fclib.solve_siconos(pb['W'], pb['q'], pb['mu'], tol=1e-300, max_iter=sweeps)
    return s['seconds']


def velocity_digest():
    return hashlib.sha1(np.array([list(b.state.vel) + list(b.state.angVel) for b in O.bodies]).tobytes()).hexdigest()[:16]


class Feed:
    """Grain creation of the pile protocol (``yadecd.pile.Feeder``) between steps: one grain
    every 1/(rate·dt) steps, from a fixed seed, so that every variant gets the same sequence."""

    def __init__(self, p, enabled):
        self.enabled, self.p = enabled, p
        self.period = pile.creation_period(p['rate'], p['dt'])
        self.feeder = pile.Feeder(p, np.random.default_rng(p['seed'] + 77), {})

    def __call__(self):
        if self.enabled and O.iter % self.period == 0:
            self.feeder.create()


def step_loop(steps, feed):
    """Run ``steps`` steps (feeding between them); returns the wall time inside O.step only."""
    wall = 0.0
    for _ in range(steps):
        if feed:
            feed()
        t0 = time.perf_counter()
        O.step()
        wall += time.perf_counter() - t0
    return wall


def breakdown(scene, steps, method='CD', feed=None):
    """Mean wall time per step of each engine and integrator stage over ``steps`` steps."""
    cd = yadecd.integrator()
    cd.tolerance, cd.maxIter = tol, maxit
    for e in O.engines:
        e.execTime = 0
    cd.timingDeltas.reset()
    sweeps = contacts = 0
    wall = 0.0
    for _ in range(steps):
        wall += step_loop(1, feed)
        sweeps += cd.iterations
        contacts += cd.nContacts
    wall /= steps
    parts = {'step': wall}
    parts.update({e.__class__.__name__: e.execTime * 1e-9 / steps for e in O.engines})
    for label, ns in stage_times(cd).items():
        parts['CD.' + label] = ns * 1e-9 / steps
    for name, seconds in parts.items():
        if seconds > 0:
            record(kind='stage', scene=scene, bodies=len(O.bodies), contacts=contacts // steps, method=method,
                   sweeps=sweeps / steps, quantity=name, value=seconds * 1e3, unit='ms/step')


O.timingEnabled = True
for target in [int(float(x)) for x in args.contacts.split(',') if x]:
    scenes.fcc_block(target / 6.2, warnUnconverged=False)
    cd = yadecd.integrator()
    tol, maxit = cd.tolerance, cd.maxIter
    O.step()  # contacts appear; warm start from here on
    n = cd.nContacts
    cd.momentum = False  # the sweep alone; the momentum pass is timed below
    cd.sphereFastPath = False
    tg = per_sweep(lambda k: solve_time(cd, k))
    record(kind='sweep', scene='fcc_block', bodies=len(O.bodies), contacts=n, method='CD general path', quantity='time per contact-sweep', value=tg / n * 1e9, unit='ns')
    cd.sphereFastPath = True
    t = per_sweep(lambda k: solve_time(cd, k))
    record(kind='sweep', scene='fcc_block', bodies=len(O.bodies), contacts=n, method='CD', quantity='time per contact-sweep', value=t / n * 1e9, unit='ns')
    print('  general/fast path time per contact-sweep: %.2f' % (tg / t))
    cd.schedule = 'colours'  #, parallel with O.numThreads threads
    tc = per_sweep(lambda k: solve_time(cd, k))
    record(kind='sweep', scene='fcc_block', bodies=len(O.bodies), contacts=n, method='CD coloured', quantity='time per contact-sweep', value=tc / n * 1e9, unit='ns')
    cd.schedule = 'height'
    cd.momentum = True  # a sweep plus the momentum extrapolation
    tm = per_sweep(lambda k: solve_time(cd, k))
    record(kind='sweep', scene='fcc_block', bodies=len(O.bodies), contacts=n, method='CD momentum', quantity='time per contact-sweep', value=tm / n * 1e9, unit='ns')
    if args.clumps:      # the same packing, its spheres paired into touching dimer clumps
        scenes.fcc_block(target / 6.2, dimers=True, warnUnconverged=False)
        cl = yadecd.integrator()
        O.step()
        nc = cl.nContacts
        cl.momentum = False
        tcl = per_sweep(lambda k: solve_time(cl, k))
        record(kind='sweep', scene='fcc_block dimers', bodies=len(O.bodies), contacts=nc, method='CD clumps',
               quantity='time per contact-sweep', value=tcl / nc * 1e9, unit='ns')
        print('  clump/sphere time per contact-sweep: %.2f (fast path), %.2f (general path)' % (tcl / nc / (t / n), tcl / nc / (tg / n)))
        scenes.fcc_block(target / 6.2, warnUnconverged=False)   # the sphere block again, for what follows
        cd = yadecd.integrator()
        O.step()
        cd.momentum = False
    if not args.no_siconos:
        pb = fclib.local_problem(cd)
        ts = per_sweep(lambda k: siconos_time(pb, k))
        record(kind='sweep', scene='fcc_block', bodies=len(O.bodies), contacts=n, method='Siconos NSGS', quantity='time per contact-sweep', value=ts / n * 1e9, unit='ns')
        print('  Siconos/CD time per contact-sweep: %.2f' % (ts / t))
    if args.no_block_steps:
        continue
    breakdown('fcc_block', 3 if args.quick else 10)
    # determinism: a fixed coloured run from the same scene, hashed (compare across -j)
    scenes.fcc_block(target / 6.2, warnUnconverged=False, schedule='colours', maxIter=200)
    O.run(5, True)
    digest = velocity_digest()
    record(kind='determinism', scene='fcc_block', bodies=len(O.bodies), contacts=yadecd.integrator().nContacts, method='CD coloured',
           quantity='sha1 of velocities after 5 steps', value=digest, unit='')

for snapshot in args.snapshot:
    p = pile.scene_from_snapshot(snapshot)
    O.timingEnabled = True
    cd = yadecd.integrator()
    tol, maxit = cd.tolerance, cd.maxIter
    label = 'pile ' + os.path.basename(os.path.dirname(os.path.abspath(snapshot))) + '/' + os.path.basename(snapshot) + (' fed' if args.feed else '')
    step_loop(20, Feed(p, args.feed))  # rebuild contacts and warm start (snapshots hold no impulses)
    O.saveTmp('bench')
    # Every variant starts from a reloaded scene (reloading changes the memory layout, and times).
    # The first pass after the first reload ran 10-30% slower than later ones in every stage,
    # YADE's own included: it is run once more and discarded.
    O.loadTmp('bench')
    step_loop(args.pile_steps, Feed(p, args.feed))
    O.loadTmp('bench')
    O.timingEnabled = True
    breakdown(label, args.pile_steps, feed=Feed(p, args.feed))
    cd = yadecd.integrator()  # determinism: the default solver's velocities after the timed steps (compare across -j)
    record(kind='determinism', scene=label, bodies=len(O.bodies), contacts=cd.nContacts, method='CD',
           quantity='sha1 of velocities after %d steps' % args.pile_steps, value=velocity_digest(),
           unit='schedule %s, interface %d contacts' % (cd.schedule, cd.nInterface))
    # the same steps again: height order, plain Gauss–Seidel, general path, over-relaxation, coloured sweep
    for key in [v for v in args.pile_variants.split(',') if v]:
        method, attrs = PILE_VARIANTS[key]
        O.loadTmp('bench')
        O.timingEnabled = True
        for k, v in attrs.items():
            setattr(yadecd.integrator(), k, v)
        breakdown(label, args.pile_steps, method=method, feed=Feed(p, args.feed))

print('wrote', args.out)

"""CD against YADE's soft-contact MD on a pile at the paper's size, from the same state over the
same simulated time, fed by the same protocol.

    scripts/yade -j1 -n -x scripts/bench/cd_md_fullsize.py --snapshot RUN/snap.npz [--time 0.01] [--warmup 0.002]
        [--cd-dt 2e-4,1e-3] [--cd-tolerance 1e-3,3e-3] [--young 1e9,auto] [--md-scale-time] [--out docs/data/cd_md_fullsize.csv]

Every case restarts from the snapshot (``yadecd.pile.scene_from_snapshot``), keeps feeding grains
by the protocol's rule (200 per second, the same grains in every case), runs ``--warmup``
simulated seconds untimed (a snapshot holds no impulses: CD's first steps are cold solves, and MD's
springs must first take up the load) and then ``--time`` simulated seconds, timed: CD at the
paper's h = 2e-4 s (and any further ``--cd-dt``, e.g. the faster protocol's 1e-3) and tolerance 1e-3 (``--cd-tolerance``), MD (linear spring and
Coulomb slider, ``yadecd.compare.md``, global damping 0.2, O.dt = 0.5 · PWaveTimeStep) at each Young's
modulus of ``--young``. ``auto`` is the modulus at which MD's mean grain–grain overlap equals CD's:
a linear contact's overlap under a given load is inversely proportional to E, so it is read off
the MD case before it (E_auto = E_prev · overlap_prev / overlap_CD) and then *run*, not
extrapolated; ``1e9,auto,auto`` refines it once more.
Recorded per case: wall time, steps, wall time per simulated second, grains, contacts, and the
grain–grain overlaps at the end over the mean diameter, two ways: of the contacts that carry a
force, from the bodies' positions (``compare_pile.loaded_overlaps``; for CD beyond each contact's
``overlapAllowance``, the overlaps a state was built with), which is what ``auto`` matches; and,
for reference, from the contact geometry over all contacts (CD's is its mid-step predictor's,
which shows up to h/2 times a grain's approach speed, and includes its open near contacts).
Each case's wall time per simulated second is also given relative to the first CD case's. Use
a deposited or relaxed pile's snapshot (``cone_pile.py --separate`` builds one without
construction overlaps); run it on an idle machine.
"""
import argparse
import math
import datetime
import os
import sys
import time
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd (README: which yadecd)

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0]))))
import numpy as np  # noqa: E402
from yade import O  # noqa: E402
from yadecd import pile  # noqa: E402
from yadecd.compare.pile import loaded_overlaps, overlaps  # noqa: E402
from yadecd.io import write_csv  # noqa: E402

ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
ap.add_argument('--snapshot', required=True, help='a pile snapshot .npz (its run.json beside it gives the protocol)')
ap.add_argument('--time', type=float, default=0.01, help='simulated seconds timed per case')
ap.add_argument('--warmup', type=float, default=0.002, help='simulated seconds run untimed first')
ap.add_argument('--md-scale-time', action='store_true', help='run each MD case after the first for --time and --warmup times '
                'sqrt(E_first / E): the same number of steps and of elastic oscillation periods, for the cost per simulated '
                'second of a stiff modulus; gravity is not scaled, so such a case does not reach load equilibrium and its '
                'overlaps are not a match')
ap.add_argument('--cd-dt', default='2e-4', help='CD time steps [s], comma-separated; the first is the one MD is matched to')
ap.add_argument('--cd-tolerance', default='1e-3', help="CD tolerances, comma-separated, one per --cd-dt or one for all "
                "(default the paper's 1e-3, whatever the snapshot's run used)")
ap.add_argument('--young', default='1e9,auto', help="MD Young's moduli [Pa], comma-separated; 'auto' matches CD's mean overlap")
ap.add_argument('--out', default=os.path.join(REPO, 'docs', 'data', 'cd_md_fullsize.csv'))
args = ap.parse_args()
if not os.path.exists(args.snapshot):
    ap.error('--snapshot %s: no such file (build one with scripts/bench/cone_pile.py)' % args.snapshot)
if args.time <= 0 or args.warmup < 0:
    ap.error('--time must be positive and --warmup not negative')
moduli = [m.strip() for m in args.young.split(',') if m.strip()]
if moduli and moduli[0] == 'auto':
    ap.error("--young: 'auto' needs a numeric modulus before it")
try:
    cd_steps = [float(x) for x in args.cd_dt.split(',') if x.strip()]
except ValueError:
    ap.error('--cd-dt: comma-separated time steps in seconds, got %r' % args.cd_dt)
if not cd_steps or min(cd_steps) <= 0:
    ap.error('--cd-dt needs at least one positive time step')
try:
    cd_tols = [float(x) for x in args.cd_tolerance.split(',') if x.strip()]
except ValueError:
    ap.error('--cd-tolerance: comma-separated relative residuals, got %r' % args.cd_tolerance)
if len(cd_tols) == 1:
    cd_tols = cd_tols * len(cd_steps)
if len(cd_tols) != len(cd_steps) or min(cd_tols) <= 0:
    ap.error('--cd-tolerance: one positive value, or one per --cd-dt (%d), got %r' % (len(cd_steps), args.cd_tolerance))


def run_case(method, young=None, dt=None, tol=None, scale=1.0):
    """Restart from the snapshot, feed and run --time simulated seconds; returns the CSV row."""
    over = dict(method=method, dt=dt, tolerance=tol) if method == 'CD' else dict(method='MD', young=young, md_safety=0.5, md_damping=0.2)
    p = pile.scene_from_snapshot(args.snapshot, **over)
    period = pile.creation_period(p['rate'], p['dt'])
    feeder = pile.Feeder(p, np.random.default_rng(p['seed'] + 77), {})
    sim, warmup = args.time * scale, args.warmup * scale
    warm, steps = int(round(warmup / O.dt)), int(round(sim / O.dt))
    t0, last = time.time(), time.time()
    for k in range(warm + steps):
        if k == warm:
            t0 = time.time()
        if k % period == 0:
            feeder.create()
        O.step()
        if time.time() - last > 60:
            last = time.time()
            print('  %s %s: step %d/%d' % (method, young or '', k + 1, warm + steps), flush=True)
    wall = time.time() - t0
    omax, omean = overlaps()
    lmax, lmean, loaded = loaded_overlaps(beyond_allowance=(method == 'CD'))
    grains = sum(1 for b in O.bodies if b and b.dynamic and b.shape.__class__.__name__ == 'Sphere')
    row = dict(date=datetime.date.today().isoformat(), snapshot=os.path.relpath(args.snapshot, REPO) if args.snapshot.startswith(REPO) else args.snapshot,
               method=method, young_Pa='' if young is None else '%.4g' % young, dt_s='%.4g' % O.dt,
               tolerance='' if tol is None else '%.4g' % tol, steps=steps,
               sim_time_s=sim, wall_s='%.2f' % wall, wall_per_sim_s='%.1f' % (wall / sim), grains=grains,
               contacts=O.interactions.countReal(), loaded_contacts=loaded,
               loaded_overlap_mean_over_d='%.3e' % lmean, loaded_overlap_max_over_d='%.3e' % lmax,
               geom_overlap_mean_over_d='%.3e' % omean, geom_overlap_max_over_d='%.3e' % omax)
    print('  '.join('%s=%s' % kv for kv in row.items()), flush=True)
    return row, wall, lmean


rows = []
row, cd_wall, cd_overlap = run_case('CD', dt=cd_steps[0], tol=cd_tols[0])
rows.append(row)
for dt, tol in zip(cd_steps[1:], cd_tols[1:]):
    rows.append(run_case('CD', dt=dt, tol=tol)[0])
last, first = None, None
for m in moduli:
    if m == 'auto':
        e1, o1 = last
        young = e1 * o1 / cd_overlap
        print('auto: E = %.3g Pa (from E = %.3g Pa, overlap %.3e d, CD %.3e d)' % (young, e1, o1, cd_overlap), flush=True)
    else:
        young = float(m)
    first = young if first is None else first
    row, wall, ov = run_case('MD', young, scale=math.sqrt(first / young) if args.md_scale_time else 1.0)
    last = (young, ov)
    rows.append(row)
for r in rows:   # wall time per simulated second, relative to the first CD case's
    r['over_first_cd_per_sim_s'] = '%.2f' % (float(r['wall_s']) / float(r['sim_time_s']) / (cd_wall / args.time))
write_csv(args.out, rows)

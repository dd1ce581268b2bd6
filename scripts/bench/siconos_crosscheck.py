"""Cross-check one step of a CD run against Siconos.

    scripts/yade -n -x scripts/bench/siconos_crosscheck.py [--snapshot RUN/snap_0008.000.npz [--feed] [--dt H] | --fcc 1e4]
                                                          [--tol 1e-6] [--out docs/data/siconos_crosscheck.csv]

Takes a scene (a pile state rebuilt from a snapshot, fed by the pile protocol meanwhile with
``--feed`` as save_step.py does, or an FCC block), runs a few warm-up steps, then one step with the
engine at ``--tol``. That step's frictional contact problem is written in FCLIB's HDF5 layout
(``--fclib``, with the engine's warm start as FCLIB's guess, for scripts/bench/siconos_solvers.py),
read back, and solved by Siconos' NSGS from zero and from
the engine's previous-step impulses (the same warm start the engine had), continued in chunks
until it reaches the engine's residual. Reported for every solution, under one common definition (Siconos' relative natural-map error, ρ = 1, see
``yadecd.export.fclib.residual``): the residual, sweeps and wall time to tolerance, and the agreement
of impulses and velocities. Appends one CSV row per solver.
"""
import argparse
import datetime
import os
import sys

import numpy as np

from yade import O
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd (README: which yadecd)
import yadecd
from yadecd import scenes, pile  # noqa: E402
from yadecd.export import fclib  # noqa: E402
from yadecd.io import append_csv  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0]))))  # inside YADE __file__ is the yade executable
parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
parser.add_argument('--snapshot', default='', help='pile snapshot .npz (default: an FCC block)')
parser.add_argument('--feed', action='store_true', help='snapshot: create grains by the pile protocol during the steps')
parser.add_argument('--dt', type=float, default=None, help="snapshot: the time step [s] (default: the run's)")
parser.add_argument('--fcc', type=float, default=1e4, help='contacts of the FCC block when no snapshot')
parser.add_argument('--warmup', type=int, default=20, help='steps before the checked one')
parser.add_argument('--tol', type=float, default=1e-6, help="engine tolerance (its own residual) for the checked step")
parser.add_argument('--fclib', default='/tmp/yadecd_step.hdf5', help='where the FCLIB file of the step goes')
parser.add_argument('--export-only', action='store_true', help='write the FCLIB file and stop (no Siconos solve, no CSV row)')
parser.add_argument('--max-sweeps', type=int, default=400000, help='Siconos gives up here')
parser.add_argument('--out', default=os.path.join(REPO, 'docs', 'data', 'siconos_crosscheck.csv'))
args = parser.parse_args(sys.argv[1:])

if (args.feed or args.dt is not None) and not args.snapshot:
    parser.error('--feed and --dt go with --snapshot')
if args.dt is not None and not args.dt > 0:
    parser.error('--dt takes a positive time step')
feeder = None
if args.snapshot:
    p = pile.scene_from_snapshot(args.snapshot, **({'dt': args.dt} if args.dt is not None else {}))
    scene = 'pile %s%s, h = %g s' % (os.path.basename(args.snapshot), ', fed' if args.feed else '', p['dt'])
    if args.feed:
        feeder, period = pile.Feeder(p, np.random.default_rng(p['seed'] + 77), {}), pile.creation_period(p['rate'], p['dt'])
else:
    scenes.fcc_block(args.fcc / 6.2)
    scene = 'fcc_block'
cd = yadecd.integrator()
cd.warnUnconverged = False
O.timingEnabled = True
for k in range(args.warmup):
    if feeder and O.iter % period == 0:
        feeder.create()
    O.step()
if feeder and O.iter % period == 0:
    feeder.create()
warm = {(i.id1, i.id2): np.array(i.phys.impulse) for i in O.interactions if i.isReal}

cd.tolerance, cd.maxIter = args.tol, 200000
cd.timingDeltas.reset()
O.step()
t_engine = dict((l, ns) for l, ns, c in cd.timingDeltas.data)['solveImpulses'] * 1e-9
pb = fclib.local_problem(cd)
# The engine's warm start of this step: last step's global impulses in this step's local frames
# (n, t1, t2), built as the engine builds them; the geometry still holds this step's normals.
ids = [(int(i), int(j)) for i, j in pb['ids']]
r_warm = np.zeros(3 * len(ids))
for a, pair in enumerate(ids):
    if pair in warm:
        n = np.array(O.interactions[pair[0], pair[1]].geom.normal)
        t1 = np.cross(n, [1, 0, 0] if abs(n[0]) < 0.57 else [0, 1, 0])
        t1 /= np.linalg.norm(t1)
        r_warm[3 * a:3 * a + 3] = [warm[pair] @ n, warm[pair] @ t1, warm[pair] @ np.cross(n, t1)]
fclib.write(args.fclib, pb, title='YADE CD step',
            description='%s, step %d, %d contacts; engine: %d sweeps to its own residual %.3g (tolerance %g)'
            % (scene, O.iter, len(pb['mu']), cd.iterations, cd.residual, cd.tolerance),
            math_info='u = W r + q; r in C_mu, u + mu|u_T| e_N in C_mu*, orthogonal', guess=r_warm)
back = fclib.read(args.fclib)
W, q, mu = back['W'], back['q'], back['mu']
res_engine = fclib.residual(W, q, mu, pb['r'])
print('%s: %d contacts, engine: %d sweeps, %.3f s, own residual %.2e, common residual %.2e'
      % (scene, len(mu), cd.iterations, t_engine, cd.residual, res_engine))
if args.export_only:
    print('wrote', args.fclib)
    sys.exit(0)

rows = []
common = dict(date=datetime.date.today().isoformat(), scene=scene, contacts=len(mu))
rows.append(dict(common, solver='YADE CD (engine)', start='warm', sweeps=cd.iterations, seconds=t_engine,
                 common_residual=res_engine, max_dr_rel=0.0, max_du_rel=0.0))


def siconos_to_residual(r0, target, limit=args.max_sweeps):
    """Siconos NSGS continued in chunks of growing length from r0 until the common residual is
    at most ``target`` (Siconos' own stopping test uses another normalisation): sweeps and solve
    time summed over the chunks (set-up outside the timed part)."""
    r = np.zeros(3 * len(mu)) if r0 is None else r0.copy()
    sweeps, seconds, chunk = 0, 0.0, 100
    while True:
        s = fclib.solve_siconos(W, q, mu, tol=1e-300, max_iter=chunk, r0=r)
        r, sweeps, seconds = s['r'], sweeps + s['iterations'], seconds + s['seconds']
        res = fclib.residual(W, q, mu, r)
        if res <= target or sweeps >= limit:
            return dict(r=r, u=s['u'], sweeps=sweeps, seconds=seconds, residual=res, reached=res <= target)
        chunk = min(int(chunk * 1.5), limit - sweeps)


for start, r0 in (('cold', None), ('warm', r_warm)):
    s = siconos_to_residual(r0, res_engine)
    dr = np.abs(s['r'] - pb['r']).max() / np.abs(pb['r']).max()
    du = np.abs(s['u'] - pb['u']).max() / max(np.abs(q).max(), 1e-300)
    print('Siconos NSGS (%s start): %s common residual %.2e after %d sweeps, %.3f s; |Δr|/|r| %.1e, |Δu|/|q| %.1e'
          % (start, 'reached' if s['reached'] else 'did NOT reach', s['residual'], s['sweeps'], s['seconds'], dr, du))
    rows.append(dict(common, solver='Siconos NSGS', start=start, sweeps=s['sweeps'], seconds=s['seconds'],
                     common_residual=s['residual'], max_dr_rel=dr, max_du_rel=du))

os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
for row in rows:
    append_csv(args.out, row, list(rows[0]))
print('wrote', args.out, 'and', args.fclib)

"""Sweeps per step against the time step, with and without momentum, from one pile state.

    scripts/yade -j1 -n -x scripts/bench/sweeps_vs_dt.py SNAPSHOT.npz [--dt 2e-4,1e-3] [--momentum 1,0]
                  [--warmup-time 0.01] [--sim-time 0.03] [--tolerance T] [--csv OUT.csv]

For every (h, momentum) pair the pile is rebuilt from the snapshot (yadecd.pile.scene_from_snapshot,
the run's parameters but h), fed by the pile protocol (200 grains per second, the same grains in
every case) for ``--warmup-time`` simulated seconds so that contacts and warm starts are back, then
for ``--sim-time`` seconds while the solver's counts are recorded per step: sweeps, status
changes, sliding and sticking contacts. Sweep counts do not depend on the machine or on what else
runs on it; the wall times printed do (say so when quoting them).

Question it answers (docs/performance.md, "The time step at scale"): on the same states, how
much of the paper's h = 2e-4 sweep work per simulated second the faster protocol's h = 1e-3
needs, and how both grow with the pile.
"""
import argparse
import os
import sys
import time

import numpy as np

from yade import O
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd (README: which yadecd)

import yadecd
from yadecd import io as benchio, pile  # noqa: E402

ap = argparse.ArgumentParser(prog='sweeps_vs_dt.py', description=__doc__.split('\n')[0])
ap.add_argument('snapshot')
ap.add_argument('--dt', default='2e-4,1e-3', help='time steps [s], comma-separated')
ap.add_argument('--momentum', default='1,0', help='momentum settings (1, 0), comma-separated')
ap.add_argument('--warmup-time', type=float, default=0.01, help='simulated time before counting [s]')
ap.add_argument('--sim-time', type=float, default=0.03, help='simulated time counted [s]')
ap.add_argument('--tolerance', type=float, default=None, help="the solver's tolerance (default: the run's)")
ap.add_argument('--csv', default=None)
a = ap.parse_args(sys.argv[1:])
if not os.path.exists(a.snapshot):
    ap.error('no snapshot %s' % a.snapshot)
try:
    dts = [float(x) for x in a.dt.split(',') if x.strip()]
    moms = [bool(int(x)) for x in a.momentum.split(',') if x.strip()]
except ValueError as e:
    ap.error('--dt and --momentum take comma-separated numbers (%s)' % e)
if not dts or min(dts) <= 0 or not moms or not a.sim_time > 0 or a.warmup_time < 0:
    ap.error('--dt must be > 0, --sim-time > 0, --warmup-time >= 0, --momentum 1 and/or 0')
if a.tolerance is not None and not 0 < a.tolerance < 1:
    ap.error('--tolerance must lie in (0, 1)')

rows = []
for dt in dts:
    for momentum in moms:
        p = pile.scene_from_snapshot(a.snapshot, dt=dt)
        cd = yadecd.integrator()
        cd.momentum = momentum
        if a.tolerance is not None:
            cd.tolerance = a.tolerance
        feeder = pile.Feeder(p, np.random.default_rng(p['seed'] + 77), {})
        period = pile.creation_period(p['rate'], dt)
        n_warm, n_count = int(round(a.warmup_time / dt)), int(round(a.sim_time / dt))
        sweeps, changes, sliding, sticking, contacts, unconverged = [], [], [], [], [], 0
        wall0 = None
        for k in range(n_warm + n_count):
            if O.iter % period == 0:
                feeder.create()
            if k == n_warm:
                wall0 = time.time()
            O.step()
            if k >= n_warm:
                sweeps.append(cd.iterations)
                changes.append(cd.nStatusChanges)
                sliding.append(cd.nSliding)
                sticking.append(cd.nSticking)
                contacts.append(cd.nContacts)
                unconverged += 0 if cd.converged else 1
        wall = time.time() - (wall0 or time.time())
        s = np.array(sweeps, float)
        row = {'snapshot': os.path.basename(a.snapshot), 'snapshot_time_s': p.get('time', float('nan')),
               'grains': len(O.bodies), 'dt_s': dt, 'momentum': int(momentum), 'tolerance': cd.tolerance, 'steps': len(s),
               'contacts_mean': float(np.mean(contacts)), 'sweeps_median': float(np.median(s)),
               'sweeps_mean': float(np.mean(s)), 'sweeps_p90': float(np.quantile(s, 0.9)),
               'sweeps_per_sim_s': float(s.sum() / a.sim_time),
               'contact_sweeps_per_sim_s': float(np.dot(s, contacts) / a.sim_time),
               'status_changes_mean': float(np.mean(changes)), 'sliding_mean': float(np.mean(sliding)),
               'sticking_mean': float(np.mean(sticking)), 'unconverged_steps': unconverged,
               'wall_s': wall}
        rows.append(row)
        print('h=%g momentum=%d: %d steps, %.0f contacts, sweeps median %.0f mean %.0f p90 %.0f; '
              '%.3g contact-sweeps per simulated s; status changes %.1f, sliding %.0f, sticking %.0f per step; '
              '%d unconverged; %.0f s wall' % (dt, momentum, row['steps'], row['contacts_mean'], row['sweeps_median'],
                                               row['sweeps_mean'], row['sweeps_p90'], row['contact_sweeps_per_sim_s'],
                                               row['status_changes_mean'], row['sliding_mean'], row['sticking_mean'],
                                               unconverged, wall), flush=True)
if a.csv:
    benchio.write_csv(a.csv, rows)

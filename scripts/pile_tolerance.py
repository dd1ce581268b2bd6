"""How much do the pile's force analyses depend on the Gauss–Seidel tolerance?

    scripts/yade -n -x scripts/pile_tolerance.py RUN_DIR [--tolerance 1e-2] [--tight 1e-6] [--out FILE]
                                                 [--snapshot TIGHT.npz]

Loads the run's newest checkpoint (``PileRun.load``: YADE's archive, or a carried run's
``state.npz``; ``RUN_DIR/at_feed_end`` is the run's checkpoint at the end of its feed, kept by the runner), re-solves one step with the run's own tolerance (or ``--tolerance``) and with a much
tighter one (from the same saved state, same warm start), and compares the ground-pressure
profile (per ring) and band force densities (vertical and horizontal cuts through the pile).
Writes RUN_DIR/tolerance_effect.json and prints the relative changes: where they exceed the
ring error bars, the figure's numbers are solver noise. ``--snapshot`` also keeps the tight
step's snapshot (the state one step after the checkpoint, its forces solved to ``--tight``), which
``pile_figures.py`` analyses like any other: the figures of a run made at a loose tolerance then
carry the forces of a tight one.
"""
import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np
from yade import O
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)
from yadecd import pile, analysis as pa  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument('run_dir')
ap.add_argument('--tolerance', type=float, default=None, help="the tolerance to judge (default: the run's)")
ap.add_argument('--tight', type=float, default=1e-6)
ap.add_argument('--max-iter', type=int, default=200000)
ap.add_argument('--out', default=None)
ap.add_argument('--snapshot', default=None, help="keep the tight step's snapshot at this path (.npz)")
a = ap.parse_args(sys.argv[1:])
with open(os.path.join(a.run_dir, 'run.json')) as f:
    p = json.load(f)


def solve(tol):
    """One step of the run from its newest checkpoint with the forces solved to ``tol``: returns
    the snapshot of that step and a dict of its tolerance, sweeps, residual, convergence and wall
    time (with --snapshot, the tight solve's snapshot is also written there, birth times included)."""
    run = pile.PileRun.load(a.run_dir)   # YADE's archive, or rebuilt from state.npz (a carried run)
    cd = O.engines[-1]
    cd.tolerance, cd.maxIter, cd.warnUnconverged = tol, a.max_iter, False
    t0 = time.time()
    O.step()
    dt = time.time() - t0
    path = os.path.join(tempfile.mkdtemp(), 'snap.npz')
    pile.snapshot(path, {}, p)
    if a.snapshot and tol == a.tight:
        pile.snapshot(a.snapshot, run.births, p, t=run.clock.time())
    return pa.load_snapshot(path), dict(tolerance=tol, sweeps=cd.iterations, residual=cd.residual, converged=cd.converged, wall_s=dt)


results = {}
snaps = {}
for name, tol in (('run', a.tolerance or p['tolerance']), ('tight', a.tight)):
    snaps[name], results[name] = solve(tol)
    print('%-5s tolerance %.0e: %d sweeps, residual %.2e, %.1f s' % (name, tol, results[name]['sweeps'], results[name]['residual'], results[name]['wall_s']))

prof = pa.profile_and_slope(snaps['tight'])
d = pa.mean_diameter(snaps['tight'])
gp = {k: pa.ground_pressure(s, 2 * d) for k, s in snaps.items()}
p_run, p_tight, err = gp['run']['pressure_Pa'], gp['tight']['pressure_Pa'], gp['tight']['err_Pa']
ok = np.isfinite(p_tight) & (p_tight > 0)
ring_change = np.abs(p_run - p_tight)[ok] / p_tight[ok]
ring_vs_err = np.abs(p_run - p_tight)[ok] / np.maximum(err[ok], 1e-300)
H = prof['H']
bands = []
for frac in (0.25, 0.5):
    z = frac * H
    for r0, r1 in ((0.0, 0.5 * prof['base_radius'] * (1 - frac)),):
        T = {k: pa.band_force_density(s, (r0, z), (r1, z)) for k, s in snaps.items()}  # horizontal annulus
        tr, tt = np.array(T['run'].T), np.array(T['tight'].T)
        bands.append(dict(kind='annulus', z_m=z, r0_m=r0, r1_m=r1, T_run_Pa=tr.tolist(), T_tight_Pa=tt.tolist(),
                          rel_change=float(np.linalg.norm(tr - tt) / max(np.linalg.norm(tt), 1e-300))))
    rc = 0.3 * prof['base_radius']
    T = {k: pa.band_force_density(s, (rc, z + d), (rc, z - d)) for k, s in snaps.items()}  # cylinder
    tr, tt = np.array(T['run'].T), np.array(T['tight'].T)
    bands.append(dict(kind='cylinder', z_m=z, r_m=rc, T_run_Pa=tr.tolist(), T_tight_Pa=tt.tolist(),
                      rel_change=float(np.linalg.norm(tr - tt) / max(np.linalg.norm(tt), 1e-300))))
summary = dict(solves=results, rings=dict(r_mid_m=gp['tight']['r_mid'][ok].tolist(), p_run_Pa=p_run[ok].tolist(),
                                          p_tight_Pa=p_tight[ok].tolist(), err_Pa=err[ok].tolist(),
                                          max_rel_change=float(ring_change.max()), max_change_over_error=float(ring_vs_err.max())),
               bands=bands)
print('ground pressure: largest ring change %.2e relative, %.2f error bars' % (ring_change.max(), ring_vs_err.max()))
for b in bands:
    print('band %-8s z=%.2f cm: relative change %.2e' % (b['kind'], 100 * b['z_m'], b['rel_change']))
out = a.out or os.path.join(a.run_dir, 'tolerance_effect.json')
with open(out, 'w') as f:
    json.dump(summary, f, indent=1)
print('saved', out)

"""Save one step of a pile state as a problem file for the core benchmark (build/cd_core_bench).

    scripts/yade -j1 -n -x scripts/bench/save_step.py RUN/snap_XXXX.npz OUT.cdp [--warmup 20] [--feed]
                  [--tolerance 1e-3] [--schedule 5] [--slabs 2]

The pile is rebuilt from the snapshot (yadecd.pile.scene_from_snapshot), stepped ``--warmup``
times so that contacts and warm-start impulses are back (snapshots hold none), creating grains by
the pile protocol meanwhile with ``--feed`` (as at the end of a deposition), and the next step's
input to the solver core is written to OUT (ContactDynamicsIntegrator.problemFile).
"""
import argparse
import os
import sys

import numpy as np

from yade import O

import yadecd
from yadecd import pile

ap = argparse.ArgumentParser(prog='save_step.py', description=__doc__.split('\n')[0])
ap.add_argument('snapshot')
ap.add_argument('out')
ap.add_argument('--warmup', type=int, default=20)
ap.add_argument('--feed', action='store_true')
ap.add_argument('--tolerance', type=float, default=None, help="solver tolerance (default: the run's)")
ap.add_argument('--schedule', type=int, default=None, help='sweepOrder (default: the run\'s)')
ap.add_argument('--slabs', type=int, default=None)
a = ap.parse_args(sys.argv[1:])
if not os.path.exists(a.snapshot):
    ap.error('no snapshot %s' % a.snapshot)
p = pile.scene_from_snapshot(a.snapshot)
cd = yadecd.integrator()
for key, value in (('tolerance', a.tolerance), ('sweepOrder', a.schedule), ('slabs', a.slabs)):
    if value is not None:
        setattr(cd, key, value)
feeder = pile.Feeder(p, np.random.default_rng(p['seed'] + 77), {}) if a.feed else None
period = pile.creation_period(p['rate'], p['dt'])
for k in range(a.warmup + 1):
    if feeder and O.iter % period == 0:
        feeder.create()
    if k == a.warmup:
        cd.problemFile = a.out
    O.step()
print('save_step: %s: %d bodies, %d contacts, %d sweeps in the saved step (tolerance %g, sweepOrder %d, slabs %d)'
      % (a.out, len(O.bodies), cd.nContacts, cd.iterations, cd.tolerance, cd.sweepOrder, cd.slabs))

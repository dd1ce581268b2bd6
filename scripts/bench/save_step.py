"""Save steps of a pile as problem files for the core benchmark (build/cd_core_bench).

    scripts/yade -j1 -n -x scripts/bench/save_step.py SOURCE OUT.cdp [--warmup 20] [--feed]
                  [--count 1] [--spacing 1] [--tolerance 1e-3] [--schedule slabs] [--slabs 2]

SOURCE is either
  - a snapshot (RUN/snap_XXXX.npz): the pile is rebuilt from it (yadecd.pile.scene_from_snapshot)
    and stepped ``--warmup`` times so that contacts and warm-start impulses are back (snapshots
    hold none), creating grains by the pile protocol meanwhile with ``--feed`` (as at the end of
    a deposition); or
  - a run directory (one holding run.json and a checkpoint, e.g. a carried run in runs/): the run
    is resumed from its newest checkpoint in a scratch copy (the run itself is never touched) and
    advanced ``--warmup`` steps by its own protocol (feeding included): the saved steps are the
    run's own, with its impulses, spins and landing history.

Then the next step's input to the solver core is written to OUT
(ContactDynamicsIntegrator.problemFile); with ``--count N``, N steps ``--spacing`` steps apart are
written to OUT with _0 … _{N−1} before its extension.
"""
import argparse
import os
import shutil
import sys
import tempfile

import numpy as np

from yade import O
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd (README: which yadecd)

import yadecd
from yadecd import pile  # noqa: E402

ap = argparse.ArgumentParser(prog='save_step.py', description=__doc__.split('\n')[0])
ap.add_argument('source', help='a snapshot (.npz) or a run directory')
ap.add_argument('out')
ap.add_argument('--warmup', type=int, default=20)
ap.add_argument('--feed', action='store_true', help='snapshots: create grains by the protocol during the steps (runs always do)')
ap.add_argument('--count', type=int, default=1, help='steps to save')
ap.add_argument('--spacing', type=int, default=1, help='steps between two saved steps')
ap.add_argument('--tolerance', type=float, default=None, help="solver tolerance (default: the run's)")
ap.add_argument('--schedule', choices=('height', 'colours', 'slabs'), default=None, help='sweep schedule (default: the run\'s)')
ap.add_argument('--slabs', type=int, default=None)
ap.add_argument('--dt', type=float, default=None, help="snapshots: the time step [s] (default: the run's)")
a = ap.parse_args(sys.argv[1:])
if not os.path.exists(a.source):
    ap.error('no snapshot or run directory %s' % a.source)
if a.warmup < 0 or a.count < 1 or a.spacing < 1:
    ap.error('need --warmup >= 0, --count >= 1 and --spacing >= 1')
from_run = os.path.isdir(a.source)
if from_run and not os.path.exists(os.path.join(a.source, 'run.json')):
    ap.error('%s is a directory without run.json: not a pile run' % a.source)
if a.dt is not None and (from_run or not a.dt > 0):
    ap.error('--dt takes a positive time step, and only with a snapshot (a run keeps its own)')


def outputs():
    if a.count == 1:
        return [a.out]
    stem, ext = os.path.splitext(a.out)
    return ['%s_%d%s' % (stem, i, ext or '.cdp') for i in range(a.count)]


def configure(cd):
    for key, value in (('tolerance', a.tolerance), ('schedule', a.schedule), ('slabs', a.slabs)):
        if value is not None:
            setattr(cd, key, value)


def report(path, cd):
    print('save_step: %s: %d bodies, %d contacts, %d sweeps in the saved step (tolerance %g, schedule %s, slabs %d)'
          % (path, len(O.bodies), cd.nContacts, cd.iterations, cd.tolerance, cd.schedule, cd.slabs), flush=True)


if from_run:
    from yadecd.runs.carry import carry
    scratch = tempfile.mkdtemp(prefix='save_step_')
    try:
        copy = os.path.join(scratch, 'run')   # the run's portable part; the run itself is never touched
        carry(a.source, copy, snap_every=1e9, log=lambda m: None)
        run = pile.PileRun.resume(copy, {}, log=lambda m: print('save_step: ' + m, flush=True))
        cd = O.engines[-1]
        configure(cd)
        dt = run.p['dt']
        t_end = pile.feed_end_time(run.p) + run.p['relax']
        steps = a.warmup + (a.count - 1) * a.spacing + 1
        if run.clock.time() + steps * dt > t_end + 0.5 * dt:
            sys.exit('save_step: the run in %s ends at t = %.3f s and its checkpoint is at t = %.3f s: fewer than the %d '
                     'steps asked are left; save steps from one of its snapshots instead'
                     % (a.source, t_end, run.clock.time(), steps))
        run.advance(run.clock.time() + a.warmup * dt)
        for i, path in enumerate(outputs()):
            if i and a.spacing > 1:
                run.advance(run.clock.time() + (a.spacing - 1) * dt)
            cd.problemFile = path
            run.advance(run.clock.time() + dt)
            report(path, cd)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
else:
    p = pile.scene_from_snapshot(a.source, **({'dt': a.dt} if a.dt is not None else {}))
    cd = yadecd.integrator()
    configure(cd)
    feeder = pile.Feeder(p, np.random.default_rng(p['seed'] + 77), {}) if a.feed else None
    period = pile.creation_period(p['rate'], p['dt'])
    saved = {a.warmup + i * a.spacing: path for i, path in enumerate(outputs())}   # step index -> file
    for k in range(max(saved) + 1):
        if feeder and O.iter % period == 0:
            feeder.create()
        if k in saved:
            cd.problemFile = saved[k]
        O.step()
        if k in saved:
            report(saved[k], cd)

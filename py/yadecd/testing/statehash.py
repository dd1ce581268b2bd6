"""State hashes of the engine on fixed scenes: the bit-for-bit guard of solver refactors.

Each case builds a scene of :mod:`yadecd.scenes` (or a small pile), sets the integrator's options,
runs a fixed number of steps and hashes the exact state: positions, orientations, velocities and
angular velocities of every body, and every contact's impulse (contacts in (id1, id2) order, since
the container's order carries no physics). ``tests/data/state_hashes.json`` holds the hashes the
engine gave before a refactor, for one and two threads (``scripts/state_hashes.py`` writes it);
``tests/engine/test_state_hashes.py`` requires the same hashes after it.

The cases cover every sweep schedule (with parallel stages, slabs cut into columns too), momentum on and off, the sphere fast path and the general
3×3 path, over-relaxation, a sparser residual check, restitution, a hyperstatic block, a mass
ratio and a fed pile.
"""
import hashlib
import os
import tempfile

import numpy as np

from yade import O

from .. import integrator, scenes

# name -> (builder, builder kwargs, integrator options, steps)
CASES = {}


def _case(name, build, steps, **options):
    """A case; its position correction is the plain one (the engine's default) unless
    ``correctionMomentum=True`` is given. Its sweeps use the threads at any size
    (``parallelMinContacts`` 0): these scenes are below the default threshold, and the
    two-thread hashes must exercise the parallel stages."""
    options.setdefault('correctionMomentum', False)
    options.setdefault('parallelMinContacts', 0)
    CASES[name] = (build, options, steps)


def _loose(**opts):
    return scenes.random_loose_packing(n=30, seed=3, **opts)


# case names keep the schedules' integer codes (1 height, 4 colours, 5 slabs): they are the keys of
# tests/data/state_hashes.json
_SCHEDULE = {1: 'height', 4: 'colours', 5: 'slabs'}
for _order in (1, 4, 5):
    _case('loose30_order%d' % _order, _loose, 300, schedule=_SCHEDULE[_order])
for _order in (1, 4, 5):
    _case('loose30_order%d_plain' % _order, _loose, 300, schedule=_SCHEDULE[_order], momentum=False)
    _case('loose30_order%d_general' % _order, _loose, 300, schedule=_SCHEDULE[_order], sphereFastPath=False)
_case('loose30_relaxation', _loose, 300, schedule='height', momentum=False, relaxation=1.5)
_case('loose30_check_every4', _loose, 300, schedule='slabs', checkEvery=4)
_case('fcc1000_order1', lambda **o: scenes.fcc_block(1000, **o), 5, schedule='height')
_case('fcc1000_order5', lambda **o: scenes.fcc_block(1000, **o), 5, schedule='slabs', slabs=4)
# parallel stages: colours of ≥ 64 contacts, slabs of ≥ 256 inner contacts, with landings (the
# position correction at work) in the loose 300-grain packing
_case('fcc1000_order4', lambda **o: scenes.fcc_block(1000, **o), 5, schedule='colours')
for _order in (1, 4, 5):
    _case('loose300_order%d' % _order, lambda **o: scenes.random_loose_packing(n=300, box=0.08, seed=5, **o), 600,
          schedule=_SCHEDULE[_order])
_case('mass_ratio100', lambda **o: scenes.mass_ratio_stack(100.0, **o), 50, tolerance=1e-10)
_case('binary_restitution', lambda **o: scenes.binary_collision((1.0, 0.2, 0), (-0.5, 0, 0.1), en=0.6, et=0.2,
                                                                gap=1e-4, offset=0.004), 40)
_case('pile60', None, 1500)
# the accelerated position correction (correctionMomentum, opt-in): landings in the loose packing
# with height, colour and slab schedules, and the fed pile
for _order in (1, 4, 5):
    _case('loose300_order%d_corrmom' % _order, lambda **o: scenes.random_loose_packing(n=300, box=0.08, seed=5, **o), 600,
          schedule=_SCHEDULE[_order], correctionMomentum=True)
_case('pile60_corrmom', None, 1500, correctionMomentum=True)
# slabs cut into columns (a two-dimensional decomposition): the block with four parts, the loose
# packing with landings with six
_case('fcc1000_columns', lambda **o: scenes.fcc_block(1000, **o), 5, schedule='slabs', slabs=2, slabsAcross=2)
_case('loose300_columns', lambda **o: scenes.random_loose_packing(n=300, box=0.08, seed=5, **o), 600,
      schedule='slabs', slabs=2, slabsAcross=3)
# bodies owned by parts (slabsOwnBodies, opt-in): the fed pile in two slabs, the loose packing
# with landings in 2 x 3 columns
_case('pile60_owned', None, 1500, schedule='slabs', slabs=2, slabsOwnBodies=True)
_case('loose300_columns_owned', lambda **o: scenes.random_loose_packing(n=300, box=0.08, seed=5, **o), 600,
      schedule='slabs', slabs=2, slabsAcross=3, slabsOwnBodies=True)


def state_digest():
    """SHA-256 (hex) of the exact state of every body and every real contact's impulse."""
    h = hashlib.sha256()
    bodies = np.array([tuple(b.state.pos) + tuple(b.state.vel) + tuple(b.state.angVel)
                       + tuple(b.state.ori[k] for k in range(4)) for b in O.bodies], dtype=float)
    h.update(bodies.tobytes())
    contacts = sorted((i.id1, i.id2) + tuple(i.phys.impulse) for i in O.interactions
                      if i.isReal and hasattr(i.phys, 'impulse'))
    h.update(np.array(contacts, dtype=float).tobytes())
    return h.hexdigest()


def run_case(name):
    """Build, run and hash one case; returns (digest, steps run, contacts at the end)."""
    build, options, steps = CASES[name]
    if build is None:      # the fed pile: the protocol itself, 60 grains, 0.3 s, the case's options by their pile names
        from .. import pile
        from ..pile.protocol import SOLVER_OPTIONS
        solver = {key: options[attr] for key, attr in SOLVER_OPTIONS.items() if attr in options}
        with tempfile.TemporaryDirectory() as tmp:
            pile.run(os.path.join(tmp, 'run'), n_grains=60, relax=0.0, seed=7, snap_every=1e9, log=lambda s: None, **solver)
    else:
        build()
        cd = integrator()
        for key, value in options.items():
            setattr(cd, key, value)
        cd.warnUnconverged = False
        O.run(steps, True)
    return state_digest(), O.iter, O.interactions.countReal()

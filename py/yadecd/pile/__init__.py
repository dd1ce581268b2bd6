"""Moreau's 3D sand pile (paper §IV.2), built with the Contact Dynamics engine.

Protocol (defaults are the paper's, :data:`protocol.PROTOCOL`; SI units inside):

- grains: spheres with diameters uniform in [0.25, 0.5] cm, density 1000 kg/m³ (inferred from
  the paper's bulk density 0.615 g/cm³ at a packing fraction near 0.6); or (``grain_shape``)
  rigid clumps of spheres of the same volume distribution (:mod:`.grains`), created in a
  uniformly random orientation;
- floor: a random paving of fixed grains of the same size distribution, resting on the plane
  z = 0 (a wall at z = 0 under it catches grains that slip between paving grains);
- friction 0.4 everywhere, restitution 0, gravity 9.81 m/s², time step 2e-4 s;
- creation: one grain at a time, 200 per second, at zero velocity, its centre on a vertical
  through a uniformly random point of the disc of radius 0.8 cm about the axis Oz, at the
  lowest height at which it rests, without overlap, on a grain met on that vertical (in flight
  or not), on the paving or on the plane (:func:`build.creation_height`).

``method='MD'`` runs the same protocol with YADE's soft contacts instead (the CD-versus-MD
comparison of a pile, ``scripts/compare_pile.py``).

A run directory holds ``run.json`` (the parameters), ``snap_<time>.npz`` snapshots (the data
every analysis needs, :func:`write.snapshot`), ``ckpt/`` (verified checkpoint units to resume
from, :class:`runner.PileRun` and docs/reliability.md), ``progress.csv`` and ``segments.csv``.

===================  =========================================================================
:mod:`.protocol`     parameters and defaults, their validation, the feed and snapshot schedule
                     (imports without YADE)
:mod:`.grains`       grain shapes (spheres, clumps of spheres of the same volume), their mass
                     properties, random orientations, the resting height of a dropped grain
                     (imports without YADE)
:mod:`.build`        paving, grain creation, engines, scenes from snapshots, the cone state
:mod:`.write`        snapshots of a running scene
:mod:`.runner`       :class:`PileRun` (start, resume, advance), branches, :func:`run`
:mod:`.rolloff`      how far a grain rolls on the paving (the floor's roughness check)
===================  =========================================================================

The names of these modules are reachable from the package (``from yadecd import pile;
pile.run(...)``); they are loaded on first use, so that ``yadecd.pile.protocol`` imports without
YADE.
"""
import importlib

_WHERE = {
    'protocol': ('DEFAULTS', 'expected_base_radius', 'feed_end_time', 'snapshot_times', 'RESUME_MAY_CHANGE',
                 'BRANCH_MAY_CHANGE', 'epoch_list', 'check_params', 'disk_need', 'creation_period', 'feed_time',
                 'engine_options', 'PROTOCOL', 'SOLVER_DEPARTURES', 'SOLVER_OPTIONS', 'RENAMED', 'upgrade',
                 'read_run_json', 'solver_defaults', 'defaults'),
    'build': ('paving', 'build_scene', 'add_grain', 'add_clump', 'set_clump_mass', 'set_engines', 'solver_stats', 'scene_from_snapshot', 'cone_state',
              'separating_dilation', 'creation_height', 'Feeder', 'Clock'),
    'write': ('snapshot',),
    'grains': ('SHAPES', 'shape', 'equivalent_radius', 'member_radius', 'mass_properties', 'circumradius', 'aspect_ratio',
               'union_moments', 'random_rotation', 'resting_height'),
    'runner': ('ETA_EXPONENT', 'eta_seconds', 'preflight', 'RUN_FILES', 'PileRun', 'duration', 'has_run', 'clear_run',
               'branch', 'run', 'CheckpointError', 'RunStateError'),
}
_OWNER = {name: module for module, names in _WHERE.items() for name in names}
__all__ = sorted(_OWNER)


def __getattr__(name):
    module = _OWNER.get(name)
    if module is None:
        raise AttributeError("module 'yadecd.pile' has no attribute %r" % name)
    value = getattr(importlib.import_module('.' + module, __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_OWNER))

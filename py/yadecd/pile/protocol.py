"""The pile protocol: every parameter of a run with its default (the paper's values), the one
validation of a parameter set, and the schedule derived from it (feed, snapshots, disk needed).

Imports without YADE (the ensemble driver reads it under plain Python).
"""

import math

import numpy as np

from .grains import SHAPES

#: The solver options a pile run sets, by their pile names (the engine attribute's name in
#: snake_case). :class:`ContactDynamicsIntegrator` defines each one, its default and its
#: validation (:func:`yadecd.solver_options`); the pile states only where it departs
#: (:data:`SOLVER_DEPARTURES`).
SOLVER_OPTIONS = {'tolerance': 'tolerance', 'max_iter': 'maxIter', 'relaxation': 'relaxation', 'momentum': 'momentum',
                  'correction_momentum': 'correctionMomentum', 'schedule': 'schedule', 'slabs': 'slabs',
                  'slabs_across': 'slabsAcross', 'slabs_own_bodies': 'slabsOwnBodies',
                  'parallel_min_contacts': 'parallelMinContacts'}

#: The solver options that YADE's archive does not keep (``Attr::noSave``): a resume from a
#: checkpoint's scene sets them again from the run's parameters.
UNSAVED_OPTIONS = ('correction_momentum', 'parallel_min_contacts', 'slabs_across', 'slabs_own_bodies')

#: Where the pile departs from the engine's defaults (why: docs/pile.md, "Solver settings").
SOLVER_DEPARTURES = dict(
    tolerance=1e-3,      # the forces a pile's analyses read need no more (docs/pile.md, "Force accuracy")
    max_iter=2000,
    schedule='slabs',    # parallel on two threads, and keeps the upward order piles need
)

#: The protocol's own parameters, the paper's values (SI units; the paper's cm in comments).
PROTOCOL = dict(
    n_grains=14000,      # grains to create
    grain_shape='sphere',  # 'sphere' (the paper's), or a clump of spheres of that volume: 'dimer', 'tetra' (grains.SHAPES)
    d_min=0.0025,        # m   (0.25 cm)
    d_max=0.0050,        # m   (0.50 cm)
    rho=1000.0,          # kg/m³
    mu=0.4,
    en=0.0,
    g=9.81,              # m/s²
    dt=2e-4,             # s
    rate=200.0,          # grains per second
    feed_radius=0.008,   # m   (0.8 cm)
    floor_radius=0.0,    # m; 0: sized from n_grains (1.4 × the expected base radius)
    relax=0.0,           # s of relaxation after the last grain
    seed=1,
    epochs='',           # comma-separated snapshot times [s]; '' = every snap_every
    snap_every=2.0,      # s between snapshots when epochs is empty
    checkpoint_every=60.0,  # wall-clock seconds between checkpoints
    vtk=False,           # also export VTK files (ParaView) at snapshots
    stop_time=0.0,       # s; > 0: checkpoint and stop there (continue later with resume)
    method='CD',         # 'CD', or 'MD': YADE's soft contacts (linear spring–slider) on the same protocol
    young=1e7,           # Pa; MD only (contact stiffness kn = young·r)
    md_safety=0.5,       # MD only: O.dt = md_safety·PWaveTimeStep() (replaces dt)
    md_damping=0.2,      # MD only: Cundall's non-viscous damping, as YADE deposition scripts use
)

#: What a run sets that is not the engine's default: the protocol and the solver's departures.
#: The full parameter set of a run, with the engine's defaults, is :func:`defaults` (needs YADE).
DEFAULTS = dict(PROTOCOL, **SOLVER_DEPARTURES)

#: Parameters renamed since earlier releases: old name -> (new name, {old value: new value}).
#: :func:`upgrade` maps them, so that old ``run.json`` files and tables still load.
RENAMED = {'sweep_order': ('schedule', {1: 'height', 4: 'colours', 5: 'slabs'})}


def upgrade(p):
    """A copy of the parameter dict ``p`` with the keys of :data:`RENAMED` mapped to their
    current names and values. Raises ValueError for an old value that has no current one (a
    retired sweep order, say) or for a parameter given under both names with different values."""
    out = dict(p)
    for old, (new, values) in RENAMED.items():
        if old not in out:
            continue
        value = out.pop(old)
        if value not in values:
            raise ValueError('pile parameter %s=%r (now %s) has no current value: it must be one of %s'
                             % (old, value, new, ', '.join('%r' % v for v in values)))
        if new in out and out[new] != values[value]:
            raise ValueError('pile parameters %s=%r and %s=%r disagree: give %s only' % (old, value, new, out[new], new))
        out[new] = values[value]
    return out


def read_run_json(path):
    """The parameters a ``run.json`` holds, renamed keys mapped (:func:`upgrade`)."""
    import json
    with open(path) as f:
        return upgrade(json.load(f))


def solver_defaults():
    """The engine's defaults of the pile's :data:`SOLVER_OPTIONS`, by pile name (needs YADE)."""
    from .. import solver_options
    engine = solver_options()
    return {key: engine[attr] for key, attr in SOLVER_OPTIONS.items()}


def defaults():
    """Every parameter of a pile run with its default: the engine's solver defaults, overridden
    by the protocol's :data:`DEFAULTS` (needs YADE)."""
    return dict(solver_defaults(), **DEFAULTS)


def engine_options(p):
    """The solver options of the parameter dict ``p`` as :class:`ContactDynamicsIntegrator`
    attributes (``max_iter`` -> ``maxIter``...)."""
    return {attr: p[key] for key, attr in SOLVER_OPTIONS.items() if key in p}


def expected_base_radius(n, d_min, d_max, slope_deg=26.0, packing=0.6):
    """Base radius [m] of a cone of ``n`` grains at the given slope and packing fraction."""
    v_grain = math.pi / 6 * (d_max ** 4 - d_min ** 4) / (4 * (d_max - d_min))  # mean of d³ times π/6
    volume = n * v_grain / packing
    return (3 * volume / (math.pi * math.tan(math.radians(slope_deg)))) ** (1 / 3)


def feed_end_time(p):
    """Simulated time [s] at which the run ``p`` creates its last grain (:func:`feed_time`)."""
    return feed_time(p['n_grains'], p['rate'], p['dt'])


def snapshot_times(p, t_end):
    """Times [s] of a run's snapshots: its epochs, or every snap_every up to t_end (the last at t_end)
    and, when the run relaxes after the feed, the end of the feed too (the analyses' "end of feed"
    epoch, which the regular times need not hit: 25 s for 5000 grains, snap_every 2 s)."""
    if p['epochs']:
        return epoch_list(p['epochs'])
    k = max(1, int(round(t_end / p['snap_every'])))
    times = [t_end * (i + 1) / k for i in range(k)]
    t_feed = feed_end_time(p)
    if t_feed < t_end - 0.5 * p['dt'] and min(abs(t - t_feed) for t in times) > 0.5 * p['dt']:
        times = sorted(times + [t_feed])
    return times


# Options a resumed run may be given anew; any other option must equal the run's own.
RESUME_MAY_CHANGE = ('stop_time', 'checkpoint_every', 'vtk', 'parallel_min_contacts')


# what a branch (:func:`branch`) may change besides: how precisely each step is solved, not the
# pile's physics or protocol (grains, feed, time step, friction)
# (and the decomposition of the sweep: another order of the same Gauss–Seidel, for another machine)
BRANCH_MAY_CHANGE = RESUME_MAY_CHANGE + ('tolerance', 'max_iter', 'correction_momentum', 'slabs', 'slabs_across',
                                         'slabs_own_bodies')


def epoch_list(epochs):
    """The snapshot times [s] of a comma-separated string, sorted; ValueError names a bad one."""
    try:
        return sorted(float(t) for t in str(epochs).split(',') if t.strip())
    except ValueError:
        raise ValueError("epochs must be comma-separated times in seconds, not %r" % (epochs,)) from None


def check_params(p):
    """Raise ValueError naming the first bad parameter of a pile run (before any work is done).
    The protocol's parameters are checked here; the solver options by the engine itself (one
    validation: :class:`ContactDynamicsIntegrator` refuses what it cannot do). Needs YADE."""
    known = defaults()
    unknown = set(p) - set(known)
    if unknown:
        raise ValueError('unknown pile parameters: %s' % ', '.join(sorted(unknown)))
    for key, default in known.items():
        v = p[key]
        if isinstance(default, bool):
            ok = isinstance(v, (bool, np.bool_))
        elif isinstance(default, int) and key in SOLVER_OPTIONS:    # an integer attribute of the engine
            ok = isinstance(v, (int, np.integer)) and not isinstance(v, bool)
        elif isinstance(default, (int, float)):
            ok = isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) and math.isfinite(v)
        else:
            ok = isinstance(v, str)
        if not ok:
            raise ValueError('pile parameter %s must be %s, not %r' % (key, {bool: 'a bool', int: 'an integer', float: 'a number',
                                                                                 str: 'a string'}[type(default)], v))
    rules = [
        ('n_grains', p['n_grains'] >= 1 and int(p['n_grains']) == p['n_grains'], 'a positive integer'),
        ('d_min', p['d_min'] > 0, 'positive [m]'),
        ('d_max', p['d_max'] >= p['d_min'], '>= d_min [m]'),
        ('rho', p['rho'] > 0, 'positive [kg/m³]'),
        ('mu', p['mu'] >= 0, '>= 0'),
        ('en', 0 <= p['en'] <= 1, 'in [0, 1]'),
        ('g', p['g'] > 0, 'positive [m/s²]'),
        ('dt', p['dt'] > 0, 'positive [s]'),
        ('rate', p['rate'] > 0, 'positive [grains/s]'),
        ('feed_radius', p['feed_radius'] >= 0, '>= 0 [m]'),
        ('floor_radius', p['floor_radius'] >= 0, '>= 0 [m] (0: sized from n_grains)'),
        ('relax', p['relax'] >= 0, '>= 0 [s]'),
        ('snap_every', p['snap_every'] > 0, 'positive [s]'),
        ('checkpoint_every', p['checkpoint_every'] > 0, 'positive [s of wall time]'),
        ('stop_time', p['stop_time'] >= 0, '>= 0 [s]'),
        ('grain_shape', p['grain_shape'] in SHAPES, 'one of %s' % ', '.join(repr(k) for k in sorted(SHAPES))),
        ('method', p['method'] in ('CD', 'MD'), "'CD' or 'MD'"),
        ('young', p['young'] > 0, 'positive [Pa]'),
        ('md_safety', 0 < p['md_safety'] <= 1, 'in (0, 1]'),
        ('md_damping', 0 <= p['md_damping'] < 1, 'in [0, 1)'),
    ]
    for key, ok, what in rules:
        if not ok:
            raise ValueError('pile parameter %s must be %s (got %r)' % (key, what, p[key]))
    if any(t <= 0 for t in epoch_list(p['epochs'])):
        raise ValueError('pile parameter epochs must hold positive times (got %r)' % (p['epochs'],))
    from yade.wrapper import ContactDynamicsIntegrator
    for key, attr in SOLVER_OPTIONS.items():
        try:
            ContactDynamicsIntegrator(**{attr: p[key]})
        except Exception as e:   # the engine's own message names the attribute and the reason
            raise ValueError('pile parameter %s=%r: %s' % (key, p[key], e)) from None
    try:                         # options that are checked together (slabs × slabs_across)
        ContactDynamicsIntegrator(**engine_options(p))
    except Exception as e:
        raise ValueError('pile parameters %s: %s' % (', '.join('%s=%r' % (k, p[k]) for k in SOLVER_OPTIONS), e)) from None


def disk_need(p):
    """Bytes a run needs in its directory, estimated from its size: the checkpoints kept (three
    units at once while one is written, 1000 B per body each) and the snapshots (400 B per body
    each). Both allowances are above the sizes measured on piles (docs/reliability.md), so that
    a run that starts has room to finish."""
    floor_radius = p['floor_radius'] or 1.4 * expected_base_radius(p['n_grains'], p['d_min'], p['d_max'])
    d_mean = 0.5 * (p['d_min'] + p['d_max'])
    members = len(SHAPES[p.get('grain_shape', 'sphere')]['offsets'])
    per_grain = 1 if members == 1 else members + 1       # a clump is a body besides its members
    bodies = per_grain * p['n_grains'] + 0.55 * (floor_radius / (0.5 * d_mean)) ** 2
    t_end = feed_end_time(p) + p['relax']
    n_snaps = len(snapshot_times(p, t_end))
    return int(bodies * (3 * 1000 + n_snaps * 400) + 1e6)


def creation_period(rate=None, dt=None):
    """Steps between two grain creations: round(1/(rate·dt)), at least 1 (defaults: the
    protocol's rate and time step)."""
    rate = DEFAULTS['rate'] if rate is None else rate
    dt = DEFAULTS['dt'] if dt is None else dt
    return max(1, int(round(1.0 / (rate * dt))))


def feed_time(n_grains, rate=None, dt=None):
    """Simulated time [s] at which the last grain is created (one every :func:`creation_period` steps)."""
    dt = DEFAULTS['dt'] if dt is None else dt
    return n_grains * creation_period(rate, dt) * dt

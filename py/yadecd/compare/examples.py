"""YADE's own example scripts under Contact Dynamics: the soft engines of a script replaced by
:func:`yadecd.engines`, everything else of the script kept (docs/compare.md, "YADE's examples
under CD"; driver ``scripts/yade_examples.py``, one example ``scripts/example_under_cd.py``).

A script is run as written but for three substitutions in its text: ``O.run(...)`` calls
:func:`budget_run` (the engines are converted at its first call, and the steps are taken
synchronously within the example's step budget), ``O.wait()`` and ``waitIfBatch()`` return at
once, and the GUI (``yade.qt``) is an inert stand-in, since the runs are headless. After the
script's own code, the remaining budget is run.

The conversion (:func:`convert_engines`) replaces ForceResetter, the collider, the
InteractionLoop and NewtonIntegrator by ``yadecd.engines(gravity=<NewtonIntegrator's>)`` and keeps
every other engine (PyRunners, recorders, YADE's controllers) in its place before the integrator.
What CD has no use for is dropped and said: NewtonIntegrator's damping (CD dissipates by its
contact law) and the time steppers that read contact stiffness (rigid contacts have none).
"""
import math
import re
import sys
import time
import types

__all__ = ['EXAMPLES', 'convert_engines', 'substitute', 'observables', 'ExampleRun']

#: the examples run (path under YADE's examples/, what it exercises, step budget): clumps,
#: boxes, periodic cells, and a few sphere scenes, the typical scripts of each kind
EXAMPLES = (
    ('simple-scene/simple-scene.py', 'spheres, box', 20000),
    ('simple-scene/simple-scene-energy-tracking.py', 'spheres, box, energy', 20000),
    ('packs/packs.py', 'spheres, facets, predicates', 5000),
    ('test/clump.py', 'clumps, box', 20000),
    ('test/clumpPack.py', 'clumps from a clump cloud', 5000),
    ('test/clump-facet.py', 'clumps, facets', 20000),
    ('clumps/addToClump-example.py', 'clumps built by addToClump, box', 20000),
    ('clumps/replaceByClumps-example.py', 'replaceByClumps, box', 20000),
    ('clumps/releaseFromClump-example.py', 'releaseFromClump, box', 20000),
    ('clumps/save-load-clumps.py', 'clumps saved and loaded', 5000),
    ('clumps/clump-hopper-test.py', 'clumps in a facet hopper', 20000),
    ('clumps/triax-basic-with-clumps.py', 'clumps, TriaxialStressController', 5000),
    ('PeriodicBoundaries/periodic-simple.py', 'periodic, velGrad', 5000),
    ('PeriodicBoundaries/periodic-simple-shear.py', 'periodic, PeriTriaxController, shear', 5000),
    ('PeriodicBoundaries/periodic-triax.py', 'periodic, PeriTriaxController', 5000),
    ('PeriodicBoundaries/periodic-compress.py', 'periodic, PeriIsoCompressor', 5000),
    ('PeriodicBoundaries/periodic-shear.py', 'periodic, gravity, shear', 5000),
    ('PeriodicBoundaries/cellFlipping.py', 'periodic, flipCell', 5000),
    ('PeriodicBoundaries/periodicSandPile.py', 'periodic, boxes, pile', 5000),
)

#: engines that a CD scene replaces (their class names)
REPLACED = ('ForceResetter', 'InsertionSortCollider', 'SpatialQuickSortCollider', 'InteractionLoop', 'NewtonIntegrator')
#: engines that only a soft-contact scene can use: dropped, with the reason
DROPPED = {'GlobalStiffnessTimeStepper': 'reads contact stiffness, which rigid contacts do not have'}


def convert_engines(engine_list):
    """The CD engine list for a soft-contact one: ``(new list, notes)``. The kept engines keep
    their order, before the integrator; ``notes`` says what was dropped or changed.

    :raises ValueError: when the list has no NewtonIntegrator (nothing to convert)."""
    from .. import engines as cd_engines
    newton = [e for e in engine_list if type(e).__name__ == 'NewtonIntegrator']
    if not newton:
        raise ValueError('the engine list has no NewtonIntegrator: %s' % [type(e).__name__ for e in engine_list])
    newton = newton[0]
    notes, kept = [], []
    if newton.damping:
        notes.append('NewtonIntegrator damping %g dropped' % newton.damping)
    for e in engine_list:
        name = type(e).__name__
        if name in REPLACED:
            continue
        if name in DROPPED:
            notes.append('%s dropped (%s)' % (name, DROPPED[name]))
            continue
        kept.append(e)
    new = cd_engines(gravity=tuple(newton.gravity), extra=kept)
    if newton.label:
        new[-1].label = newton.label
    return new, notes


_RUN = re.compile(r'\bO\.run\s*\(')
_WAIT = re.compile(r'\bO\.wait\s*\(\s*\)')
_WAITBATCH = re.compile(r'\b(?:utils\.)?waitIfBatch\s*\(\s*\)')


def substitute(source):
    """The example's text with ``O.run(`` → ``budget_run(``, ``O.wait()`` and ``waitIfBatch()``
    → nothing (they return at once)."""
    source = _RUN.sub('budget_run(', source)
    source = _WAIT.sub('None', source)
    return _WAITBATCH.sub('None', source)


def _inert_qt():
    """A stand-in for ``yade.qt`` in headless runs: every attribute is a callable that does
    nothing and returns another stand-in."""
    class Inert(types.ModuleType):
        def __getattr__(self, name):
            if name.startswith('__'):
                raise AttributeError(name)
            return _Nothing()

    class _Nothing:
        def __call__(self, *a, **k):
            return _Nothing()

        def __getattr__(self, name):
            return _Nothing()

        def __setattr__(self, name, value):
            pass

        def __iter__(self):
            return iter(())

    return Inert('yade.qt')


def observables():
    """What the table compares between the two methods at the end: kinetic energy [J], the
    mean height of the dynamic bodies [m], the number of real contacts, the largest overlap over
    the smaller radius of the pair, and for a periodic cell the mean stress −tr(σ)/3 [Pa]."""
    from yade import O, utils
    bodies = [b for b in O.bodies if b is not None and b.dynamic and not b.isClumpMember]
    ke = sum(0.5 * b.state.mass * b.state.vel.squaredNorm() for b in bodies)
    zs = [b.state.pos[2] for b in bodies]
    worst = 0.0
    for i in O.interactions:
        if i.isReal and hasattr(i.geom, 'penetrationDepth') and hasattr(i.geom, 'refR1'):
            r = min(x for x in (i.geom.refR1, i.geom.refR2) if x > 0) if max(i.geom.refR1, i.geom.refR2) > 0 else float('nan')
            worst = max(worst, i.geom.penetrationDepth / r)
    out = dict(kinetic=ke, mean_z=sum(zs) / len(zs) if zs else float('nan'), contacts=len([i for i in O.interactions if i.isReal]),
               max_overlap=worst, time=O.time, iter=O.iter)
    if O.periodic:
        s = utils.getStress()
        out['pressure'] = -(s[0, 0] + s[1, 1] + s[2, 2]) / 3
    return out


class ExampleRun:
    """One example run by ``method`` ('cd': converted at the first ``O.run``; 'md': as written)
    with a budget of ``steps`` steps in all, headless."""

    def __init__(self, path, method, steps, log=print):
        if method not in ('cd', 'md'):
            raise ValueError("method must be 'cd' or 'md', not %r" % (method,))
        self.path, self.method, self.steps, self.log = path, method, int(steps), log
        self.converted, self.notes, self.taken = False, [], 0

    def convert(self):
        """Replace the script's engines by CD's (once, for a CD run; :func:`convert_engines`), keeping
        its notes of what was dropped or changed."""
        from yade import O
        if self.method == 'cd' and not self.converted:
            O.engines, notes = convert_engines(O.engines)
            self.notes.extend(notes)
            self.converted = True

    def budget_run(self, n=-1, wait=False, *rest):
        """``O.run(n)`` within the budget: converts the engines first (CD), then steps
        synchronously until n steps or the budget are done, or the scene pauses itself."""
        from yade import O
        self.convert()
        left = self.steps - self.taken
        todo = left if n is None or n < 0 else min(int(n), left)
        for _ in range(todo):
            O.step()
            self.taken += 1

    def execute(self):
        """Run the example; returns a dict (status 'ran' or 'failed', error, notes, steps,
        wall_s, observables)."""
        from yade import O
        import yade
        sys.modules['yade.qt'] = yade.qt = _inert_qt()
        try:
            import matplotlib
            matplotlib.use('Agg')
        except ImportError:
            pass
        with open(self.path) as f:
            source = substitute(f.read())
        # the script runs in __main__ itself, as under ``yade -x``: its PyRunner commands look
        # their functions up there
        namespace = vars(__import__('__main__'))
        namespace.update(budget_run=self.budget_run, __file__=self.path)
        start = time.time()
        status, error = 'ran', ''
        try:
            exec(compile(source, self.path, 'exec'), namespace)
            if not O.engines:
                raise RuntimeError('the example sets no engines')
            self.budget_run(-1)
        except Exception as e:     # the table reports any failure of the example, with its message
            status, error = 'failed', '%s: %s' % (type(e).__name__, str(e).strip().splitlines()[0] if str(e).strip() else '')
        obs = {}
        try:
            obs = observables()
        except Exception as e:     # a scene too broken to measure is still reported
            obs = {'error': str(e)}
        finite = all(not isinstance(v, float) or math.isfinite(v) for v in obs.values())
        if status == 'ran' and not finite:
            status, error = 'failed', 'non-finite state after %d steps' % self.taken
        return dict(example=self.path, method=self.method, status=status, error=error, notes=self.notes,
                    steps=self.taken, budget=self.steps, wall_s=time.time() - start, dt=O.dt, **obs)

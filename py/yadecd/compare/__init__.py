"""Contact Dynamics against YADE's soft-contact MD, on scenes with exact solutions and on piles.

=================  ===========================================================================
:mod:`.run`        one scene run by one method, its failure status and errors (re-exported here)
:mod:`.cases`      the scene cases and their exact solutions
:mod:`.measure`    measurements on a running scene (overlaps, energies, floor force)
:mod:`.md`         YADE's MD engines for the same scenes
:mod:`.sweep`      sweeps of time step and stiffness over the cases, with figures
:mod:`.pile`       CD against MD on a pile
:mod:`.shear`      periodic simple shear at controlled pressure: μ(I), φ(I) by both methods
:mod:`.examples`   YADE's own example scripts run under CD and as written
=================  ===========================================================================

The names of :mod:`.run` are reachable from the package (``from yadecd import compare;
compare.run(...)``), loaded on first use, so that the modules that need no YADE
(``examples``' list and engine conversion, for the driver scripts) import without it.
"""
import importlib


def __getattr__(name):
    if name == '__all__':
        return list(importlib.import_module('.run', __name__).__all__)
    if name.startswith('__'):
        raise AttributeError(name)
    run = importlib.import_module('.run', __name__)
    if not hasattr(run, name):
        raise AttributeError("module 'yadecd.compare' has no attribute %r" % name)
    value = getattr(run, name)
    globals()[name] = value
    return value

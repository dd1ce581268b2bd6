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

The names of :mod:`.run` are re-exported here (``from yadecd import compare; compare.run(...)``)
inside YADE; outside it, the package still imports, so that the modules that need no YADE
(``examples``' list and engine conversion, for the driver scripts) do.
"""
import importlib.util


def _have_yade():
    try:
        return importlib.util.find_spec('yade') is not None
    except (ImportError, ValueError):
        return False


if _have_yade():
    from .run import *  # noqa: F401,F403
    from .run import __all__  # noqa: F401

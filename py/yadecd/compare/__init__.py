"""Contact Dynamics against YADE's soft-contact MD, on scenes with exact solutions and on piles.

=================  ===========================================================================
:mod:`.run`        one scene run by one method, its failure status and errors (re-exported here)
:mod:`.cases`      the scene cases and their exact solutions
:mod:`.measure`    measurements on a running scene (overlaps, energies, floor force)
:mod:`.md`         YADE's MD engines for the same scenes
:mod:`.sweep`      sweeps of time step and stiffness over the cases, with figures
:mod:`.pile`       CD against MD on a pile
=================  ===========================================================================

Needs YADE (run inside it).
"""
from .run import *  # noqa: F401,F403
from .run import __all__  # noqa: F401

"""Contact Dynamics (Moreau's non-smooth, rigid-contact method) for YADE.

Import from any YADE script (the set-up installs this package into YADE's library directory)::

    from yadecd import engines
    O.engines = engines(gravity=(0, 0, -9.81))
    O.dt = 1e-4

The C++ classes (``ContactDynamicsIntegrator``, ``CDPhys``, ``Ip2_FrictMat_FrictMat_CDPhys``,
``Law2_ScGeom_CDPhys_Coulomb`` and the ``Ig2_*_CDScGeom`` / ``Bo1_Sphere_CDAabb`` functors) are
loaded by YADE at start-up and live in ``yade.wrapper`` like every other class.
"""
__all__ = ['engines', 'integrator', 'solver_options', 'SOLVER_OPTIONS']

# YADE is imported by the functions that need it, never at import time: yadecd.analysis,
# yadecd.pile.protocol, yadecd.io and most of yadecd.runs import without YADE (tests/analysis/test_layout.py).

#: The engine's solver options: the attributes of :class:`ContactDynamicsIntegrator` that say how
#: each step is solved. The C++ class is the one definition of each (name, default, validation,
#: docstring); :func:`solver_options` reads their defaults from it.
SOLVER_OPTIONS = ('tolerance', 'maxIter', 'checkEvery', 'relaxation', 'momentum', 'schedule', 'slabs', 'slabsAcross',
                  'slabsOwnBodies', 'sphereFastPath',
                  'alertRatio', 'alertSpeedFactor', 'positionTolerance', 'maxProjectionIter', 'correctionMomentum',
                  'parallelMinContacts', 'warnUnconverged', 'recordResidual')


def solver_options():
    """``{name: default}`` of the engine's :data:`SOLVER_OPTIONS`, read from a fresh
    :class:`ContactDynamicsIntegrator` (what each does: its docstring, ``help(ContactDynamicsIntegrator)``)."""
    from yade.wrapper import ContactDynamicsIntegrator
    fresh = ContactDynamicsIntegrator()
    return {name: getattr(fresh, name) for name in SOLVER_OPTIONS}


def engines(gravity=(0, 0, -9.81), en=0.0, et=0.0, extra=(), **integrator_options):
    """The canonical engine list of a Contact Dynamics scene, in YADE's usual order::

        ForceResetter
        InsertionSortCollider([Bo1_Sphere_CDAabb, Bo1_Wall_Aabb, Bo1_Facet_Aabb, Bo1_Box_Aabb])   (defaults)
        InteractionLoop([Ig2_Sphere_Sphere_CDScGeom, Ig2_Wall_Sphere_CDScGeom, Ig2_Facet_Sphere_CDScGeom,
                         Ig2_Box_Sphere_CDScGeom],
                        [Ip2_FrictMat_FrictMat_CDPhys(en, et)], [Law2_ScGeom_CDPhys_Coulomb])
        *extra                      (e.g. PyRunner engines)
        ContactDynamicsIntegrator(gravity, **integrator_options)

    Shape pairs: sphere–sphere, and a sphere against a wall, a facet or a box (``utils.box``, in
    any orientation). Walls, facets and boxes are obstacles: fixed, or moved kinematically by
    setting their ``state.vel``. Each ``Ig2_*_CDScGeom`` functor creates a contact once the gap
    is below the alert distance (:yref:`ContactDynamicsIntegrator.alertRatio`).

    :param gravity: gravitational acceleration [m/s²].
    :param en, et: normal and tangential restitution coefficients given to new contacts.
    :param extra: engines inserted just before the integrator.
    :param integrator_options: attributes of :yref:`ContactDynamicsIntegrator` (``tolerance``,
        ``maxIter``, ``alertRatio``...).
    """
    from yade.wrapper import (ForceResetter, InsertionSortCollider, InteractionLoop, Bo1_Wall_Aabb,
                              Bo1_Facet_Aabb, Bo1_Box_Aabb, Bo1_Sphere_CDAabb, Ig2_Sphere_Sphere_CDScGeom,
                              Ig2_Wall_Sphere_CDScGeom, Ig2_Facet_Sphere_CDScGeom, Ig2_Box_Sphere_CDScGeom,
                              Ip2_FrictMat_FrictMat_CDPhys, Law2_ScGeom_CDPhys_Coulomb,
                              ContactDynamicsIntegrator)
    return [
        ForceResetter(),
        InsertionSortCollider([Bo1_Sphere_CDAabb(), Bo1_Wall_Aabb(), Bo1_Facet_Aabb(), Bo1_Box_Aabb()]),
        InteractionLoop(
            [Ig2_Sphere_Sphere_CDScGeom(), Ig2_Wall_Sphere_CDScGeom(), Ig2_Facet_Sphere_CDScGeom(),
             Ig2_Box_Sphere_CDScGeom()],
            [Ip2_FrictMat_FrictMat_CDPhys(en=en, et=et)],
            [Law2_ScGeom_CDPhys_Coulomb()]),
        *extra,
        ContactDynamicsIntegrator(gravity=gravity, **integrator_options),
    ]


def integrator():
    """The scene's :yref:`ContactDynamicsIntegrator` (raises LookupError when there is none)."""
    from yade import O
    from yade.wrapper import ContactDynamicsIntegrator
    for e in O.engines:
        if isinstance(e, ContactDynamicsIntegrator):
            return e
    raise LookupError('O.engines holds no ContactDynamicsIntegrator: build the list with yadecd.engines()')

"""YADE's own soft-contact (MD) engines on a scene built for Contact Dynamics: the comparison's
other method. A scene builder of :mod:`yadecd.scenes` creates the bodies and the CD engines;
:func:`to_md` swaps in YADE's MD engines on the same bodies."""
from yade import O, utils
from yade import Vector3
from yade.wrapper import (ForceResetter, InsertionSortCollider, InteractionLoop, Bo1_Sphere_Aabb,
                          Bo1_Wall_Aabb, Bo1_Facet_Aabb, Ig2_Sphere_Sphere_ScGeom,
                          Ig2_Wall_Sphere_ScGeom, Ig2_Facet_Sphere_ScGeom,
                          Ip2_FrictMat_FrictMat_FrictPhys, Law2_ScGeom_FrictPhys_CundallStrack,
                          NewtonIntegrator)

from .. import integrator

try:  # Hertz–Mindlin with a restitution-based viscous damping (YADE's Mindlin law)
    from yade.wrapper import (Ip2_FrictMat_FrictMat_MindlinPhys, Law2_ScGeom_MindlinPhys_Mindlin,
                              MatchMaker)
    HAVE_HERTZ = True
except ImportError:  # pragma: no cover - depends on the YADE build
    HAVE_HERTZ = False

__all__ = ['md_engines', 'to_md', 'HAVE_HERTZ']

G = 9.81


def md_engines(gravity=(0, 0, -G), law='linear', damping=0.0, en=1.0, es=None):
    """YADE's soft-contact engine list. ``law='linear'``: linear spring + Coulomb slider
    (``Ip2_FrictMat_FrictMat_FrictPhys``, ``Law2_ScGeom_FrictPhys_CundallStrack``: kn from
    Young's modulus and radii, ks = poisson·kn, no contact damping, restitution ≈ 1).
    ``law='hertz'``: Hertz–Mindlin (``Ip2_FrictMat_FrictMat_MindlinPhys`` with restitution
    ``en``/``es`` through its viscous damping, ``Law2_ScGeom_MindlinPhys_Mindlin``).
    ``damping``: NewtonIntegrator's (Cundall's non-viscous) global damping."""
    if law == 'linear':
        ip, lw = Ip2_FrictMat_FrictMat_FrictPhys(), Law2_ScGeom_FrictPhys_CundallStrack()
    elif law == 'hertz':
        if not HAVE_HERTZ:
            raise RuntimeError('this YADE build has no Hertz-Mindlin law')
        es = en if es is None else es
        ip = Ip2_FrictMat_FrictMat_MindlinPhys(en=MatchMaker(algo='val', val=en), es=MatchMaker(algo='val', val=es))
        lw = Law2_ScGeom_MindlinPhys_Mindlin()
    else:
        raise ValueError('law must be linear or hertz, not %r' % (law,))
    return [
        ForceResetter(),
        InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Wall_Aabb(), Bo1_Facet_Aabb()]),
        InteractionLoop([Ig2_Sphere_Sphere_ScGeom(), Ig2_Wall_Sphere_ScGeom(), Ig2_Facet_Sphere_ScGeom()], [ip], [lw]),
        NewtonIntegrator(gravity=gravity, damping=damping),
    ]


def to_md(young=1e7, safety=0.5, damping=0.0, law='linear', poisson=0.25, en=1.0, es=None):
    """Turn the scene just built by a :mod:`yadecd.scenes` builder (CD engines, no step taken)
    into an MD scene on the same bodies: every material gets ``young`` and ``poisson`` (for the
    linear law poisson is ks/kn), the engines become :func:`md_engines` with the CD integrator's
    gravity, and ``O.dt = safety · PWaveTimeStep()``. Returns ``O.dt``."""
    if O.iter != 0 or len([i for i in O.interactions if i.isReal]):
        raise RuntimeError('to_md must be called on a freshly built scene (before any step)')
    gravity = Vector3(integrator().gravity)
    for m in O.materials:
        m.young = young
        m.poisson = poisson
    O.engines = md_engines(gravity, law=law, damping=damping, en=en, es=es)
    O.dt = safety * utils.PWaveTimeStep()
    return O.dt

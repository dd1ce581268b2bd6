"""Measurements taken the same way for CD and MD runs of a comparison: gaps and overlaps from
positions, the floor force, the mechanical energy (kinetic + gravity + elastic energy of MD
springs)."""
import math

from yade import O
from yade import Vector3
from yade.wrapper import Sphere, Wall

__all__ = ['spheres', 'gap', 'overlaps', 'floor_force', 'mechanical_energy', 'all_finite']


def spheres():
    """Every body of the scene whose shape is a sphere."""
    return [b for b in O.bodies if isinstance(b.shape, Sphere)]


def gap(b1, b2):
    """Gap between a sphere and a sphere or wall from the current positions [m] (negative:
    overlap), or None for other shapes. Computed from positions, not from the contact geometry:
    YADE's MD geometry is that of the step start and CD's that of the mid-step."""
    if not isinstance(b2.shape, Sphere):
        b1, b2 = b2, b1
    if not isinstance(b2.shape, Sphere):
        return None
    r2 = b2.shape.radius
    if isinstance(b1.shape, Sphere):
        return (b2.state.pos - b1.state.pos).norm() - b1.shape.radius - r2
    if isinstance(b1.shape, Wall):
        ax, sense = b1.shape.axis, b1.shape.sense
        dz = b2.state.pos[ax] - b1.state.pos[ax]
        return (abs(dz) if sense == 0 else sense * dz) - r2
    return None


def overlaps():
    """Interpenetration of every real contact [m] (0 when open), with the smaller diameter of
    the pair: list of (overlap, diameter). Facet contacts use the contact geometry."""
    out = []
    for i in O.interactions:
        if not i.isReal:
            continue
        b1, b2 = O.bodies[i.id1], O.bodies[i.id2]
        d = min(2 * b.shape.radius for b in (b1, b2) if isinstance(b.shape, Sphere))
        g = gap(b1, b2)
        if g is None:
            g = -i.geom.penetrationDepth
        out.append((max(0.0, -g), d))
    return out


def floor_force(floor=0):
    """Total normal force of the contacts on body ``floor`` [N] (CD: impulse/h)."""
    f = 0.0
    for i in O.interactions.withBody(floor):
        if i.isReal:
            f += i.phys.normalForce.norm()
    return f


def _elastic_energy(i):
    p = i.phys
    kn = getattr(p, 'kn', 0.0)
    if kn <= 0 or p.__class__.__name__ == 'CDPhys':
        return 0.0
    fn = p.normalForce.norm()
    fs = p.shearForce.norm()
    ks = getattr(p, 'ks', 0.0)
    es = 0.5 * fs * fs / ks if ks > 0 else 0.0
    if hasattr(p, 'kno'):  # Hertz: F = kno δ^1.5, energy = 2/5 kno δ^2.5 = 2/5 F^(5/3) kno^(-2/3)
        return 0.4 * fn ** (5 / 3) * p.kno ** (-2 / 3) + es
    return 0.5 * fn * fn / kn + es


def mechanical_energy(gravity):
    """Kinetic + gravitational potential (−m g·x) + elastic energy stored in MD contacts [J]."""
    e = 0.0
    g = Vector3(gravity)
    for b in spheres():
        if not b.dynamic:
            continue
        s = b.state
        e += 0.5 * s.mass * s.vel.squaredNorm() + 0.5 * s.inertia[0] * s.angVel.squaredNorm() - s.mass * g.dot(s.pos)
    for i in O.interactions:
        if i.isReal:
            e += _elastic_energy(i)
    return e


def all_finite():
    """Whether every sphere's position and velocities are finite."""
    for b in spheres():
        s = b.state
        for v in (s.pos, s.vel, s.angVel):
            if not all(math.isfinite(x) for x in v):
                return False
    return True

"""Pile snapshots from a YADE scene (:func:`snapshot`, the data every analysis reads) and a scene
rebuilt from one (:func:`scene_from_snapshot`).
"""

import os
import numpy as np
from yade import O
from yade.wrapper import Sphere


def snapshot(path, births, p, t=None):
    """Save what the analyses need at the current time ``t`` (default O.time; SI): grains (pos,
    radius, vel, fixed, birth time, ids) and contacts (ids, point, normal, force on body 2 [N]).

    A grain is a rigid body: a sphere, or a clump (its centre of mass, velocity and id, and the
    radius of the sphere of its mass at density ``p['rho']``: its volume-equivalent radius, so
    that the analyses' masses and volumes are the clump's). A contact of a clump member is the
    clump's (``c_id1``/``c_id2`` hold clump ids). Clump members are also saved as ``m_pos``,
    ``m_radius`` and ``m_grain`` (the id of their clump), for figures. Written under a temporary
    name and renamed: a kill never leaves half a snapshot."""
    ids, pos, rad, vel, fixed, birth = [], [], [], [], [], []
    m_pos, m_rad, m_grain = [], [], []
    owner = {}
    for b in O.bodies:
        if b.isClumpMember:
            owner[b.id] = b.clumpId
            m_pos.append(tuple(b.state.pos))
            m_rad.append(b.shape.radius)
            m_grain.append(b.clumpId)
            continue
        if b.isClump:
            radius = (3 * b.state.mass / (4 * np.pi * p['rho'])) ** (1 / 3)
        elif isinstance(b.shape, Sphere):
            radius = b.shape.radius
        else:
            continue
        ids.append(b.id)
        pos.append(tuple(b.state.pos))
        rad.append(radius)
        vel.append(tuple(b.state.vel))
        fixed.append(not b.dynamic)
        birth.append(births.get(b.id, -1.0))
    c1, c2, cp, cn, cf = [], [], [], [], []
    for i in O.interactions:
        if not i.isReal:
            continue
        f = i.phys.normalForce + i.phys.shearForce
        c1.append(owner.get(i.id1, i.id1))
        c2.append(owner.get(i.id2, i.id2))
        cp.append(tuple(i.geom.contactPoint))
        cn.append(tuple(i.geom.normal))
        cf.append(tuple(f))
    extra = {}
    if m_grain:
        extra = dict(m_pos=np.array(m_pos), m_radius=np.array(m_rad), m_grain=np.array(m_grain, dtype=int))
    tmp = path + '.tmp'
    with open(tmp, 'wb') as f:
        np.savez_compressed(f, time=O.time if t is None else t, g=p['g'], rho=p['rho'], ids=np.array(ids), pos=np.array(pos),
                            radius=np.array(rad), vel=np.array(vel), fixed=np.array(fixed), birth=np.array(birth),
                            c_id1=np.array(c1, dtype=int), c_id2=np.array(c2, dtype=int), c_point=np.array(cp).reshape(-1, 3),
                            c_normal=np.array(cn).reshape(-1, 3), c_force=np.array(cf).reshape(-1, 3), **extra)
    os.replace(tmp, path)

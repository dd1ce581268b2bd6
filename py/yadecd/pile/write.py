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
    Written under a temporary name and renamed: a kill never leaves half a snapshot."""
    ids, pos, rad, vel, fixed, birth = [], [], [], [], [], []
    for b in O.bodies:
        if not isinstance(b.shape, Sphere):
            continue
        ids.append(b.id)
        pos.append(tuple(b.state.pos))
        rad.append(b.shape.radius)
        vel.append(tuple(b.state.vel))
        fixed.append(not b.dynamic)
        birth.append(births.get(b.id, -1.0))
    c1, c2, cp, cn, cf = [], [], [], [], []
    for i in O.interactions:
        if not i.isReal:
            continue
        f = i.phys.normalForce + i.phys.shearForce
        c1.append(i.id1)
        c2.append(i.id2)
        cp.append(tuple(i.geom.contactPoint))
        cn.append(tuple(i.geom.normal))
        cf.append(tuple(f))
    tmp = path + '.tmp'
    with open(tmp, 'wb') as f:
        np.savez_compressed(f, time=O.time if t is None else t, g=p['g'], rho=p['rho'], ids=np.array(ids), pos=np.array(pos),
                            radius=np.array(rad), vel=np.array(vel), fixed=np.array(fixed), birth=np.array(birth),
                            c_id1=np.array(c1, dtype=int), c_id2=np.array(c2, dtype=int), c_point=np.array(cp).reshape(-1, 3),
                            c_normal=np.array(cn).reshape(-1, 3), c_force=np.array(cf).reshape(-1, 3))
    os.replace(tmp, path)

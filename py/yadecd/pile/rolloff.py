"""At what tilt does a single grain leave the pile's floor? (Run inside YADE.)

The pile rests on a random paving of fixed grains (:func:`yadecd.pile.paving`). A foot of single
grains can only hold where the paving holds a lone grain; a floor that lets grains roll away at
a low tilt lowers the pile. This measures, for grains of given diameters, the tilt of the floor
at which a grain resting in a pocket of the paving starts to roll out.

Method: grains of each diameter are set down at random places of the paving, far apart (they
never meet), and settled under vertical gravity. Gravity is then turned slowly towards +x
(``rate`` degrees per second of simulated time, quasi-static: a grain leaves a pocket long before
the tilt moves by a degree). A grain's release tilt is the tilt at which it has moved half a
diameter from its settled place; it is then removed. Everything is the pile protocol's: the same
paving rule, friction 0.4, density, time step, CD engine.
"""
import math
import time

import numpy as np

from yade import O, utils, Vector3

from .. import engines
from .build import paving
from ..scenes import material


def release_angles(diameters, per_size=20, spacing=0.03, d_min=0.0025, d_max=0.005, mu=0.4, rho=1000.0,
                   dt=2e-4, rate=10.0, max_tilt=70.0, settle=0.3, seed=1, log=print):
    """Release tilts [deg] of ``per_size`` grains of each diameter of ``diameters`` [m].

    :returns: dict diameter -> array of release tilts [deg] (nan: still held at ``max_tilt``).
    """
    if not diameters or min(diameters) <= 0 or per_size < 1 or rate <= 0 or not (0 < max_tilt < 90):
        raise ValueError('release_angles needs positive diameters, per_size >= 1, rate > 0 and 0 < max_tilt < 90')
    rng = np.random.default_rng(seed)
    n = len(diameters) * per_size
    side = int(math.ceil(math.sqrt(n)))
    half = 0.5 * side * spacing + 2 * d_max
    O.reset()
    mat = material(mu, rho)
    O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
    for x, y, r in paving(np.random.default_rng(seed + 1_000_003), half * math.sqrt(2), d_min, d_max):
        if abs(x) < half and abs(y) < half:
            O.bodies.append(utils.sphere((x, y, r), r, fixed=True, material=mat))
    grains = {}
    order = rng.permutation(n)
    for k in range(n):
        slot = order[k]
        cx = (slot % side - 0.5 * (side - 1)) * spacing + rng.uniform(-0.3, 0.3) * spacing
        cy = (slot // side - 0.5 * (side - 1)) * spacing + rng.uniform(-0.3, 0.3) * spacing
        dia = diameters[k // per_size]
        bid = O.bodies.append(utils.sphere((cx, cy, d_max + 0.5 * dia + 1e-4), 0.5 * dia, material=mat))
        grains[bid] = dia
    O.engines = engines(gravity=(0, 0, -9.81), tolerance=1e-6, maxIter=20000)
    O.dt = dt
    O.run(int(round(settle / dt)), True)
    rest = {b: Vector3(O.bodies[b].state.pos) for b in grains}
    released = {}
    t0, tilt = time.time(), 0.0
    step_deg = rate * dt * 50
    while grains and tilt < max_tilt:
        tilt += step_deg
        th = math.radians(tilt)
        O.engines[-1].gravity = Vector3(9.81 * math.sin(th), 0, -9.81 * math.cos(th))
        O.run(50, True)
        for b in list(grains):
            if (O.bodies[b].state.pos - rest[b]).norm() > 0.5 * grains[b]:
                released[b] = (grains.pop(b), tilt)
                O.bodies.erase(b)
        if log and int(tilt / 5) != int((tilt - step_deg) / 5):
            log('rolloff: tilt %4.1f deg, %d of %d grains released (%.0f s)' % (tilt, len(released), n, time.time() - t0))
    out = {d: [] for d in diameters}
    for dia, angle in released.values():
        out[dia].append(angle)
    for dia in grains.values():
        out[dia].append(float('nan'))
    return {d: np.array(v) for d, v in out.items()}

# Contact Dynamics plugin: a fast check run by `yade --check` (installed into YADE's checks).
# A sphere on a plane inclined at 30° with μ = 0.5 ≥ (2/7)·tan 30° rolls without slipping:
# v = (5/7)·g·sin θ·t exactly (the midpoint scheme integrates constant accelerations exactly).
import math
from yade import O
from yadecd import scenes

if 'YadeCheckError' not in globals():
    class YadeCheckError(Exception):
        pass

theta = math.radians(30)
sc = scenes.sphere_on_plane(theta, 0.5)
O.run(100, True)
s = O.bodies[sc['sphere']].state
expected = 5 / 7 * sc['g'] * math.sin(theta) * O.time
if abs(s.vel[0] / expected - 1) > 1e-12:
    raise YadeCheckError('CD rolling sphere: v=%r, expected %r' % (s.vel[0], expected))
if abs(s.angVel[1] * sc['r'] / s.vel[0] - 1) > 1e-12:
    raise YadeCheckError('CD rolling sphere slips: omega*r=%r, v=%r' % (s.angVel[1] * sc['r'], s.vel[0]))
O.reset()

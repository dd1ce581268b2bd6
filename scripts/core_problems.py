"""Write the core tier's saved steps (tests/data/core/*.cdp): one step of each scene, as the solver
core's input (ContactDynamicsIntegrator.problemFile), followed by the engine's own results of that
step (impulses, velocities, sweeps, bit for bit) and, where one is known, the exact answer.

    scripts/yade -j1 -n -x scripts/core_problems.py [--out tests/data/core] [--pile-snapshot RUN/snap_0001.500.npz]
                  [--clump-run RUN]

Cases (see yadecd.scenes): a sphere rolling without slipping and one sliding on an incline (exact
impulses), a column of 10 and one of 5 with rotations blocked (general kernel; the weight above
each contact, exact), a 1:100 mass-ratio stack (exact), a hyperstatic FCC block at rest in a box of walls (floor
and walls together carry its weight, exact), a binary collision with restitution, a fed 300-grain pile step
(when a snapshot is given), a sheared periodic cell (contacts through periodic images) and a step of a pile of clumps (when a clump pile run is given: its newest checkpoint,
loaded as ``PileRun.load`` does, the run itself untouched).
"""
import argparse
import math
import os
import sys

from yade import O
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

import yadecd
from yadecd import scenes  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(sys.argv[0])))
ap = argparse.ArgumentParser(prog='core_problems.py', description=__doc__.split('\n')[0])
ap.add_argument('--out', default=os.path.join(REPO, 'tests', 'data', 'core'))
ap.add_argument('--pile-snapshot', default=None, help='a pile snapshot (.npz with run.json beside it) for the fed pile step')
ap.add_argument('--clump-run', default=None, help='a pile run of clump grains (pile.py --grain-shape) for the clump pile step')
args = ap.parse_args(sys.argv[1:])
os.makedirs(args.out, exist_ok=True)
G = 9.81


def fmt(x):
    """A number written exactly (repr of a double)."""
    return repr(float(x))


def vec(v):
    """A vector as exact numbers separated by spaces."""
    return ' '.join(fmt(x) for x in v)


def save(name, description, expect=(), warmup=0):
    """Run ``warmup`` steps, then one step writing its problem; append the engine's results and
    the exact answers ``expect`` (lines)."""
    cd = yadecd.integrator()
    cd.warnUnconverged = False
    if warmup:
        O.run(warmup, True)
    path = os.path.join(args.out, name + '.cdp')
    cd.problemFile = path
    O.step()
    if cd.problemFile:
        raise RuntimeError('%s: the step did not write its problem' % name)
    lines = ['describe ' + description, 'engine_sweeps %d' % cd.iterations]
    mover = lambda i: O.bodies[i].clumpId if O.bodies[i].isClumpMember else i  # noqa: E731  (what the solve moves)
    for i in O.interactions:   # in the container's order, the engine's contact order
        if i.isReal and hasattr(i.phys, 'impulse'):
            lines.append('engine_impulse %d %d %s' % (mover(i.id1), mover(i.id2), vec(i.phys.impulse)))
    for b in O.bodies:
        if b.dynamic and not b.isClumpMember:
            lines.append('engine_velocity %d %s %s' % (b.id, vec(b.state.vel), vec(b.state.angVel)))
    lines += list(expect)
    with open(path, 'a') as f:
        f.write('\n'.join(lines) + '\n')
    print('%-22s %6d bodies %6d contacts %4d sweeps  %s' % (name, len(O.bodies), cd.nContacts, cd.iterations, description))


def column_expectations(ids, m, h):
    """Contact k (body below, body k) carries the weight of the spheres from k up."""
    n, out, below = len(ids), [], 0
    for k, b in enumerate(ids):
        P = (n - k) * m * G * h
        out.append('expect_impulse %d %d 0 0 %s %s' % (below, b, fmt(P), fmt(1e-8 * n * m * G * h)))
        below = b
    return out


# a sphere on an incline: rolling without slipping (friction (2/7) m g sinθ) and sliding (μ N)
for name, theta, mu in (('incline_roll', 0.3, 0.5), ('incline_slide', 0.6, 0.1)):
    s = scenes.sphere_on_plane(theta, mu)
    m, h = O.bodies[s['sphere']].state.mass, O.dt
    N = m * G * math.cos(theta) * h
    T = (2 / 7) * m * G * math.sin(theta) * h if name == 'incline_roll' else mu * N
    assert name != 'incline_roll' or (2 / 7) * math.tan(theta) < mu
    save(name, 'sphere on an incline of %g rad, mu %g: %s' % (theta, mu, 'rolls without slipping' if name == 'incline_roll' else 'slides'),
         ['expect_impulse %d %d %s %s' % (s['floor'], s['sphere'], vec((-T, 0, N)), fmt(1e-10 * N))])

c = scenes.column(10)
save('column10', 'a column of 10 spheres at rest on the floor, its first step', column_expectations(c['ids'], c['m'], O.dt))

c = scenes.column(5)
for b in c['ids']:
    O.bodies[b].state.blockedDOFs = 'XYZ'  # rotations blocked: the general kernel
save('column5_blocked', 'a column of 5 spheres, rotations blocked (general kernel), its first step', column_expectations(c['ids'], c['m'], O.dt))

st = scenes.mass_ratio_stack(100.0)
ml, mh = O.bodies[st['light']].state.mass, O.bodies[st['heavy']].state.mass
save('mass_ratio100', 'a light sphere under one 100 times heavier, the first step', [
    'expect_impulse 0 %d 0 0 %s %s' % (st['light'], fmt((ml + mh) * G * O.dt), fmt(1e-8 * (ml + mh) * G * O.dt)),
    'expect_impulse %d %d 0 0 %s %s' % (st['light'], st['heavy'], fmt(mh * G * O.dt), fmt(1e-8 * mh * G * O.dt))])

blk = scenes.fcc_block(108, boxed=True)
M = sum(O.bodies[b].state.mass for b in blk['ids'])
walls = ','.join(str(b.id) for b in O.bodies if not b.dynamic)  # the floor and the four walls (friction: they share the weight)
save('fcc108_boxed', 'a hyperstatic FCC block of 108 spheres in a box of 4 walls, at rest: its first step',
     ['expect_load %s 0 0 %s %s' % (walls, fmt(-M * G * O.dt), fmt(1e-7 * M * G * O.dt))])

scenes.binary_collision((1.0, 0.2, 0), (-0.5, 0, 0.1), en=0.6, et=0.2, gap=1e-4, offset=0.004)
for _ in range(1000):  # step to the landing: the open contact's first impulse, with its landing velocity kept
    O.step()
    landed = [i for i in O.interactions if i.isReal and i.phys.impulse.norm() > 0]
    if landed:
        break
assert landed and landed[0].phys.approachVelocity.norm() > 0, 'the binary collision did not land within a step'
save('binary_restitution', 'two spheres colliding obliquely, en 0.6, et 0.2: the step after the landing (restitution on the landing velocity)')

# a periodic cell compressed and sheared by its velGrad: contacts through the images, whose shift
# velocity (Cell.intrShiftVel) is part of their relative velocity
from yade import pack, Matrix3  # noqa: E402
O.reset()
cloud = pack.SpherePack()
cloud.makeCloud((0, 0, 0), (0.04, 0.04, 0.04), rMean=0.004, rRelFuzz=0.2, num=100, periodic=True, seed=3)  # places 66
cloud.toSimulation(material=scenes.material(0.4))
O.engines = yadecd.engines(gravity=(0, 0, 0), tolerance=1e-12, maxIter=100000)
O.dt = 1e-4
O.cell.velGrad = Matrix3(-5, 2, 0, 0, -5, 0, 0, 0, -5)
through = lambda: sum(1 for i in O.interactions if i.isReal and i.geom.penetrationDepth > 0 and tuple(i.cellDist) != (0, 0, 0))  # noqa: E731
while through() < 10 and O.iter < 2000:       # compressed until ten contacts touch through an image
    O.run(10, True)
save('periodic_shear', 'a periodic cell of %d spheres compressed and sheared by velGrad, %d contacts touching through an image'
     % (len(O.bodies), through()))

if args.pile_snapshot:
    from yadecd import pile
    pile.scene_from_snapshot(args.pile_snapshot)
    # plain Gauss–Seidel stalls near a relative residual of 1e-8 on this step (friction): the
    # option grid solves it to 1e-7, 10⁴ times tighter than piles are run
    save('pile300_fed', 'a 300-grain pile at the end of its feed (%s)' % os.path.basename(args.pile_snapshot),
         ['grid_tolerance 1e-7'], warmup=30)
if args.clump_run:
    from yadecd import pile
    run = pile.PileRun.load(args.clump_run, log=lambda s: None)
    shape = run.p['grain_shape']
    # plain Gauss–Seidel on clump contacts stalls near 1e-7 (their coupled blocks): the grid's 1e-6
    # is still 1000 times tighter than piles are run
    save('%s_pile' % shape, 'a pile of %d %s clumps being fed (%s at t = %.3f s)' % (run.feeder.count, shape, os.path.basename(
        os.path.abspath(args.clump_run)), run.clock.time()), ['grid_tolerance 1e-6'])
print('wrote', args.out)

"""The local Signorini–Coulomb solver and the Gauss–Seidel solve, against closed forms and
against Siconos' NSGS solver (Debian's python3-siconos, an independent implementation)."""
from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
import math
import os
import random
import unittest

import numpy as np

from yade import O, Vector3, Matrix3, utils
from yade.wrapper import ContactDynamicsIntegrator as CDI

import yadecd
from yadecd import scenes
from yadecd.export import fclib

try:
    import siconos.numerics as sn
except ImportError:  # the set-up installs python3-siconos; a missing one must not pass silently
    sn = None


def require_siconos(test):
    """Fail (not skip: a skip passes) when Siconos is missing; scripts/setup.sh installs it."""
    if sn is None:
        test.fail('python3-siconos is missing: run scripts/setup.sh, which installs it')


def siconos_solve(W, q, mu, tol=1e-14):
    """Siconos NSGS on the problem u = W r + q, û = u + μ|u_T| e_N ∈ C*, r ∈ C, û ⊥ r."""
    s = fclib.solve_siconos(W, q, mu, tol=tol)
    return s['info'], s['r'], s['u']


def random_local_problems(seed, count, coupling):
    """``count`` local problems (W, b, μ) with W = A Aᵀ SPD, A = diag(1..2) + coupling·noise,
    each returned with the engine's solution r."""
    rnd = np.random.default_rng(seed)
    for _ in range(count):
        A = rnd.normal(size=(3, 3)) * coupling + np.diag(rnd.uniform(1, 2, 3))
        W = A @ A.T
        b, mu = rnd.uniform(-1, 1, 3), rnd.uniform(0, 0.8)
        r, _ = CDI.solveLocal(Matrix3(*W.flatten()), Vector3(*b), mu)
        yield W, b, mu, np.array(r)


def cone_law_error(r, U, mu):
    """Max violation of the Signorini–Coulomb law by (r, U), in natural-map form (ρ = 1)."""
    return CDI.naturalMapResidual(Vector3(*r), Vector3(*U), mu).norm()


class TestLocalSolver(unittest.TestCase):
    """One contact, U = W r + b, solved exactly."""

    def test_closed_form_diagonal(self):
        """W = diag(a, c, c): open if b_N ≥ 0; stick r = −W⁻¹b if |b_T|/c ≤ μ(−b_N/a);
        else slide: r_N = −b_N/a, r_T = −μ r_N b_T/|b_T|."""
        rnd = random.Random(3)
        counts = [0, 0, 0]
        for _ in range(300):
            a, c, mu = rnd.uniform(0.5, 3), rnd.uniform(0.5, 5), rnd.uniform(0, 1)
            b = Vector3(rnd.uniform(-1, 1), rnd.uniform(-1, 1), rnd.uniform(-1, 1))
            r, st = CDI.solveLocal(Matrix3(a, 0, 0, 0, c, 0, 0, 0, c), b, mu)
            bt = math.hypot(b[1], b[2])
            if b[0] >= 0:
                expected, est = Vector3(0, 0, 0), 0
            elif bt / c <= mu * (-b[0] / a):
                expected, est = Vector3(-b[0] / a, -b[1] / c, -b[2] / c), 1
            else:
                rn = -b[0] / a
                expected, est = Vector3(rn, -mu * rn * b[1] / bt, -mu * rn * b[2] / bt), 2
            counts[est] += 1
            self.assertEqual(st, est)
            self.assertLess((r - expected).norm(), 1e-14 * (1 + expected.norm()))
        self.assertTrue(all(k > 20 for k in counts), 'all three branches exercised: %s' % counts)

    def test_residual_zero_on_solutions(self):
        """The natural-map residual vanishes on each branch of the law, frictionless (μ = 0)
        included: open (r = 0, U_N > 0), sticking (U = 0, r inside), sliding (r on the cone,
        U_T opposite r_T)."""
        for mu in (0.0, 0.4):
            cases = [((0, 0, 0), (1.0, 0.2, -0.1)), ((1.0, 0.1 * mu, 0), (0, 0, 0)),
                     ((1.0, -mu, 0), (0, 0.5, 0))]
            for r, U in cases:
                self.assertLess(cone_law_error(r, U, mu), 1e-15, 'mu=%g r=%s U=%s' % (mu, r, U))
        # and is large off the law: an open contact carrying an impulse
        self.assertGreater(cone_law_error((1.0, 0, 0), (1.0, 0, 0), 0.0), 0.5)

    def test_coupled_blocks_satisfy_the_law(self):
        """A full SPD W (coupled normal and tangential parts): the result satisfies the law."""
        for W, b, mu, r in random_local_problems(5, 200, 0.3):
            U = W @ r + b
            self.assertLess(cone_law_error(r, U, mu), 1e-12, 'W=%s b=%s mu=%g' % (W.tolist(), b.tolist(), mu))

    def test_against_siconos_local(self):
        """Same local problems solved by Siconos NSGS: reactions agree to 1e-8."""
        require_siconos(self)
        for W, b, mu, r in random_local_problems(7, 100, 0.2):
            info, rs, _ = siconos_solve(W, b, [mu])
            self.assertEqual(info, 0)
            self.assertLess(np.abs(r - rs).max(), 1e-8)


class TestSphereFastPath(unittest.TestCase):
    """The compact sphere-contact sweep (sphereFastPath) and the general 3×3 path are the same
    Gauss–Seidel: from the same state, one step gives the same impulses and velocities."""

    def one_step(self, fast):
        O.loadTmp('fastpath')
        cd = yadecd.integrator()
        cd.sphereFastPath = fast
        O.step()
        return (np.array([list(i.phys.impulse) for i in O.interactions]),
                np.array([list(b.state.vel) + list(b.state.angVel) for b in O.bodies]), cd.iterations)

    def test_same_step_both_paths(self):
        scenes.random_loose_packing(n=20, tolerance=1e-12, maxIter=100000)
        O.run(250, True)  # landing and rolling: sticking, sliding and open contacts
        O.saveTmp('fastpath')
        r_fast, v_fast, it_fast = self.one_step(True)
        r_gen, v_gen, it_gen = self.one_step(False)
        self.assertGreater(len(r_fast), 10)
        self.assertLess(np.abs(r_fast - r_gen).max(), 1e-9 * np.abs(r_gen).max())
        self.assertLess(np.abs(v_fast - v_gen).max(), 1e-9 * max(np.abs(v_gen).max(), 1e-3))
        self.assertLess(abs(it_fast - it_gen), 0.05 * it_gen + 2)

    def test_blocked_dofs_take_the_general_path(self):
        """A sphere with blocked rotations is not isotropic: the general path must give the
        exact sliding result (no rolling) of a block on a plane."""
        sc = scenes.sphere_on_plane(math.radians(30), 0.2)
        O.bodies[sc['sphere']].state.blockedDOFs = 'XYZ'
        O.run(100, True)
        g, th = 9.81, math.radians(30)
        expected = g * (math.sin(th) - 0.2 * math.cos(th)) * O.time  # sliding block
        self.assertAlmostEqual(O.bodies[sc['sphere']].state.vel[0] / expected, 1.0, delta=1e-10)


class TestMomentum(unittest.TestCase):
    """Nesterov momentum with adaptive restart over whole sweeps (momentum, the default)."""

    def test_single_contact_exact_in_one_sweep(self):
        """The first sweep of a step is plain Gauss–Seidel: a sphere resting on a wall is solved
        exactly in one sweep, momentum or not."""
        sc = scenes.column(1, tolerance=1e-12, maxIter=1)
        cd = yadecd.integrator()
        self.assertTrue(cd.momentum)
        for _ in range(3):
            O.step()
            self.assertTrue(cd.converged)
        f = O.interactions[0, sc['ids'][0]].phys.normalForce[2]
        self.assertAlmostEqual(f / (sc['m'] * 9.81), 1.0, delta=1e-12)

    def test_same_step_as_plain_gauss_seidel(self):
        """From the same state of a loose packing (sticking, sliding and open contacts), one step
        solved tightly with and without momentum gives the same velocities."""
        scenes.random_loose_packing(n=20, tolerance=1e-12, maxIter=100000)
        O.run(250, True)
        O.saveTmp('momentum')
        out = {}
        for mom in (False, True):
            O.loadTmp('momentum')
            cd = yadecd.integrator()
            cd.momentum = mom
            O.step()
            self.assertTrue(cd.converged)
            out[mom] = np.array([list(b.state.vel) + list(b.state.angVel) for b in O.bodies])
        self.assertLess(np.abs(out[True] - out[False]).max(), 1e-9 * max(np.abs(out[False]).max(), 1e-3))

    def test_tall_column_target(self):
        """Issue target: a cold-started column of 160 spheres gets its floor force within 1e-3 of
        the weight in at most a tenth of the sweeps plain Gauss–Seidel needs for that (both at
        tolerance 1e-4; at 1e-3 plain Gauss–Seidel is still 3.6e-3 off). Measured: 823 against
        79 979 sweeps."""
        sweeps = {}
        for mom in (False, True):
            sc = scenes.column(160, tolerance=1e-4, maxIter=200000, momentum=mom, warnUnconverged=False)
            cd = yadecd.integrator()
            O.step()
            self.assertTrue(cd.converged)
            sweeps[mom] = cd.iterations
            f = O.interactions[0, sc['ids'][0]].phys.normalForce[2]
            self.assertLess(abs(f / (160 * sc['m'] * 9.81) - 1), 1e-3)
        self.assertLessEqual(10 * sweeps[True], sweeps[False])


PARALLEL_RUN = """
import hashlib, sys, numpy as np
sys.path.insert(0, %r)
from yade import O
from yadecd import scenes
import yadecd
scenes.fcc_block(1400, schedule=%r, maxIter=40, warnUnconverged=False, parallelMinContacts=0, **%r)
O.run(3, True)
cd = yadecd.integrator()
v = np.array([list(b.state.vel) + list(b.state.angVel) for b in O.bodies])
print('RESULT', O.numThreads, cd.nColours, cd.nInterface, cd.nContacts, hashlib.sha1(v.tobytes()).hexdigest())
"""


def run_with_threads(schedule, threads, **options):
    """PARALLEL_RUN in a fresh YADE with the given thread count (yade -jN) and integrator
    options: the fields of its RESULT line (threads, colours, interface contacts, contacts,
    velocity hash)."""
    import subprocess
    import tempfile
    import yade.config
    exe = os.path.join(yade.config.prefix, 'bin', 'yade' + yade.config.suffix)
    with tempfile.NamedTemporaryFile('w', suffix='.py', delete=False) as f:
        f.write(PARALLEL_RUN % (os.path.join(REPO, 'py'), schedule, options))
    try:
        res = subprocess.run([exe, '-j%d' % threads, '-n', '-x', f.name], capture_output=True, text=True, timeout=300)
    finally:
        os.unlink(f.name)
    line = [l for l in res.stdout.splitlines() if l.startswith('RESULT')]
    if not line:
        raise AssertionError(res.stdout[-2000:] + res.stderr[-2000:])
    return line[0].split()[1:]


def separate_columns(n_columns, height, rows=1, **opts):
    """Separate columns of spheres on a wall, ``n_columns`` along x in each of ``rows`` rows
    along y: no body touches two of them. Returns a sphere's mass."""
    O.reset()
    r, mat = 0.01, scenes.material(0.3)
    O.bodies.append(utils.wall(0, axis=2, sense=1, material=mat))
    for row in range(rows):
        for c in range(n_columns):
            for k in range(height):
                O.bodies.append(utils.sphere((3 * r * c, 3 * r * row, r + 2 * r * k), r, material=mat))
    O.engines = yadecd.engines(gravity=(0, 0, -9.81), **opts)
    O.dt = 1e-4
    return O.bodies[1].state.mass


def step_and_check_columns_exact(test, mass, n_columns, height):
    """One tight step of separate_columns' scene: converged, no interface (every column inside
    one part), and every column's floor force its weight to 1e-9."""
    O.step()
    cd = yadecd.integrator()
    test.assertTrue(cd.converged)
    test.assertEqual(cd.nInterface, 0)
    for c in range(n_columns):
        f = O.interactions[0, 1 + height * c].phys.normalForce[2]
        test.assertAlmostEqual(f / (height * mass * 9.81), 1.0, delta=1e-9)


class TestColouredSweep(unittest.TestCase):
    """schedule='colours': colour by colour, contacts of a colour in parallel."""

    def test_colours_share_no_body_and_column_is_exact(self):
        """A column of 12 at rest: colours alternate along the stack (2 colours), and the solve
        still gives every contact force exactly (floor: the weight, to 1e-9)."""
        sc = scenes.column(12, schedule='colours', tolerance=1e-12, maxIter=200000)
        O.step()
        cd = yadecd.integrator()
        self.assertTrue(cd.converged)
        self.assertEqual(cd.nColours, 2)
        f = O.interactions[0, sc['ids'][0]].phys.normalForce[2]
        self.assertAlmostEqual(f / (12 * sc['m'] * 9.81), 1.0, delta=1e-9)

    def test_bit_identical_for_any_thread_count(self):
        """The same coloured run with 1 and 2 threads (yade -j1, -j2; colours large enough to be
        swept in parallel) ends with bit-identical velocities."""
        out = {}
        for j in (1, 2):
            threads, colours, _, contacts, digest = run_with_threads('colours', j)
            self.assertEqual(int(threads), j)
            self.assertGreater(int(contacts) / int(colours), 64)  # colours big enough to go parallel
            out[j] = digest
        self.assertEqual(out[1], out[2])


class TestSlabSweep(unittest.TestCase):
    """schedule='slabs': slabs swept upwards in parallel, then the interface between them."""

    def test_separate_columns_need_no_interface_and_are_exact(self):
        """Four columns of 10, two slabs: each slab holds two whole columns (no interface), and
        every floor force is the column's weight to 1e-9."""
        m = separate_columns(4, 10, schedule='slabs', slabs=2, tolerance=1e-12, maxIter=200000)
        step_and_check_columns_exact(self, m, 4, 10)

    def test_same_step_as_height_order(self):
        """From the same state of a loose packing (sticking, sliding and open contacts), one step
        solved tightly in three slabs (with an interface) and in plain height order gives the
        same velocities."""
        scenes.random_loose_packing(n=20, tolerance=1e-12, maxIter=100000)
        O.run(250, True)
        O.saveTmp('slabs')
        out = {}
        for order in ('height', 'slabs'):
            O.loadTmp('slabs')
            cd = yadecd.integrator()
            cd.schedule, cd.slabs = order, 3
            O.step()
            self.assertTrue(cd.converged)
            if order == 'slabs':
                self.assertGreater(cd.nInterface, 0)
                self.assertLess(cd.nInterface, cd.nContacts)
            out[order] = np.array([list(b.state.vel) + list(b.state.angVel) for b in O.bodies])
        self.assertLess(np.abs(out['slabs'] - out['height']).max(), 1e-9 * max(np.abs(out['height']).max(), 1e-3))

    def test_bit_identical_for_any_thread_count(self):
        """The same slab run with 1 and 2 threads (yade -j1, -j2; slabs large enough to be swept
        in parallel) ends with bit-identical velocities."""
        out = {}
        for j in (1, 2):
            threads, _, interface, contacts, digest = run_with_threads('slabs', j)
            self.assertEqual(int(threads), j)
            self.assertGreater(int(contacts) - int(interface), 512)  # slabs big enough to go parallel
            self.assertGreater(int(interface), 0)
            out[j] = digest
        self.assertEqual(out[1], out[2])


class TestOwnedBodies(unittest.TestCase):
    """schedule='slabs' with slabsOwnBodies: every body owned by the part holding most of its
    contacts, the interface only the contacts between bodies of two owners."""

    def test_same_step_as_height_order_with_a_smaller_interface(self):
        """From the same state of a loose packing, one step solved tightly in three slabs with
        bodies owned, in three slabs as by default, and in plain height order gives the same
        velocities; the owned interface is not empty and smaller than the default's (a subset
        of it: each of its contacts has a body touching two slabs)."""
        scenes.random_loose_packing(n=40, tolerance=1e-12, maxIter=100000)
        O.run(250, True)
        O.saveTmp('owned')
        out, interface = {}, {}
        for kind in ('height', 'touched', 'owned'):
            O.loadTmp('owned')
            cd = yadecd.integrator()
            if kind != 'height':
                cd.schedule, cd.slabs, cd.slabsOwnBodies = 'slabs', 3, kind == 'owned'
            O.step()
            self.assertTrue(cd.converged)
            interface[kind] = cd.nInterface
            out[kind] = np.array([list(b.state.vel) + list(b.state.angVel) for b in O.bodies])
        self.assertGreater(interface['owned'], 0)
        self.assertLess(interface['owned'], interface['touched'])
        for kind in ('touched', 'owned'):
            self.assertLess(np.abs(out[kind] - out['height']).max(), 1e-9 * max(np.abs(out['height']).max(), 1e-3))

    def test_bit_identical_for_any_thread_count(self):
        """The same run with bodies owned by two slabs, and by 2 x 2 columns, with 1 and 2
        threads ends with bit-identical velocities, different from the default's (another
        order), with a smaller interface."""
        for opts in (dict(slabs=2), dict(slabs=2, slabsAcross=2)):
            out = {}
            for j in (1, 2):
                threads, _, interface, contacts, digest = run_with_threads('slabs', j, slabsOwnBodies=True, **opts)
                self.assertEqual(int(threads), j)
                self.assertGreater(int(contacts) - int(interface), 1024)  # parts big enough to go parallel
                self.assertGreater(int(interface), 0)
                out[j] = digest
            self.assertEqual(out[1], out[2], opts)
            _, _, default_interface, _, default_digest = run_with_threads('slabs', 1, **opts)
            self.assertNotEqual(out[1], default_digest, opts)
            self.assertLess(int(interface), int(default_interface), opts)


class TestColumnSweep(unittest.TestCase):
    """schedule='slabs' with slabsAcross > 1: slabs cut into columns, the parts swept in
    parallel, then the interface groups in colours that share no part."""

    def test_separate_columns_in_a_square_need_no_interface_and_are_exact(self):
        """Four columns of 10 on a 2 x 2 square, two slabs of two columns each: every column is
        a part of its own (no interface), and every floor force is the column's weight to 1e-9."""
        m = separate_columns(2, 10, rows=2, schedule='slabs', slabs=2, slabsAcross=2, tolerance=1e-12, maxIter=200000)
        step_and_check_columns_exact(self, m, 4, 10)

    def test_same_step_as_height_order(self):
        """From the same state of a loose packing, one step solved tightly in 2 x 2 columns (with
        an interface) and in plain height order gives the same velocities."""
        scenes.random_loose_packing(n=40, tolerance=1e-12, maxIter=100000)
        O.run(250, True)
        O.saveTmp('columns')
        out = {}
        for across in (0, 2):
            O.loadTmp('columns')
            cd = yadecd.integrator()
            if across:
                cd.schedule, cd.slabs, cd.slabsAcross = 'slabs', 2, across
            else:
                cd.schedule = 'height'
            O.step()
            self.assertTrue(cd.converged)
            if across:
                self.assertGreater(cd.nInterface, 0)
                self.assertLess(cd.nInterface, cd.nContacts)
            out[across] = np.array([list(b.state.vel) + list(b.state.angVel) for b in O.bodies])
        self.assertLess(np.abs(out[2] - out[0]).max(), 1e-9 * max(np.abs(out[0]).max(), 1e-3))

    def test_bit_identical_for_any_thread_count(self):
        """The same run in 2 x 2 columns with 1 and 2 threads (yade -j1, -j2; parts large enough
        to be swept in parallel) ends with bit-identical velocities, different from the slabs'
        (another order)."""
        out = {}
        for j in (1, 2):
            threads, _, interface, contacts, digest = run_with_threads('slabs', j, slabs=2, slabsAcross=2)
            self.assertEqual(int(threads), j)
            self.assertGreater(int(contacts) - int(interface), 1024)  # parts big enough to go parallel
            self.assertGreater(int(interface), 0)
            out[j] = digest
        self.assertEqual(out[1], out[2])
        self.assertNotEqual(out[1], run_with_threads('slabs', 1)[4])

    def test_bad_parts_are_refused_by_name(self):
        for bad in (0, 65, -1):
            with self.assertRaisesRegex(ValueError, 'slabsAcross=%d: must lie in 1..64' % bad):
                CDI(slabsAcross=bad)
        cd = CDI(slabs=16)
        with self.assertRaisesRegex(ValueError, r'slabs=16 with slabsAcross=8: the parts \(slabs × slabsAcross\) must be at most 64'):
            cd.slabsAcross = 8
        cd.slabs = 8
        cd.slabsAcross = 8   # 64 parts: allowed
        self.assertEqual((cd.slabs, cd.slabsAcross), (8, 8))


class TestAgainstSiconos(unittest.TestCase):
    """A whole step's frictional contact problem, exported by the engine (``problem()``), solved
    by Siconos: impulses agree to 1e-8 where the solution is unique (as many independent
    contacts as needed, W non-singular), velocities wherever."""

    def setUp(self):
        require_siconos(self)

    def test_column_step(self):
        scenes.column(3, tolerance=1e-13, maxIter=100000)
        O.dt = 1e-3
        O.step()
        pb = fclib.local_problem()
        info, rs, _ = siconos_solve(pb['W'], pb['q'], pb['mu'])
        self.assertEqual(info, 0)
        self.assertLess(np.abs(np.array(pb['r']) - rs).max(), 1e-8 * np.abs(rs).max())

    def test_sliding_stack_step(self):
        """Spheres pushed sideways on the floor and on each other: sliding and sticking mixed."""
        sc = scenes.column(3, mu=0.2, tolerance=1e-13, maxIter=100000)
        for k, i in enumerate(sc['ids']):
            O.bodies[i].state.vel = Vector3(0.3 * (k - 1), 0.1 * k, 0)
        O.step()
        cd = yadecd.integrator()
        pb = fclib.local_problem(cd)
        self.assertGreater(cd.nSliding, 0)
        info, rs, us = siconos_solve(pb['W'], pb['q'], pb['mu'])
        self.assertEqual(info, 0)
        self.assertLess(np.abs(np.array(pb['r']) - rs).max(), 1e-8 * np.abs(rs).max())

    def test_packing_velocities(self):
        """A settling packing (hyperstatic: impulses not unique): local velocities agree."""
        scenes.random_loose_packing(n=15, tolerance=1e-12, maxIter=200000)
        O.run(300, True)
        O.step()
        pb = fclib.local_problem()
        W, q, r = pb['W'], pb['q'], pb['r']
        info, rs, us = siconos_solve(W, q, pb['mu'], tol=1e-12)
        self.assertEqual(info, 0)
        u = W @ r + q
        scale = max(np.abs(q).max(), 1e-30)
        self.assertLess(np.abs(u - us).max() / scale, 1e-6)

    def test_fclib_file_round_trip(self):
        """The step's problem written in FCLIB's HDF5 layout reads back identical, and Siconos
        solving the problem read from the file agrees with the engine's impulses to 1e-8; the
        common residual of both solutions is below 1e-10."""
        import os
        import tempfile
        sc = scenes.column(3, mu=0.2, tolerance=1e-13, maxIter=100000)
        for k, i in enumerate(sc['ids']):
            O.bodies[i].state.vel = Vector3(0.3 * (k - 1), 0.1 * k, 0)
        O.step()
        pb = fclib.local_problem()
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, 'step.hdf5')
            fclib.write(path, pb, title='column of 3', description='test')
            back = fclib.read(path)
        self.assertEqual((back['W'] != pb['W']).nnz, 0)
        for key in ('q', 'mu', 'r', 'u'):
            self.assertTrue(np.array_equal(back[key], pb[key]), key)
        sol = fclib.solve_siconos(back['W'], back['q'], back['mu'], tol=1e-14)
        self.assertEqual(sol['info'], 0)
        self.assertLess(np.abs(sol['r'] - pb['r']).max(), 1e-8 * np.abs(sol['r']).max())
        self.assertLess(fclib.residual(back['W'], back['q'], back['mu'], pb['r']), 1e-10)
        self.assertLess(fclib.residual(back['W'], back['q'], back['mu'], sol['r']), 1e-10)

    def test_sparse_export_matches_engine_velocities(self):
        """W r + q of the exported problem is the law's velocity the engine ended with: for a
        sticking column at rest it is zero, and the floor impulse is the column's weight·dt."""
        sc = scenes.column(4, tolerance=1e-13, maxIter=100000)
        O.dt = 1e-3
        O.step()
        pb = fclib.local_problem()
        self.assertLess(np.abs(pb['u']).max(), 1e-12)
        weight = sum(O.bodies[i].state.mass for i in sc['ids']) * 9.81
        floor = [a for a, (i, j) in enumerate(pb['ids']) if not O.bodies[int(i)].dynamic or not O.bodies[int(j)].dynamic]
        self.assertEqual(len(floor), 1)
        self.assertAlmostEqual(pb['r'][3 * floor[0]] / (weight * O.dt), 1.0, delta=1e-9)


if __name__ == '__main__':
    unittest.main()

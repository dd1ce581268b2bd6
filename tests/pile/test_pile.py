"""The sand-pile pipeline: the creation rule on constructed cases, and the whole pipeline
(deposition, checkpoint/resume, snapshots, analyses, figures) on a tiny pile."""
import json
import math
import os
import shutil
import tempfile
import unittest

import numpy as np

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yade import O
import yadecd.pile as pile



def load_figures():
    """yadecd.analysis.report (as scripts/pile_figures.py uses it)."""
    from yadecd.analysis import report as pile_figures
    return pile_figures


class TestCreationRule(unittest.TestCase):
    """Lowest height at which a new sphere rests, without overlap, on a sphere met on its
    vertical: z_j + sqrt((r + r_j)² − d²), or r on the bare plane."""

    def test_bare_plane(self):
        self.assertEqual(pile.creation_height(0, 0, 0.002, np.zeros((0, 3)), np.zeros(0)), 0.002)

    def test_on_one_sphere(self):
        """A grain on the plane: the new one rests on it (the plane under it is not free)."""
        c, rj, r, d = np.array([[0.0, 0.0, 0.003]]), np.array([0.003]), 0.002, 0.004
        z = pile.creation_height(d, 0, r, c, rj)
        self.assertAlmostEqual(z, 0.003 + math.sqrt((r + 0.003) ** 2 - d ** 2), delta=1e-15)

    def test_free_plane_under_a_floating_grain(self):
        """Room between the plane and a grain in flight: the new grain goes on the plane."""
        c, rj = np.array([[0.0, 0.0, 0.02]]), np.array([0.003])
        self.assertEqual(pile.creation_height(0.004, 0, 0.002, c, rj), 0.002)

    def test_below_a_grain_in_flight(self):
        """A grain in flight high above leaves room: the new grain rests on the lower one."""
        c = np.array([[0.0, 0.0, 0.003], [0.0, 0.0, 0.05]])
        rj = np.array([0.003, 0.003])
        self.assertAlmostEqual(pile.creation_height(0, 0, 0.002, c, rj), 0.003 + 0.005, delta=1e-15)

    def test_no_room_below(self):
        """A grain just above leaves no room: the new grain rests on top of it."""
        c = np.array([[0.0, 0.0, 0.003], [0.0, 0.0, 0.011]])
        rj = np.array([0.003, 0.003])
        self.assertAlmostEqual(pile.creation_height(0, 0, 0.002, c, rj), 0.011 + 0.005, delta=1e-15)

    def test_never_overlaps(self):
        rnd = np.random.default_rng(2)
        for _ in range(200):
            c = rnd.uniform([-0.01, -0.01, 0], [0.01, 0.01, 0.03], size=(30, 3))
            rj = rnd.uniform(0.00125, 0.0025, 30)
            x, y, r = rnd.uniform(-0.005, 0.005), rnd.uniform(-0.005, 0.005), rnd.uniform(0.00125, 0.0025)
            z = pile.creation_height(x, y, r, c, rj)
            d = np.sqrt((c[:, 0] - x) ** 2 + (c[:, 1] - y) ** 2 + (c[:, 2] - z) ** 2)
            self.assertGreaterEqual((d - r - rj).min(), -1e-12)
            self.assertGreaterEqual(z, r)


class TestEta(unittest.TestCase):
    """eta_seconds against hand integrals: constant cost, cost growing linearly with the grain
    count during the feed, the relaxation at the final count, the end reached."""

    def test_integrals(self):
        w = 3.0
        self.assertAlmostEqual(pile.eta_seconds(10, 70, 70, w, exponent=0), 60 * w, delta=1e-9)
        # during the feed, cost ∝ N ∝ s: ∫_t^T s/t ds = (T² − t²)/(2t)
        self.assertAlmostEqual(pile.eta_seconds(10, 70, 70, w, exponent=1, points=2001), w * (70 ** 2 - 10 ** 2) / 20, delta=1e-3)
        # feed to 70 s then 2 s at the final count
        expect = w * ((70 ** 2 - 10 ** 2) / 20 + 2 * 7.0)
        self.assertAlmostEqual(pile.eta_seconds(10, 72, 70, w, exponent=1, points=4001), expect, delta=0.05)
        # in the relaxation the count no longer grows
        self.assertAlmostEqual(pile.eta_seconds(71, 72, 70, w, exponent=1.2), w, delta=1e-9)
        self.assertEqual(pile.eta_seconds(72, 72, 70, w), 0.0)
        self.assertEqual(pile.duration(2 * 86400 + 3 * 3600 + 4 * 60 + 5), '2d 03:04:05')
        self.assertEqual(pile.duration(float('inf')), '?')


class TestSnapshotTimes(unittest.TestCase):
    """The snapshot times: the regular grid, the end of the feed added where the grid misses it,
    never twice, not without relaxation, and explicit epochs as given."""

    def times(self, **kw):
        p = dict(pile.DEFAULTS, **kw)
        return pile.snapshot_times(p, pile.feed_end_time(p) + p['relax'])

    def test_grid_and_feed_end(self):
        # 5000 grains at h = 1e-3 (period 5 steps): feed ends at 25 s, snapshots every 2 s to 26 s
        t = self.times(n_grains=5000, dt=1e-3, relax=1.0, snap_every=2.0)
        self.assertEqual(len(t), 14)
        self.assertAlmostEqual(t[11], 24.0)
        self.assertAlmostEqual(t[12], 25.0)
        self.assertAlmostEqual(t[13], 26.0)
        self.assertEqual(t, sorted(t))
        # 14 000 grains, 2 s of relaxation: 70 s is on the grid, not repeated
        t = self.times(n_grains=14000, dt=1e-3, relax=2.0, snap_every=2.0)
        self.assertEqual(len(t), 36)
        self.assertEqual(sum(abs(x - 70.0) < 1e-9 for x in t), 1)
        # no relaxation: the grid ends at the feed end (12 intervals of 25/12 s), not repeated
        t = self.times(n_grains=5000, dt=1e-3, relax=0.0, snap_every=2.0)
        self.assertAlmostEqual(t[-1], 25.0)
        self.assertAlmostEqual(t[0], 25.0 / 12)
        self.assertEqual(len(t), 12)
        # h = 2e-4 (period 25 steps): 1000 grains end at 5 s
        t = self.times(n_grains=1000, dt=2e-4, relax=1.0, snap_every=4.0)
        self.assertEqual(len(t), 3)
        self.assertAlmostEqual(t[0], 3.0)
        self.assertAlmostEqual(t[1], 5.0)
        self.assertAlmostEqual(t[2], 6.0)

    def test_epochs_as_given(self):
        self.assertEqual(self.times(n_grains=5000, dt=1e-3, relax=1.0, epochs='5,10,11'), [5.0, 10.0, 11.0])


class TestTinyPile(unittest.TestCase):
    """Deposition of 60 grains with the paper's protocol, interrupted and resumed, then the
    analyses and every figure."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix='cd-pile-')
        cls.run_dir = os.path.join(cls.tmp, 'run')
        args = dict(n_grains=60, relax=0.6, snap_every=0.3, seed=3, log=lambda s: None)
        pile.run(cls.run_dir, stop_time=0.15, **args)
        cls.stopped_at = O.time
        pile.run(cls.run_dir, resume=True, log=lambda s: None)
        cls.resumed = [tuple(b.state.pos) for b in O.bodies]
        cls.straight_dir = os.path.join(cls.tmp, 'straight')
        pile.run(cls.straight_dir, **args)
        cls.straight = [tuple(b.state.pos) for b in O.bodies]

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_protocol(self):
        """60 grains, one every 1/(200 grains/s), at zero velocity within 0.8 cm of the axis."""
        snaps = sorted(f for f in os.listdir(self.straight_dir) if f.startswith('snap_'))
        s = np.load(os.path.join(self.straight_dir, snaps[-1]))
        births = np.sort(s['birth'][~s['fixed']])
        self.assertEqual(len(births), 60)
        np.testing.assert_allclose(np.diff(births), 1 / 200, rtol=1e-9)
        self.assertAlmostEqual(births[0], 0.0)
        d = s['radius'][~s['fixed']] * 2
        self.assertTrue(((d >= 0.0025) & (d <= 0.005)).all())
        with open(os.path.join(self.straight_dir, 'run.json')) as f:
            p = json.load(f)
        self.assertEqual(p['mu'], 0.4)
        self.assertEqual(p['dt'], 2e-4)

    def test_resume_is_exact(self):
        """Stopped at t=0.15 s, checkpointed and resumed: the same pile as without stopping."""
        self.assertAlmostEqual(self.stopped_at, 0.15, delta=1e-9)
        self.assertEqual(self.resumed, self.straight)

    def test_pile_at_rest_carries_its_weight(self):
        """0.6 s after the last grain this pile (seed 3) is at rest (CD holds it exactly: speeds at
        round-off; a property of this realization: 3 of 8 seeds are at rest then, the others creep
        at 1e-7-1e-5 m/s, docs/performance.md, scripts/bench/rest_check.py) and its supports (paving grains and the plane under them) carry exactly its weight: the sum
        of the vertical contact forces on them equals Σ m g to round-off."""
        snaps = sorted(f for f in os.listdir(self.straight_dir) if f.startswith('snap_'))
        s = np.load(os.path.join(self.straight_dir, snaps[-1]))
        self.assertAlmostEqual(float(s['time']), 0.9, delta=1e-9)
        free = ~s['fixed']
        self.assertLess(np.abs(s['vel'][free]).max(), 1e-9)
        support = set(s['ids'][s['fixed']].tolist()) | {0}           # paving grains and the wall (id 0)
        load = 0.0
        for a, b, f in zip(s['c_id1'], s['c_id2'], s['c_force']):
            if (a in support) != (b in support):
                load += -f[2] if b in support else f[2]             # c_force acts on body 2
        weight = (s['rho'] * 4 / 3 * math.pi * s['radius'][free] ** 3).sum() * s['g']
        self.assertAlmostEqual(load / weight, 1.0, delta=1e-9)

    def test_analyses_and_figures(self):
        out = os.path.join(self.tmp, 'fig')
        summary = load_figures().analyse(self.straight_dir, out)
        with open(os.path.join(out, 'summary.json')) as f:
            saved = json.load(f)
        for k in range(8):
            if k == 3:   # a 60-grain pile has no room for reciprocal bands: skipped, and the summary says why
                self.assertIn('no pair of bands fits', saved['figures_skipped']['fig3_reciprocal_cuts'])
                self.assertFalse(any(f.startswith('fig3') for f in os.listdir(out)))
                continue
            self.assertTrue(any(f.startswith('fig%d' % k) and f.endswith('.png') for f in os.listdir(out)), 'figure %d' % k)
        for key in ('slope_deg', 'H_m', 'p_center_Pa', 'hydrostatic_Pa', 'floor_load_over_weight'):
            self.assertIn(key, saved)
        # a 60-grain pile is about two grains high: no straight flank, and the summary says why
        self.assertIsNone(saved['slope_deg'])
        self.assertIn('no straight flank', saved['slope_note'])
        self.assertGreater(saved['H_over_d'], 1.5)
        self.assertLess(saved['H_over_d'], 3.0)
        # the paving carries the weight less what reaches the plane between paving grains
        self.assertGreater(saved['floor_load_over_weight'], 0.8)
        self.assertLessEqual(saved['floor_load_over_weight'], 1.0 + 1e-9)
        self.assertEqual(saved['n_pile_grains'], 60)
        self.assertGreater(saved['p_center_Pa'], 0)
        # pile grains: every grain but those in flight at the snapshot (no loaded contact), and
        # a grain in flight must be moving (a grain at rest in the pile is never left out)
        snaps = sorted(f for f in os.listdir(self.straight_dir) if f.startswith('snap_'))
        snap = np.load(os.path.join(self.straight_dir, snaps[-1]))
        loaded = np.zeros(len(snap['ids']), dtype=bool)
        index = {int(b): k for k, b in enumerate(snap['ids'])}
        for a, b, f in zip(snap['c_id1'], snap['c_id2'], snap['c_force']):
            if np.linalg.norm(f) > 0:  # the floor wall is not among the grains
                loaded[[index[int(k)] for k in (a, b) if int(k) in index]] = True
        flying = ~snap['fixed'] & ~loaded
        self.assertEqual(saved['n_pile_grains'], 60 - flying.sum())
        self.assertLessEqual(flying.sum(), 3)
        self.assertTrue((np.linalg.norm(snap['vel'][flying], axis=1) > 0.01).all())
        self.assertTrue(math.isfinite(saved['chord_angle_deg']) and math.isfinite(saved['p_center_Pa']))


class TestConeState(unittest.TestCase):
    """yadecd.pile.cone_state, the benchmark's large pile state, and the solver benchmark on it
    (fed by the creation rule, slab sweep on two threads: the harness must keep running)."""

    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp(prefix='cone_')
        cls.path = pile.cone_state(cls.dir, n_grains=150, settle=0.004, cell_grains=800, log=lambda *a: None)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.dir, ignore_errors=True)

    def test_grains_stand_on_the_floor(self):
        """Exactly the grains asked for, in the protocol's size range, none below the floor
        plane, on a paving of fixed grains."""
        snap = np.load(self.path)
        grains = ~snap['fixed']
        self.assertEqual(grains.sum(), 150)
        self.assertGreater(snap['fixed'].sum(), 20)
        d = 2 * snap['radius'][grains]
        self.assertTrue(((d >= 0.0025 - 1e-9) & (d <= 0.005 + 1e-9)).all())
        self.assertTrue((snap['pos'][:, 2] >= snap['radius'] * (1 - 1e-6)).all())
        with open(os.path.join(self.dir, 'run.json')) as f:
            self.assertEqual(json.load(f)['n_grains'], 150)

    def test_separating_dilation(self):
        """Constructed spheres: the factor is the largest (r_i + r_j) / distance, 1 without overlap."""
        r = np.array([1.0, 1.0, 0.5])
        x = np.array([[0, 0, 0], [1.9, 0, 0], [0, 10, 0]])
        self.assertAlmostEqual(pile.separating_dilation(x, r), 2 / 1.9, delta=1e-8)
        x[2] = (0, 1.2, 0)                                   # 1.5 / 1.2 overlaps more
        self.assertAlmostEqual(pile.separating_dilation(x, r), 1.5 / 1.2, delta=1e-8)
        self.assertEqual(pile.separating_dilation([[0, 0, 0], [3, 0, 0]], [1, 1]), 1.0)
        self.assertEqual(pile.separating_dilation([[0, 0, 0]], [1]), 1.0)
        with self.assertRaisesRegex(ValueError, 'share a centre'):
            pile.separating_dilation([[0, 0, 0], [0, 0, 0]], [1, 1])

    def test_separated_cone_has_no_overlaps(self):
        """separate=True: after settling, grain-grain overlaps are the engine's own (below its
        position tolerance), where the plain cone keeps the packing's (checked larger, so the
        comparison can fail)."""
        def largest_overlap(path):
            snap = np.load(path)
            rad = dict(zip(snap['ids'].tolist(), snap['radius'].tolist()))
            pos = dict(zip(snap['ids'].tolist(), map(tuple, snap['pos'])))
            worst = 0.0
            for a, b in zip(snap['c_id1'].tolist(), snap['c_id2'].tolist()):
                if a in rad and b in rad:
                    worst = max(worst, (rad[a] + rad[b] - np.linalg.norm(np.subtract(pos[a], pos[b]))) / min(rad[a], rad[b]))
            return worst
        with tempfile.TemporaryDirectory(prefix='cone_sep_') as d:
            path = pile.cone_state(d, n_grains=150, settle=0.004, cell_grains=800, log=lambda *a: None, separate=True)
            separated = largest_overlap(path)
        plain = largest_overlap(self.path)
        self.assertGreater(plain, 1e-4)
        self.assertLess(separated, 2e-6)            # positionTolerance 1e-6 of the smaller radius, and round-off

    def test_bad_arguments(self):
        with self.assertRaises(ValueError) as cm:
            pile.cone_state(self.dir, n_grains=150, slope_deg=60)
        self.assertIn('slope_deg', str(cm.exception))

    def test_solver_bench_runs_on_it(self):
        import csv
        import subprocess
        import yade.config
        exe = os.path.join(yade.config.prefix, 'bin', 'yade' + yade.config.suffix)
        out = os.path.join(self.dir, 'bench.csv')
        res = subprocess.run([exe, '-j2', '-n', '-x', os.path.join(REPO, 'scripts', 'bench', 'solver_bench.py'), '--contacts', '',
                              '--snapshot', self.path, '--pile-steps', '2', '--feed', '--pile-variants', 'height', '--out', out],
                             capture_output=True, text=True, timeout=600)
        self.assertTrue(os.path.exists(out), res.stdout[-2000:] + res.stderr[-2000:])
        with open(out) as f:
            rows = list(csv.DictReader(f))
        methods = {r['method'] for r in rows if r['kind'] == 'stage'}
        self.assertEqual(methods, {'CD', 'CD height order'})
        self.assertTrue(all(r['threads'] == '2' for r in rows))
        self.assertEqual(len([r for r in rows if r['kind'] == 'determinism']), 1)


class TestPileMethods(unittest.TestCase):
    """The same protocol with YADE's MD (the CD-versus-MD comparison of a pile), bad methods."""

    def test_md_pile(self):
        """method='MD': YADE's linear law at 0.5·PWaveTimeStep, grains fed at the same rate in
        simulated time, resting with small but non-zero overlaps, forces in the snapshot."""
        tmp = tempfile.mkdtemp(prefix='cd-pile-md-')
        try:
            p = pile.run(tmp, n_grains=8, relax=0.05, snap_every=1.0, seed=2, method='MD', young=1e6, log=lambda s: None)
            from yade.wrapper import NewtonIntegrator, ContactDynamicsIntegrator
            self.assertIsInstance(O.engines[-1], NewtonIntegrator)
            self.assertNotIsInstance(O.engines[-1], ContactDynamicsIntegrator)
            from yade import utils
            self.assertAlmostEqual(p['dt'], 0.5 * utils.PWaveTimeStep(), delta=1e-12)
            self.assertAlmostEqual(O.time, 8 / 200.0 + 0.05, delta=2 * p['dt'])
            pen = [i.geom.penetrationDepth for i in O.interactions if i.isReal]
            self.assertTrue(pen and max(pen) > 0)
            snaps = [f for f in os.listdir(tmp) if f.startswith('snap_')]
            snap = np.load(os.path.join(tmp, snaps[-1]))
            self.assertGreater(np.linalg.norm(snap['c_force'], axis=1).max(), 0)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def test_md_pile_of_clumps(self):
        """The MD protocol with clump grains: YADE's NewtonIntegrator moves the same clumps, with
        the union's mass, and the snapshot counts them as grains."""
        tmp = tempfile.mkdtemp(prefix='cd-pile-md-clumps-')
        try:
            pile.run(tmp, n_grains=6, relax=0.02, snap_every=1.0, seed=2, method='MD', young=1e6, grain_shape='dimer',
                     log=lambda s: None)
            clumps = [b for b in O.bodies if b.isClump]
            self.assertEqual(len(clumps), 6)
            for b in clumps:
                a = O.bodies[sorted(b.shape.members)[0]].shape.radius
                self.assertAlmostEqual(b.state.mass / (1000 * pile.SHAPES['dimer']['volume'] * a ** 3), 1, delta=1e-12)
            snaps = [f for f in os.listdir(tmp) if f.startswith('snap_')]
            snap = np.load(os.path.join(tmp, snaps[-1]))
            self.assertEqual(sorted(snap['ids'][~snap['fixed']].tolist()), sorted(b.id for b in clumps))
            self.assertEqual(len(snap['m_grain']), 12)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def test_unknown_method(self):
        """Rejected before anything is built: the current scene is left as it was."""
        tmp = tempfile.mkdtemp(prefix='cd-pile-bad-')
        n_before = len(O.bodies)
        try:
            with self.assertRaisesRegex(ValueError, "method must be 'CD' or 'MD'"):
                pile.run(tmp, n_grains=2, method='FEM', log=lambda s: None)
            self.assertEqual(len(O.bodies), n_before)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)



class TestEnsembleDriver(unittest.TestCase):
    """scripts/pile_ensemble.py drives real YADE runs: two tiny piles, one of which has a damaged
    checkpoint, run to the end: the healthy one finishes, the damaged one is reported as failed
    with its error, the driver exits 1, and `analyse` lists the failure and uses the other."""

    def test_one_failure_does_not_stop_the_others(self):
        import subprocess
        script = os.path.join(SCRIPTS, 'pile_ensemble.py')
        with tempfile.TemporaryDirectory() as d:
            root = os.path.join(d, 'ens')
            bad = os.path.join(root, 'n6_s2')
            os.makedirs(bad)
            with open(os.path.join(bad, 'checkpoint.json'), 'w') as f:
                f.write('{"births": {"1": ')         # a checkpoint cut short by a kill
            with open(os.path.join(bad, 'run.json'), 'w') as f:
                json.dump({'n_grains': 6, 'seed': 2}, f)
            proc = subprocess.run(['/usr/bin/python3', script, 'run', root, '--sizes', '6', '--seeds', '1-2',
                                   '--relax', '0.05', '--jobs', '2'], capture_output=True, text=True, timeout=600)
            self.assertEqual(proc.returncode, 1, proc.stdout + proc.stderr)
            self.assertRegex(proc.stdout, r'n6_s1\s+done')
            self.assertRegex(proc.stdout, r'n6_s2\s+failed')
            with open(os.path.join(root, 'ensemble.json')) as f:
                status = json.load(f)['runs']
            self.assertEqual(status['n6_s1']['state'], 'done')
            self.assertEqual(status['n6_s2']['state'], 'failed')
            self.assertNotEqual(status['n6_s2']['returncode'], 0)
            self.assertTrue(status['n6_s2']['error'])
            proc = subprocess.run(['/usr/bin/python3', script, 'analyse', root], capture_output=True, text=True,
                                  timeout=600)
            self.assertEqual(proc.returncode, 0, proc.stderr)
            with open(os.path.join(root, 'analysis', 'ensemble_summary.json')) as f:
                summary = json.load(f)
            self.assertEqual(summary['n_runs_analysed'], 1)
            self.assertIn('n6_s2', summary['failed_runs'])


if __name__ == '__main__':
    unittest.main()

"""Long-run reliability of pile runs (docs/reliability.md): the layout-independent run state, resume
from it and from YADE's archive, damaged checkpoints, kills at random moments (the fast version of
scripts/fault_injection.py), a full disk, checks before work, a checkpoint of the previous release,
and a checkpoint that survives a change of the engine's serialized attributes."""
import json
import os
import shutil
import subprocess
import tempfile
import unittest

import numpy as np

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yade import O
import yadecd.pile as pile
from yadecd.runs import runstate
from yadecd.runs.checkpoint import CheckpointError, CheckpointStore
from yadecd.testing import faults

TINY = dict(n_grains=30, relax=0.05, snap_every=1e9, seed=5)   # 0.2 s: 1000 steps
QUIET = dict(log=lambda s: None)
REBUILT_GAP = 1e-6   # [d_min] measured: 0 (the rebuilt run repeats the uninterrupted one here)


def scene_arrays():
    """Every body's state and every contact's impulse, in container order (exact values)."""
    b = np.array([tuple(x.state.pos) + tuple(x.state.vel) + tuple(x.state.angVel) + tuple(x.state.ori[k] for k in range(4))
                  for x in O.bodies])
    c = [(i.id1, i.id2) + tuple(i.phys.impulse) for i in O.interactions if i.isReal]
    return b, sorted(c)


class TestRunState(unittest.TestCase):
    """state.npz holds the exact physical state, and a scene rebuilt from it equals the saved one."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix='cd-runstate-')
        cls.run_dir = os.path.join(cls.tmp, 'run')
        pile.run(cls.run_dir, stop_time=0.1, **TINY, **QUIET)
        cls.saved_bodies, cls.saved_contacts = scene_arrays()
        seq, unit, info = CheckpointStore(cls.run_dir).latest()
        cls.unit, cls.info = unit, info
        cls.data = runstate.read(os.path.join(unit, 'state.npz'))

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_format(self):
        d = self.data
        self.assertEqual(str(d['format']), 'yadecd-runstate')
        self.assertEqual(int(d['format_version']), runstate.FORMAT_VERSION)
        self.assertEqual(str(d['plugin_digest']), runstate.plugin_digest())
        self.assertAlmostEqual(float(d['time']), 0.1, delta=1e-12)
        self.assertEqual(int(d['iter']), 500)
        self.assertEqual(len(d['body_id']), len(O.bodies))
        self.assertGreater(len(d['c_id1']), 30)
        self.assertEqual(self.info['meta']['created'], 20)     # one grain every 25 steps: steps 0, 25, ..., 475

    def test_rebuild_is_exact(self):
        """Rebuilt by the code that builds a new run: bodies, orientations, velocities and every
        contact's warm-start impulse equal the saved ones exactly."""
        r = pile.PileRun(self.run_dir, json.load(open(os.path.join(self.run_dir, 'run.json'))), lambda s: None)
        r.rebuild(self.data)
        bodies, contacts = scene_arrays()
        np.testing.assert_array_equal(bodies, self.saved_bodies)
        self.assertEqual(contacts, self.saved_contacts)
        self.assertEqual(r.clock.time(), float(self.data['time']))
        self.assertEqual(r.clock.iter(), 500)

    def test_newer_format_refused(self):
        path = os.path.join(self.tmp, 'newer.npz')
        arrays = dict(self.data)
        arrays['format_version'] = np.array(99)
        np.savez(path, **arrays)
        with self.assertRaisesRegex(runstate.RunStateError, 'format 99; this plugin reads up to %d' % runstate.FORMAT_VERSION):
            runstate.read(path)

    def test_mismatched_scene_refused(self):
        """A run state restored into a scene with other bodies is refused before any body moves."""
        r = pile.PileRun(self.run_dir, json.load(open(os.path.join(self.run_dir, 'run.json'))), lambda s: None)
        r.rebuild(self.data)
        before = scene_arrays()[0]
        data = dict(self.data)
        data['radius'] = data['radius'].copy()
        data['radius'][40] *= 1.01
        data['pos'] = data['pos'] + 1e-3
        with self.assertRaisesRegex(runstate.RunStateError, 'body 40 has radius'):
            runstate.restore_bodies(data)
        np.testing.assert_array_equal(scene_arrays()[0], before)


def _listing(run_dir):
    """Every file under a run directory with its size and modification time."""
    out = {}
    for root, _, files in os.walk(run_dir):
        for name in files:
            st = os.stat(os.path.join(root, name))
            out[os.path.relpath(os.path.join(root, name), run_dir)] = (st.st_size, st.st_mtime_ns)
    return out


class TestResume(unittest.TestCase):
    """Resumes end where an uninterrupted run ends: bit for bit through YADE's archive (same
    plugin), from the previous unit when the newest is damaged, and from a first-release
    checkpoint; to the solver's tolerance when rebuilt from state.npz."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix='cd-resume-')
        cls.ref_dir = os.path.join(cls.tmp, 'straight')
        pile.run(cls.ref_dir, **TINY, **QUIET)
        cls.ref = faults.final_state(cls.ref_dir)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def stopped_run(self, name, stops=(0.05, 0.1)):
        run_dir = os.path.join(self.tmp, name)
        pile.run(run_dir, stop_time=stops[0], **TINY, **QUIET)
        for t in stops[1:]:
            pile.run(run_dir, resume=True, stop_time=t, **QUIET)
        return run_dir

    def test_archive_resume_is_bit_identical(self):
        run_dir = self.stopped_run('archive')
        lines = []
        pile.run(run_dir, resume=True, log=lines.append)
        self.assertIn('bit-identical continuation', lines[0])
        self.assertEqual(faults.compare_states(faults.final_state(run_dir), self.ref), '')

    def test_archive_resume_keeps_the_columns(self):
        """slabs_across and slabs_own_bodies (columns, bodies owned by them: engine attributes
        YADE's archive does not hold) are restored from run.json on a resume: the resumed run ends
        bit for bit where the same run without a stop ends, and that end is not the two slabs'
        (the columns are another order)."""
        opts = dict(TINY, slabs=2, slabs_across=2, slabs_own_bodies=True)
        straight = os.path.join(self.tmp, 'columns_straight')
        pile.run(straight, **opts, **QUIET)
        run_dir = os.path.join(self.tmp, 'columns')
        pile.run(run_dir, stop_time=0.1, **opts, **QUIET)
        lines = []
        pile.run(run_dir, resume=True, log=lines.append)
        self.assertIn('bit-identical continuation', lines[0])
        self.assertEqual(O.engines[-1].slabsAcross, 2)
        self.assertTrue(O.engines[-1].slabsOwnBodies)
        self.assertEqual(faults.compare_states(faults.final_state(run_dir), faults.final_state(straight)), '')
        self.assertNotEqual(faults.compare_states(faults.final_state(straight), self.ref), '')

    def test_wall_time_adds_up_over_segments(self):
        """A run stopped twice and resumed: run.json's total wall time is the sum of its segments'
        (each checkpoint carries the wall time so far, its last one to the segment's own end), and progress.csv's wall column never falls back."""
        run_dir = os.path.join(self.tmp, 'walls')
        segments = [pile.run(run_dir, stop_time=0.05, **TINY, **QUIET)['wall_time_s']]
        segments.append(pile.run(run_dir, resume=True, stop_time=0.1, **QUIET)['wall_time_s'])
        p = pile.run(run_dir, resume=True, **QUIET)
        segments.append(p['wall_time_s'])
        # a segment's end and its last checkpoint's record are the same instant: the sums agree to round-off
        self.assertAlmostEqual(p['wall_time_total_s'], sum(segments), delta=1e-9)
        self.assertGreater(p['wall_time_total_s'], p['wall_time_s'])
        with open(os.path.join(run_dir, 'progress.csv')) as f:
            walls = [float(ln.split(',')[5]) for ln in f.readlines()[1:]]
        self.assertEqual(walls, sorted(walls))
        self.assertGreater(walls[-1], segments[0])

    def test_damaged_newest_unit(self):
        """Truncated or altered files of the newest unit: reported, the unit before it is used,
        and the end is still bit-identical."""
        for name, how in (('state.npz', 'truncate'), ('scene.yade.gz', 'flip'), ('meta.json', 'truncate')):
            with self.subTest(file=name, damage=how):
                run_dir = self.stopped_run('damaged_%s_%s' % (name, how))
                units = faults.units(run_dir)
                faults.damage(os.path.join(run_dir, 'ckpt', '%06d' % units[-1][0], name), how, np.random.default_rng(1))
                lines = []
                pile.run(run_dir, resume=True, log=lines.append)
                text = '\n'.join(lines)
                self.assertIn('checkpoint %d skipped' % units[-1][0], text)
                self.assertIn('resumed %s at t=0.050 s' % run_dir, text)
                self.assertEqual(faults.compare_states(faults.final_state(run_dir), self.ref), '')

    def test_rebuilt_resume(self):
        """The state.npz path (a checkpoint written by another plugin build, simulated by its
        recorded digest): the log says so, the run ends with the same grains, birth times and
        paving, and every grain ends close to the uninterrupted run (same physical state; the
        contact order and the collider start afresh, so not bit for bit)."""
        run_dir = self.stopped_run('rebuilt', stops=(0.1,))
        seq, unit, info = CheckpointStore(run_dir).latest()
        info['meta']['plugin_digest'] = 'another-build'
        with open(os.path.join(unit, 'meta.json'), 'w') as f:     # meta.json is not among the digested files
            json.dump(info, f)
        lines = []
        pile.run(run_dir, resume=True, log=lines.append)
        text = '\n'.join(lines)
        self.assertIn('rebuilt from state.npz', text)
        self.assertIn('written by plugin another-bui', text)
        end = faults.final_state(run_dir)
        np.testing.assert_array_equal(end['ids'], self.ref['ids'])
        # the rebuilt clock is the saved time plus YADE's new O.time: sums differ by round-off
        np.testing.assert_allclose(end['birth'], self.ref['birth'], rtol=0, atol=1e-13)
        np.testing.assert_array_equal(end['radius'], self.ref['radius'])
        gap = np.abs(end['pos'] - self.ref['pos']).max() / pile.DEFAULTS['d_min']
        print('rebuilt resume: largest position difference %.3g d_min' % gap)
        self.assertLess(gap, REBUILT_GAP)

    def test_load_leaves_the_run_alone(self):
        """PileRun.load (the tools' way into a run's state, pile_tolerance.py's) gives the
        checkpoint's state, time and birth times, through YADE's archive and through a carried
        copy's state.npz alike, and changes nothing in either directory."""
        from yadecd.runs.carry import carry
        run_dir = self.stopped_run('load', stops=(0.1,))
        carried = os.path.join(self.tmp, 'load_carried')
        carry(run_dir, carried, log=lambda s: None)
        seen = {}
        for d in (run_dir, carried):
            before = _listing(d)
            lines = []
            run = pile.PileRun.load(d, log=lines.append)
            self.assertAlmostEqual(run.clock.time(), 0.1, delta=1e-12)
            seen[d] = (np.array([tuple(b.state.pos) for b in O.bodies]), dict(run.births))
            self.assertEqual(_listing(d), before)
        self.assertIn('rebuilt from state.npz', run.resumed_from)
        np.testing.assert_array_equal(seen[run_dir][0], seen[carried][0])
        self.assertEqual(seen[run_dir][1], seen[carried][1])
        self.assertGreater(len(seen[run_dir][1]), 0)
        with self.assertRaisesRegex(FileNotFoundError, 'no run.json'):
            pile.PileRun.load(self.tmp)

    def test_feed_end_kept(self):
        """A run that relaxes after its feed keeps its checkpoint at the end of the feed as a carried
        copy of itself (``at_feed_end``: pruning leaves it alone), loadable like any run: its state
        is the feed-end snapshot's, grain for grain. A run stopped before the feed's end and
        resumed keeps one too; one resumed after the feed's end without a copy runs on without."""
        from yadecd.runs.carry import FEED_END_DIR
        t_feed = pile.feed_end_time(dict(pile.DEFAULTS, **TINY))
        for run_dir in (self.ref_dir, self.stopped_run('feed_end', stops=(0.1,))):
            if run_dir != self.ref_dir:
                pile.run(run_dir, resume=True, **QUIET)
            copy = os.path.join(run_dir, FEED_END_DIR)
            seq, _, info = CheckpointStore(copy).latest()
            self.assertAlmostEqual(info['meta']['time'], t_feed, delta=1e-12)
            self.assertGreater(CheckpointStore(run_dir).latest()[0], seq)      # the run went on after it
            run = pile.PileRun.load(copy, **QUIET)
            self.assertAlmostEqual(run.clock.time(), t_feed, delta=1e-12)
            with np.load(os.path.join(run_dir, 'snap_%08.3f.npz' % t_feed)) as z:
                ids, pos, fixed = z['ids'], z['pos'], z['fixed']
            self.assertEqual(int((~fixed.astype(bool)).sum()), TINY['n_grains'])     # every grain, and the paving
            np.testing.assert_array_equal(np.array([tuple(O.bodies[int(i)].state.pos) for i in ids]), pos)
        # resumed after the end of the feed, its copy gone: the run ends as before, without one
        late = self.stopped_run('late', stops=(t_feed + 0.02,))
        shutil.rmtree(os.path.join(late, FEED_END_DIR))
        pile.run(late, resume=True, **QUIET)
        self.assertFalse(os.path.exists(os.path.join(late, FEED_END_DIR)))
        self.assertEqual(faults.compare_states(faults.final_state(late), self.ref), '')

    def test_carried_resume(self):
        """A run carried to another directory (yadecd.runs.carry: state.npz only, as committed between
        machines) resumes there through the state.npz path and ends where the uninterrupted run
        ends, to the rebuilt path's gap; the source is untouched."""
        from yadecd.runs.carry import carry
        run_dir = self.stopped_run('to_carry', stops=(0.1,))
        before = sorted(os.listdir(os.path.join(run_dir, 'ckpt')))
        dest = os.path.join(self.tmp, 'carried')
        record = carry(run_dir, dest, log=lambda s: None)
        self.assertEqual(sorted(os.listdir(os.path.join(run_dir, 'ckpt'))), before)
        self.assertEqual(record['checkpoint_files_left_out'], ['scene.yade.gz'])
        self.assertAlmostEqual(record['time'], 0.1, delta=1e-12)
        self.assertFalse(os.path.exists(os.path.join(dest, 'ckpt', '%06d' % record['checkpoint'], 'scene.yade.gz')))
        lines = []
        pile.run(dest, resume=True, log=lines.append)
        self.assertIn('rebuilt from state.npz', '\n'.join(lines))
        end = faults.final_state(dest)
        np.testing.assert_array_equal(end['ids'], self.ref['ids'])
        np.testing.assert_array_equal(end['radius'], self.ref['radius'])
        gap = np.abs(end['pos'] - self.ref['pos']).max() / pile.DEFAULTS['d_min']
        self.assertLess(gap, REBUILT_GAP)


    def test_branch(self):
        """A branch (pile.branch, pile.py --branch-from) starts from its source's newest checkpoint
        with the solver options changed and recorded, runs to the end with them, and leaves the
        source untouched; an option of the pile itself, an unknown one or an occupied directory is
        refused before anything is copied."""
        src = self.stopped_run('branch_source', stops=(0.1,))
        with open(os.path.join(src, 'run.json')) as f:
            source_json = f.read()
        tol = json.loads(source_json)['tolerance']
        dest = os.path.join(self.tmp, 'branch')
        p = pile.run(dest, branch_from=src, tolerance=3 * tol, **QUIET)
        self.assertTrue(p['finished'])
        self.assertEqual(O.engines[-1].tolerance, 3 * tol)            # the branch's steps used it
        self.assertEqual(p['tolerance'], 3 * tol)
        [record] = p['branches']
        self.assertAlmostEqual(record['time'], 0.1, delta=1e-12)
        self.assertEqual(record['changes'], {'tolerance': [tol, 3 * tol]})
        self.assertEqual(os.path.realpath(record['source']), os.path.realpath(src))
        with open(os.path.join(src, 'run.json')) as f:
            self.assertEqual(f.read(), source_json)                  # the source is untouched
        end = faults.final_state(dest)
        np.testing.assert_array_equal(end['ids'], self.ref['ids'])   # same grains, same feed
        for options, error, word in (({'n_grains': 31}, ValueError, 'n_grains'),
                                     ({'dt': 1e-4}, ValueError, 'dt'),
                                     ({'no_such_option': 1}, ValueError, 'no_such_option'),
                                     ({'tolerance': -1.0}, ValueError, 'tolerance')):
            with self.subTest(options=options):
                bad = os.path.join(self.tmp, 'branch_bad')
                with self.assertRaisesRegex(error, word):
                    pile.branch(src, bad, options, **QUIET)
                self.assertFalse(os.path.exists(bad))
        with self.assertRaisesRegex(FileExistsError, 'never replaces'):
            pile.branch(src, dest, {'tolerance': tol}, **QUIET)
        with self.assertRaisesRegex(FileNotFoundError, 'no run.json'):
            pile.branch(os.path.join(self.tmp, 'nothing_here'), os.path.join(self.tmp, 'b2'), {}, **QUIET)


class TestPreviousRelease(unittest.TestCase):
    """A checkpoint written by the first release (commit 6e7a405: checkpoint.yade.gz +
    checkpoint.json), kept in tests/data, resumes with this code and ends exactly where that
    release's own uninterrupted run ended (final_uninterrupted.npz, written by it)."""

    def test_release_6e7a405(self):
        src = os.path.join(DATA, 'checkpoint_release_6e7a405')
        with tempfile.TemporaryDirectory() as tmp:
            run_dir = os.path.join(tmp, 'run')
            os.makedirs(run_dir)
            for name in ('run.json', 'checkpoint.json', 'checkpoint.yade.gz'):
                shutil.copy(os.path.join(src, name), run_dir)
            lines = []
            pile.run(run_dir, resume=True, log=lines.append)
            self.assertIn('first-release checkpoint', lines[0])
            ref = np.load(os.path.join(src, 'final_uninterrupted.npz'))
            self.assertEqual(O.iter, int(ref['iter']))
            for key, values in (('pos', [tuple(b.state.pos) for b in O.bodies]),
                                ('vel', [tuple(b.state.vel) for b in O.bodies]),
                                ('angVel', [tuple(b.state.angVel) for b in O.bodies]),
                                ('ori', [[b.state.ori[k] for k in range(4)] for b in O.bodies])):
                np.testing.assert_array_equal(np.array(values), ref[key], err_msg=key)
            self.assertTrue(os.path.isdir(os.path.join(run_dir, 'ckpt')))   # later checkpoints: the new format


class TestChecksBeforeWork(unittest.TestCase):
    """Bad values, an existing run, options that contradict the run being resumed, an unusable or
    too small directory: a clear error naming the culprit, before any step and any file."""

    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix='cd-checks-')

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def test_bad_values(self):
        bad = [('n_grains', 0), ('n_grains', 2.5), ('d_min', -0.001), ('d_max', 0.001), ('mu', -0.1), ('en', 1.5),
               ('dt', 0.0), ('rate', -1.0), ('tolerance', 2.0), ('max_iter', 0), ('relaxation', 2.0),
               ('sweep_order', 7), ('method', 'FEM'), ('epochs', '1,x'), ('epochs', '0'), ('snap_every', 0.0),
               ('checkpoint_every', -1.0), ('dt', float('nan')), ('seed', 'one'), ('md_damping', 1.0),
               ('parallel_min_contacts', -1), ('parallel_min_contacts', 2.5), ('slabs', 0), ('slabs_across', 65)]
        for key, value in bad:
            with self.subTest(key=key, value=value):
                run_dir = os.path.join(self.tmp, 'bad_%s' % key)
                with self.assertRaisesRegex(ValueError, key):
                    # a tiny pile: a value the check let through must not start a 14 000-grain run
                    pile.run(run_dir, **dict(TINY, stop_time=0.01, **{key: value}), **QUIET)
                self.assertFalse(os.path.exists(run_dir), 'a run directory was made before the check')
        with self.assertRaisesRegex(ValueError, 'unknown pile parameters: grains'):
            pile.run(os.path.join(self.tmp, 'x'), grains=3, **QUIET)
        # each value valid alone, not together: 16 x 8 parts
        with self.assertRaisesRegex(ValueError, r'slabs=16, slabs_across=8.*must be at most 64'):
            pile.run(os.path.join(self.tmp, 'parts'), **dict(TINY, slabs=16, slabs_across=8), **QUIET)
        self.assertFalse(os.path.exists(os.path.join(self.tmp, 'parts')))

    def test_existing_run_is_never_overwritten(self):
        run_dir = os.path.join(self.tmp, 'run')
        pile.run(run_dir, stop_time=0.01, **TINY, **QUIET)
        with self.assertRaisesRegex(FileExistsError, 'already holds a pile run.*--resume.*--overwrite'):
            pile.run(run_dir, **TINY, **QUIET)
        open(os.path.join(run_dir, 'notes.txt'), 'w').write('mine')
        pile.run(run_dir, stop_time=0.01, overwrite=True, **TINY, **QUIET)
        self.assertTrue(os.path.exists(os.path.join(run_dir, 'notes.txt')))   # only the run's own files go

    def test_resume_options_must_match(self):
        run_dir = os.path.join(self.tmp, 'run')
        pile.run(run_dir, stop_time=0.01, **TINY, **QUIET)
        with self.assertRaisesRegex(ValueError, r'seed \(run: 5, given: 6\).*only stop_time'):
            pile.run(run_dir, resume=True, seed=6, **QUIET)
        with self.assertRaisesRegex(FileNotFoundError, 'nothing to resume'):
            pile.run(os.path.join(self.tmp, 'none'), resume=True, **QUIET)

    def test_unusable_directory(self):
        blocker = os.path.join(self.tmp, 'a_file')
        open(blocker, 'w').close()
        with self.assertRaisesRegex(CheckpointError, 'not usable'):
            pile.run(os.path.join(blocker, 'run'), **TINY, **QUIET)
        with self.assertRaisesRegex(CheckpointError, r'MB free; this run needs about'):
            pile.run(os.path.join(self.tmp, 'huge'), n_grains=10 ** 10, **QUIET)

    def test_command_line(self):
        """scripts/pile.py: exit 2 and one line naming the value, before YADE steps."""
        for args, expect in ((['--tolerance', '-1'], 'tolerance=-1.0: ContactDynamicsIntegrator.tolerance=-1.000000: must lie in (0, 1)'),
                             (['--n-grains', 'many'], "invalid int value: 'many'"),
                             (['--resume', '--overwrite'], 'exclude each other')):
            with self.subTest(args=args):
                out = os.path.join(self.tmp, 'cli')
                proc = subprocess.run(faults.pile_command(out, args), capture_output=True, text=True, timeout=120)
                self.assertEqual(proc.returncode, 2, proc.stdout + proc.stderr)
                self.assertIn(expect, proc.stderr)
                self.assertFalse(os.path.exists(os.path.join(out, 'run.json')))


KILL_RUN = ['--n-grains', '100', '--relax', '0.2', '--seed', '4', '--snap-every', '1e9', '--checkpoint-every', '0.3']


def reference_end(tmp):
    """Final snapshot of the uninterrupted KILL_RUN pile (same code, same plugin)."""
    ref_dir = os.path.join(tmp, 'reference')
    proc = subprocess.run(faults.pile_command(ref_dir, KILL_RUN), capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        raise RuntimeError(proc.stdout + proc.stderr)
    return faults.final_state(ref_dir)


class TestKills(unittest.TestCase):
    """kill -9 at random moments, one of them during a checkpoint write, one followed by damage
    to the newest checkpoint: every resume continues, the end is bit-identical to an
    uninterrupted run, and no kill loses more than one checkpoint interval."""

    def test_kills(self):
        with tempfile.TemporaryDirectory() as tmp:
            ref = reference_end(tmp)
            run_dir = os.path.join(tmp, 'killed')
            campaign = faults.KillCampaign(run_dir, KILL_RUN, kill_times=[2.5, -2.0, 3.0, 2.8],
                                           damage_after={2: ('state.npz', 'truncate')}, log=lambda s: None)
            events = campaign.run(timeout=600)
            killed = [e for e in events if e.get('killed')]
            self.assertGreaterEqual(len(killed), 3, events)
            self.assertTrue(any(e['during_checkpoint_write'] for e in killed), events)
            for e in killed:     # a kill loses at most one interval and a write in progress
                if e['checkpoint_written_by_this_start']:
                    self.assertLess(e['lost_s'], 0.3 + 1.0, e)
            resumed, skipped = campaign.resumed_units()
            self.assertGreaterEqual(len(resumed), len(killed))
            if any('damaged' in e for e in killed):
                self.assertTrue(skipped, 'the damaged unit was not reported')
            self.assertEqual(faults.compare_states(faults.final_state(run_dir), ref), '')


class TestStopSignal(unittest.TestCase):
    """SIGTERM (a shutdown) or Ctrl-C stops a run with a checkpoint at the next chunk of steps:
    exit code 143, a message saying how to continue, and the resumed run ends bit-identical."""

    def test_sigterm(self):
        import signal
        import time
        with tempfile.TemporaryDirectory() as tmp:
            ref = reference_end(tmp)
            run_dir = os.path.join(tmp, 'stopped')
            proc = subprocess.Popen(faults.pile_command(run_dir, KILL_RUN), stdout=subprocess.PIPE,
                                    stderr=subprocess.STDOUT, text=True, start_new_session=True)
            t0 = time.time()
            while not faults.units(run_dir) and proc.poll() is None and time.time() - t0 < 300:
                time.sleep(0.05)
            time.sleep(0.2)
            proc.send_signal(signal.SIGTERM)
            out, _ = proc.communicate(timeout=300)
            self.assertEqual(proc.returncode, 128 + signal.SIGTERM, out)
            self.assertIn('stopped by SIGTERM', out)
            self.assertIn('continue with --resume', out)
            with open(os.path.join(run_dir, 'run.json')) as f:
                p = json.load(f)
            self.assertEqual((p['stopped_by'], p['finished']), ('SIGTERM', False))
            stop_time = float(out.split('stopped by SIGTERM at t=')[1].split()[0])
            self.assertAlmostEqual(faults.units(run_dir)[-1][1]['meta']['time'], stop_time, delta=1e-4)
            proc = subprocess.run(faults.pile_command(run_dir, resume=True), capture_output=True, text=True, timeout=600)
            self.assertEqual(proc.returncode, 0, proc.stdout + proc.stderr)
            self.assertEqual(faults.compare_states(faults.final_state(run_dir), ref), '')


@unittest.skipUnless(os.geteuid() == 0, 'mounting a small tmpfs needs root (the set-up runs as root)')
class TestFullDisk(unittest.TestCase):
    """The disk fills mid-run: the run stops with a clear error, its last checkpoint intact;
    once space is back, it resumes and ends bit-identical to an uninterrupted run."""

    def test_full_disk(self):
        with tempfile.TemporaryDirectory() as tmp:
            ref = reference_end(tmp)
            mnt = os.path.join(tmp, 'small')
            os.makedirs(mnt)
            subprocess.run(['mount', '-t', 'tmpfs', '-o', 'size=4m', 'tmpfs', mnt], check=True)
            try:
                run_dir = os.path.join(mnt, 'run')
                result = faults.fill_disk_trial(run_dir, KILL_RUN, filler=os.path.join(mnt, 'filler'), timeout=600)
                self.assertEqual(result['returncode'], 2, result)
                self.assertIn('disk', result['error'])
                self.assertIn('full', result['error'])
                self.assertTrue(result['last_unit_valid'], result)
                self.assertEqual(faults.compare_states(faults.final_state(run_dir), ref), '')
            finally:
                subprocess.run(['umount', mnt], check=False)


class TestLayoutChange(unittest.TestCase):
    """A checkpoint written before a change to a serialized attribute of the engine resumes
    after it. The change: a second build of the plugin with a throwaway attribute
    (YADECD_THROWAWAY_ATTRIBUTE), run through its own YADE prefix (scripts/plugin_variant.py).
    YADE's archive of the checkpoint no longer loads there; the run resumes from state.npz."""

    def test_throwaway_attribute(self):
        from yadecd.testing import variant
        with tempfile.TemporaryDirectory() as tmp:
            build, prefix = os.path.join(tmp, 'build'), os.path.join(tmp, 'prefix')
            plugin = variant.build(build, throwaway=True)
            variant.make_prefix(prefix, plugin, os.path.join(REPO, 'py', 'yadecd'))
            env = dict(os.environ, YADECD_VARIANT_PREFIX=prefix)
            run_dir = os.path.join(tmp, 'run')
            pile.run(run_dir, stop_time=0.1, **TINY, **QUIET)            # the installed plugin writes it
            seq, unit, info = CheckpointStore(run_dir).latest()
            probe = os.path.join(tmp, 'probe.py')
            with open(probe, 'w') as f:
                f.write('from yade import O\nfrom yade.wrapper import ContactDynamicsIntegrator\n'
                        'print("throwaway", ContactDynamicsIntegrator().throwawayAttribute)\n'
                        'try:\n    O.load(%r)\n    print("archive loaded")\nexcept Exception as e:\n'
                        '    print("archive refused:", type(e).__name__)\n' % os.path.join(unit, 'scene.yade.gz'))
            yade = os.path.join(REPO, 'scripts', 'yade')
            out = subprocess.run([yade, '-n', '-x', probe], capture_output=True, text=True, env=env, timeout=300).stdout
            self.assertIn('throwaway 7', out)                  # the variant has the new attribute
            self.assertIn('archive refused', out)              # and YADE's archive no longer loads
            proc = subprocess.run(faults.pile_command(run_dir, resume=True), capture_output=True, text=True, env=env,
                                  timeout=600)
            self.assertEqual(proc.returncode, 0, proc.stdout + proc.stderr)
            self.assertIn('rebuilt from state.npz', proc.stdout)
            self.assertIn('not bit-identical', proc.stdout)
            ref_dir = os.path.join(tmp, 'straight')
            pile.run(ref_dir, **TINY, **QUIET)
            end, ref = faults.final_state(run_dir), faults.final_state(ref_dir)
            np.testing.assert_allclose(end['birth'], ref['birth'], rtol=0, atol=1e-13)
            self.assertLess(np.abs(end['pos'] - ref['pos']).max() / pile.DEFAULTS['d_min'], REBUILT_GAP)


if __name__ == '__main__':
    unittest.main()

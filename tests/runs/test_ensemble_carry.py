"""``pile_ensemble.py carry`` (yadecd.runs.ensemble.carry_ensemble) on a constructed ensemble
directory: every run with a checkpoint is carried, a run without one or not started is named as
such, a copy that is up to date is left alone, a new checkpoint, snapshot or the end of a run is
carried again, and one run that cannot be carried does not stop the others."""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

from repo_package import SCRIPTS  # first: this checkout's yadecd
from yadecd.runs import ensemble
from yadecd.runs.checkpoint import CheckpointStore

QUIET = dict(log=lambda s: None)
PARAMS = {'n_grains': 1000, 'rate': 200.0, 'dt': 5e-4, 'relax': 1.0}


def writer(content):
    def write(path):
        with open(path, 'wb') as f:
            f.write(content)
    return write


def checkpoint(run_dir, t, with_state=True):
    files = {'scene.yade.gz': writer(b'archive %g' % t)}
    if with_state:
        files['state.npz'] = writer(b'state %g' % t)
    CheckpointStore(run_dir).write(files, {'time': t, 'iter': int(1000 * t), 'wall_s': 10 * t})


def snapshot(run_dir, t):
    with open(os.path.join(run_dir, 'snap_%08.3f.npz' % t), 'wb') as f:
        f.write(b'snapshot %g' % t)


class TestCarryEnsemble(unittest.TestCase):

    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix='cd-carry-ens-')
        self.root = os.path.join(self.tmp, 'ens')
        self.dest = os.path.join(self.tmp, 'repo', 'runs')
        e = ensemble.Ensemble(self.root)
        e.plan([1000], [1, 2, 3, 4, 5], 1.0, ['--grain-shape', 'tetra'])
        self.names = sorted(e.runs())
        self.dirs = [os.path.join(self.root, n) for n in self.names]
        for d in self.dirs[:4]:
            os.makedirs(d)
            with open(os.path.join(d, 'run.json'), 'w') as f:
                json.dump(PARAMS, f)
        # s1 finished: its snapshots at 2.5, 5 and 6 s and a checkpoint before the end
        for t in (2.5, 5.0, 6.0):
            snapshot(self.dirs[0], t)
        checkpoint(self.dirs[0], 5.5)
        with open(os.path.join(self.dirs[0], 'run.json'), 'w') as f:
            json.dump(dict(PARAMS, wall_time_s=900.0, finished=True), f)
        # s2 running, two checkpoints; s3 started, no checkpoint yet; s4 a checkpoint without
        # state.npz (cannot be carried); s5 not started
        snapshot(self.dirs[1], 2.5)
        checkpoint(self.dirs[1], 2.0)
        checkpoint(self.dirs[1], 3.0)
        checkpoint(self.dirs[3], 1.0, with_state=False)

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def test_carry_and_again(self):
        out = ensemble.carry_ensemble(self.root, self.dest, **QUIET)
        s1, s2, s3, s4, s5 = self.names
        self.assertEqual(out[s1], 'carried')
        self.assertEqual(out[s2], 'carried')
        self.assertEqual(out[s3], 'no checkpoint')
        self.assertRegex(out[s4], r'^CheckpointError: .*holds no state\.npz')
        self.assertEqual(out[s5], 'not started')
        self.assertEqual(sorted(os.listdir(self.dest)), [s1, s2])
        self.assertTrue(ensemble.is_done(os.path.join(self.dest, s1)))
        self.assertFalse(ensemble.is_done(os.path.join(self.dest, s2)))
        self.assertEqual(CheckpointStore(os.path.join(self.dest, s2)).latest()[0], 2)
        self.assertEqual(sorted(n for n in os.listdir(os.path.join(self.dest, s1)) if n.startswith('snap_')),
                         ['snap_0002.500.npz', 'snap_0005.000.npz', 'snap_0006.000.npz'])

        # nothing new: nothing copied (the copies keep their inode)
        ino = os.stat(os.path.join(self.dest, s2, 'run.json')).st_ino
        out = ensemble.carry_ensemble(self.root, self.dest, **QUIET)
        self.assertEqual((out[s1], out[s2]), ('unchanged', 'unchanged'))
        self.assertEqual(os.stat(os.path.join(self.dest, s2, 'run.json')).st_ino, ino)

        # s2 writes a snapshot: carried again; then a checkpoint; then it finishes
        snapshot(self.dirs[1], 5.0)
        self.assertEqual(ensemble.carry_ensemble(self.root, self.dest, **QUIET)[s2], 'carried')
        self.assertIn('snap_0005.000.npz', os.listdir(os.path.join(self.dest, s2)))
        checkpoint(self.dirs[1], 5.5)
        self.assertEqual(ensemble.carry_ensemble(self.root, self.dest, **QUIET)[s2], 'carried')
        self.assertEqual(CheckpointStore(os.path.join(self.dest, s2)).latest()[0], 3)
        self.assertEqual(ensemble.carry_ensemble(self.root, self.dest, **QUIET)[s2], 'unchanged')
        with open(os.path.join(self.dirs[1], 'run.json'), 'w') as f:
            json.dump(dict(PARAMS, wall_time_s=700.0, finished=True), f)
        snapshot(self.dirs[1], 6.0)
        self.assertEqual(ensemble.carry_ensemble(self.root, self.dest, **QUIET)[s2], 'carried')
        self.assertTrue(ensemble.is_done(os.path.join(self.dest, s2)))

        # s3's first checkpoint: carried; the failing s4 still failing, and named
        checkpoint(self.dirs[2], 1.0)
        out = ensemble.carry_ensemble(self.root, self.dest, **QUIET)
        self.assertEqual((out[s1], out[s2], out[s3]), ('unchanged', 'unchanged', 'carried'))
        self.assertRegex(out[s4], '^CheckpointError')

    def test_refusals(self):
        with self.assertRaisesRegex(FileNotFoundError, 'no ensemble.json'):
            ensemble.carry_ensemble(self.dirs[0], self.dest, **QUIET)
        with self.assertRaisesRegex(ValueError, 'the ensemble itself'):
            ensemble.carry_ensemble(self.root, self.root + '/', **QUIET)

    def test_command_line(self):
        """``carry``: one pass (exit 1: one run could not be carried); ``--every`` returns once
        every run is done and carried; bad input names the culprit (argparse's exit 2)."""
        script = os.path.join(SCRIPTS, 'pile_ensemble.py')
        run = lambda *a: subprocess.run([sys.executable, script, 'carry'] + list(a),  # noqa: E731
                                        capture_output=True, text=True, timeout=120)
        r = run(self.root, self.dest)
        self.assertEqual(r.returncode, 1, r.stderr)
        self.assertRegex(r.stdout, r'carry of .*: 2 carried, 1 failed, 1 no checkpoint, 1 not started')
        # an ensemble of finished runs only: --every ends after the pass that carries them
        e = ensemble.Ensemble(self.root)
        for name in self.names[1:]:
            del e.data['runs'][name]
        e.save()
        r = run(self.root, self.dest, '--every', '0.01')
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertRegex(r.stdout, r'carry of .*: 1 unchanged$')
        for bad, culprit in (([self.tmp, self.dest], 'no ensemble.json'), (['--every', '0', self.root, self.dest], '--every'),
                             (['--snap-every', '-1', self.root, self.dest], '--snap-every')):
            r = run(*bad)
            self.assertEqual(r.returncode, 2)
            self.assertIn(culprit, r.stderr)


if __name__ == '__main__':
    unittest.main()

"""Carrying a pile run between machines (yadecd.runs.carry) on constructed run directories: which
snapshots go, the checkpoint reduced to state.npz, a damaged newest unit, a destination replaced
whole, refusals, the watch that carries a running pile again until it is done, and the stop
that ends a pile's process and carries its last checkpoint. The resume of a carried real run is tests/runs/test_runstate.py
TestResume.test_carried_resume."""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd.runs.carry import (FEED_END_DIR, carry, carry_if_changed, chosen_snapshots, is_done, processes_running, snapshot_time,
                               stop_and_carry, up_to_date, watch)
from yadecd.runs.checkpoint import CheckpointError, CheckpointStore

QUIET = dict(log=lambda s: None)


def snap(t):
    return 'snap_%08.3f.npz' % t


class TestSnapshotChoice(unittest.TestCase):

    def test_names(self):
        self.assertEqual(snapshot_time(snap(12.5)), 12.5)
        for other in ('run.json', 'snap_x.npz', 'snap_1.000.npz.tmp', 'vtk_0001.vtu'):
            self.assertIsNone(snapshot_time(other))

    def test_multiples_and_newest(self):
        names = [snap(t) for t in (2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 21.3)] + ['run.json', snap(2) + '.tmp']
        self.assertEqual(chosen_snapshots(names, 10), [snap(10), snap(20), snap(21.3)])
        self.assertEqual(chosen_snapshots(names, None)[-1], snap(21.3))
        self.assertEqual(len(chosen_snapshots(names, None)), 11)
        # times written with three decimals: 0.1 * k is found although 0.3 / 0.1 is not an integer in binary
        self.assertEqual(chosen_snapshots([snap(0.1 * k) for k in range(1, 7)], 0.3), [snap(0.3), snap(0.6)])
        self.assertEqual(chosen_snapshots([snap(20)], 10), [snap(20)])     # newest already a multiple: once
        self.assertEqual(chosen_snapshots([], 10), [])
        # the end of the feed is kept although it is not a multiple (a 5000-grain pile: 25 s at 200 grains/s)
        names = [snap(t) for t in (2, 10, 20, 24, 25, 26)]
        self.assertEqual(chosen_snapshots(names, 10, also=(25.0,)), [snap(10), snap(20), snap(25), snap(26)])
        self.assertEqual(chosen_snapshots(names, 10, also=(25.0004,)), [snap(10), snap(20), snap(26)])

    def test_bad_interval(self):
        for bad in (0, -2.0, float('nan')):
            with self.assertRaisesRegex(ValueError, 'snap_every'):
                chosen_snapshots([snap(1)], bad)


class RunDir(unittest.TestCase):
    """A constructed run directory: run.json, progress.csv, snapshots, two checkpoint units."""

    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix='cd-carry-')
        self.src = os.path.join(self.tmp, 'run')
        os.makedirs(self.src)
        with open(os.path.join(self.src, 'run.json'), 'w') as f:
            json.dump({'n_grains': 10, 'rate': 5.0}, f)      # the feed ends at 2 s
        with open(os.path.join(self.src, 'progress.csv'), 'w') as f:
            f.write('t,grains\n0.5,3\n')
        with open(os.path.join(self.src, 'segments.csv'), 'w') as f:
            f.write('started_unix,t_start_s\n1.0,0.0\n')
        for t in (1, 2, 3):
            with open(os.path.join(self.src, snap(t)), 'wb') as f:
                f.write(b'snapshot %d' % t)
        store = CheckpointStore(self.src)
        for t in (1.0, 2.0):
            store.write({'state.npz': self.writer(b'state %g' % t), 'scene.yade.gz': self.writer(b'archive')},
                        {'time': t, 'iter': int(100 * t), 'wall_s': 10 * t})
        self.dest = os.path.join(self.tmp, 'repo', 'runs', 'carried')

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    @staticmethod
    def writer(content):
        def write(path):
            with open(path, 'wb') as f:
                f.write(content)
        return write


class TestCarry(RunDir):

    def test_copy(self):
        record = carry(self.src, self.dest, snap_every=2, **QUIET)
        self.assertEqual(sorted(os.listdir(self.dest)),
                         sorted(['run.json', 'progress.csv', 'segments.csv', snap(2), snap(3), 'ckpt', 'CARRIED.json']))
        self.assertEqual((record['checkpoint'], record['time'], record['wall_s']), (2, 2.0, 20.0))
        self.assertEqual(record['snapshots_left_out'], [snap(1)])
        seq, unit, info = CheckpointStore(self.dest).latest()
        self.assertEqual(seq, 2)
        self.assertEqual(sorted(os.listdir(unit)), ['meta.json', 'state.npz'])
        self.assertEqual(list(info['files']), ['state.npz'])
        self.assertEqual(info['meta']['time'], 2.0)
        with open(os.path.join(unit, 'state.npz'), 'rb') as f:
            self.assertEqual(f.read(), b'state 2')

    def test_feed_end_kept(self):
        """The snapshot at the end of the feed (run.json: 10 grains at 5 per second, 2 s) is carried
        although it is not a multiple of snap_every; a run.json without a rate keeps only the multiples."""
        record = carry(self.src, self.dest, snap_every=3, **QUIET)
        self.assertEqual(record['snapshots'], [snap(2), snap(3)])
        with open(os.path.join(self.src, 'run.json'), 'w') as f:
            json.dump({'n_grains': 10}, f)
        record = carry(self.src, self.dest, snap_every=3, **QUIET)
        self.assertEqual(record['snapshots'], [snap(3)])

    def test_feed_end_copy_taken_along(self):
        """The run's copy of itself at the end of the feed goes with it, whole; a carry without
        snapshots takes none; a copy appearing in the source makes the carried one out of date."""
        record = carry(self.src, self.dest, snap_every=2, **QUIET)
        self.assertFalse(record['feed_end_copy'])
        kept = os.path.join(self.src, FEED_END_DIR)
        inner = carry(self.src, kept, snapshots=False, **QUIET)
        self.assertEqual(inner['snapshots'], [])
        self.assertFalse(inner['feed_end_copy'])
        self.assertEqual(sorted(os.listdir(kept)), ['CARRIED.json', 'ckpt', 'progress.csv', 'run.json', 'segments.csv'])
        self.assertFalse(up_to_date(self.src, self.dest, snap_every=2))
        record = carry(self.src, self.dest, snap_every=2, **QUIET)
        self.assertTrue(record['feed_end_copy'])
        self.assertTrue(up_to_date(self.src, self.dest, snap_every=2))
        copied = os.path.join(self.dest, FEED_END_DIR)
        self.assertEqual(CheckpointStore(copied).latest()[0], 2)
        with open(os.path.join(CheckpointStore(copied).latest()[1], 'state.npz'), 'rb') as f:
            self.assertEqual(f.read(), b'state 2')
        # carried on again from the copy (back to a working directory), it is still there
        back = os.path.join(self.tmp, 'work')
        self.assertTrue(carry(self.dest, back, **QUIET)['feed_end_copy'])
        self.assertEqual(CheckpointStore(os.path.join(back, FEED_END_DIR)).latest()[0], 2)

    def test_damaged_newest_unit(self):
        """The source's newest unit is truncated: the one before it is carried, and the log says why."""
        with open(os.path.join(self.src, 'ckpt', '000002', 'state.npz'), 'wb') as f:
            f.write(b'sta')
        lines = []
        record = carry(self.src, self.dest, log=lines.append)
        self.assertEqual(record['checkpoint'], 1)
        self.assertIn('checkpoint 2 skipped', '\n'.join(lines))

    def test_destination_replaced_whole(self):
        os.makedirs(self.dest)
        with open(os.path.join(self.dest, snap(9)), 'w') as f:
            f.write('a snapshot of an older carry')
        carry(self.src, self.dest, **QUIET)
        self.assertNotIn(snap(9), os.listdir(self.dest))
        self.assertFalse(any(n.startswith('carried.carry-') for n in os.listdir(os.path.dirname(self.dest))))
        # carrying the copy again (back to a working directory) gives the same files
        back = os.path.join(self.tmp, 'work')
        carry(self.dest, back, **QUIET)
        self.assertEqual(sorted(os.listdir(back)), sorted(os.listdir(self.dest)))

    def test_refusals(self):
        with self.assertRaisesRegex(FileNotFoundError, 'no run.json'):
            carry(self.tmp, self.dest, **QUIET)
        with self.assertRaisesRegex(ValueError, 'same directory'):
            carry(self.src, self.src + '/', **QUIET)
        shutil.rmtree(os.path.join(self.src, 'ckpt'))
        with self.assertRaisesRegex(CheckpointError, 'no checkpoint yet'):
            carry(self.src, self.dest, **QUIET)
        self.assertFalse(os.path.exists(self.dest))

    def test_command_line(self):
        """scripts/pile_carry.py: carries, and names the culprit on bad input (exit status 1)."""
        script = os.path.join(SCRIPTS, 'pile_carry.py')
        python = '/usr/bin/python3' if os.path.exists('/usr/bin/python3') else sys.executable
        ok = subprocess.run([python, script, self.src, self.dest, '--snap-every', '2'], capture_output=True, text=True)
        self.assertEqual(ok.returncode, 0, ok.stderr)
        self.assertIn('checkpoint 2 at t=2.000 s, 2 snapshots (1 left out), without scene.yade.gz', ok.stdout)
        bad = subprocess.run([python, script, self.tmp, self.dest], capture_output=True, text=True)
        self.assertEqual(bad.returncode, 1)
        self.assertIn('no run.json', bad.stderr)


class TestWatch(RunDir):
    """``watch`` (``pile_carry.py --every``) on the constructed run while it goes on: each round
    carries only what moved on, a round that cannot carry is retried, and the watch ends once the
    finished run is carried."""

    def finish(self):
        with open(os.path.join(self.src, 'snap_0004.000.npz'), 'wb') as f:
            f.write(b'snapshot 4')
        with open(os.path.join(self.src, 'run.json'), 'w') as f:
            json.dump({'n_grains': 10, 'rate': 5.0, 'wall_time_s': 40.0, 'finished': True}, f)

    def test_rounds(self):
        """Round 1 carries, round 2 finds nothing new, round 3 a new checkpoint, round 4 nothing,
        round 5 the end: five rounds, four sleeps of the given minutes."""
        events = {2: lambda: None,
                  3: lambda: CheckpointStore(self.src).write({'state.npz': self.writer(b'state 3')},
                                                             {'time': 3.0, 'iter': 300, 'wall_s': 30.0}),
                  5: self.finish}
        lines, sleeps = [], []

        def sleep(seconds):
            sleeps.append(seconds)
            events.get(len(sleeps) + 1, lambda: None)()

        rounds = watch(self.src, self.dest, 0.5, snap_every=2, log=lines.append, sleep=sleep)
        self.assertEqual(rounds, 5)
        self.assertEqual(sleeps, [30.0] * 4)
        outcomes = [ln.split(': ')[-1] for ln in lines if ' carry of ' in ln]
        self.assertEqual(outcomes, ['carried', 'unchanged', 'carried', 'unchanged', 'carried'])
        self.assertTrue(is_done(self.dest))
        self.assertEqual(CheckpointStore(self.dest).latest()[0], 3)
        self.assertIn(snap(4), os.listdir(self.dest))

    def test_unchanged_leaves_the_copy(self):
        self.assertEqual(carry_if_changed(self.src, self.dest, **QUIET), 'carried')
        ino = os.stat(os.path.join(self.dest, 'run.json')).st_ino
        self.assertTrue(up_to_date(self.src, self.dest))
        self.assertEqual(carry_if_changed(self.src, self.dest, **QUIET), 'unchanged')
        self.assertEqual(os.stat(os.path.join(self.dest, 'run.json')).st_ino, ino)
        # a copy made with another snapshot choice is not up to date for this one
        self.assertFalse(up_to_date(self.src, self.dest, snap_every=2))

    def test_failed_round_retried(self):
        """No checkpoint yet at the first round: named, not fatal; carried once one is written."""
        shutil.rmtree(os.path.join(self.src, 'ckpt'))
        lines = []

        def sleep(seconds):
            if len(lines) == 1:
                CheckpointStore(self.src).write({'state.npz': self.writer(b'state 1')},
                                                {'time': 1.0, 'iter': 100, 'wall_s': 10.0})
            else:
                self.finish()

        rounds = watch(self.src, self.dest, 1, log=lambda m: lines.append(m) if ' carry of ' in m else None, sleep=sleep)
        self.assertEqual(rounds, 3)
        self.assertRegex(lines[0], r'not carried \(CheckpointError: .*no checkpoint yet')
        self.assertTrue(lines[1].endswith(': carried') and lines[2].endswith(': carried'))
        for bad in (0, -1, None, float('nan')):
            with self.assertRaisesRegex(ValueError, 'every must be a positive'):
                watch(self.src, self.dest, bad, **QUIET)

    def test_every_command_line(self):
        """``pile_carry.py --every``: on a finished run one round carries it and the command ends;
        bad intervals are named (argparse's exit 2)."""
        self.finish()
        script = os.path.join(SCRIPTS, 'pile_carry.py')
        python = '/usr/bin/python3' if os.path.exists('/usr/bin/python3') else sys.executable
        r = subprocess.run([python, script, self.src, self.dest, '--every', '0.01'], capture_output=True, text=True, timeout=60)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertRegex(r.stdout, r'carry of .*run: carried$')
        self.assertTrue(is_done(self.dest))
        for bad, culprit in ((['--every', '0'], '--every'), (['--snap-every', '-1'], '--snap-every')):
            r = subprocess.run([python, script, self.src, self.dest] + bad, capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 2)
            self.assertIn(culprit, r.stderr)


# A stand-in for pile.py: runs "--out RUN" until SIGTERM, then writes one more checkpoint (as
# the pile does on the signal) and exits; it says "ready" once its handler is in place.
FAKE_PILE = """
import signal, sys, time
sys.path.insert(0, sys.argv[1])
from yadecd.runs.checkpoint import CheckpointStore
args = sys.argv[2:]
run = args[args.index('--out') + 1] if '--out' in args else [a[6:] for a in args if a.startswith('--out=')][0]
def stop(signum, frame):
    def write(path):
        with open(path, 'wb') as f:
            f.write(b'state at the signal')
    CheckpointStore(run).write({'state.npz': write}, {'time': 2.5, 'iter': 250, 'wall_s': 25.0})
    sys.exit(0)
signal.signal(signal.SIGTERM, stop)
print('ready', flush=True)
time.sleep(120)
"""


class TestStop(RunDir):
    """``stop_and_carry`` (``pile_carry.py --stop``) on a stand-in pile process."""

    def start(self, out_arg):
        from repo_package import REPO as repo
        p = subprocess.Popen([sys.executable, '-c', FAKE_PILE, os.path.join(repo, 'py')] + out_arg,
                             cwd=self.tmp, stdout=subprocess.PIPE, text=True)
        self.assertEqual(p.stdout.readline().strip(), 'ready')
        self.addCleanup(p.kill)
        return p

    def test_stop_then_carry(self):
        """The process running the run (given --out relative to its own directory) is found,
        stopped, and its last checkpoint carried; another run's process is left alone."""
        other = os.path.join(self.tmp, 'other')
        os.makedirs(other)
        p = self.start(['--out', 'run'])
        q = self.start(['--out=%s' % other])
        self.assertEqual(processes_running(self.src), [p.pid])
        self.assertEqual(processes_running(other), [q.pid])
        lines = []
        record = stop_and_carry(self.src, self.dest, log=lines.append, timeout=60)
        self.assertEqual(p.wait(timeout=10), 0)
        self.assertEqual((record['checkpoint'], record['time']), (3, 2.5))
        self.assertIn('SIGTERM sent to process %d' % p.pid, '\n'.join(lines))
        self.assertIsNone(q.poll())                       # the other run's pile still runs
        self.assertEqual(processes_running(self.src), [])
        # nothing runs it any more: carried as it is
        lines = []
        stop_and_carry(self.src, self.dest, log=lines.append)
        self.assertIn('no process runs', lines[0])

    def test_a_pile_that_does_not_stop(self):
        """A process that ignores SIGTERM: named after the timeout, nothing carried."""
        ignoring = "import signal, sys, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); print('ready', flush=True); time.sleep(60)"
        p = subprocess.Popen([sys.executable, '-c', ignoring, '--out', self.src], stdout=subprocess.PIPE, text=True)
        self.addCleanup(p.kill)
        self.assertEqual(p.stdout.readline().strip(), 'ready')
        with self.assertRaisesRegex(RuntimeError, r'still run .* after SIGTERM; nothing carried'):
            stop_and_carry(self.src, self.dest, timeout=1, log=lambda m: None)
        self.assertFalse(os.path.exists(self.dest))

    def test_command_line(self):
        script = os.path.join(SCRIPTS, 'pile_carry.py')
        python = '/usr/bin/python3' if os.path.exists('/usr/bin/python3') else sys.executable
        p = self.start(['--out', self.src])
        r = subprocess.run([python, script, self.src, self.dest, '--stop', '--snap-every', '2'], capture_output=True, text=True, timeout=60)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn('SIGTERM sent to process %d' % p.pid, r.stdout)
        self.assertIn('checkpoint 3 at t=2.500 s', r.stdout)
        for bad, culprit in ((['--stop', '--every', '5'], 'do not go together'), (['--stop', '--timeout', '0'], '--timeout')):
            r = subprocess.run([python, script, self.src, self.dest] + bad, capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 2)
            self.assertIn(culprit, r.stderr)


if __name__ == '__main__':
    unittest.main()

"""The ensemble driver on Dask's distributed engine (yadecd.runs.ensemble, scripts/pile_ensemble.py):
a local cluster of one worker runs two small piles; the worker is killed (SIGKILL) in the middle
of the first pile, after a checkpoint. YADE, losing its parent, gets SIGTERM and stops at a
checkpoint; Dask runs the task again on the restarted worker, which resumes the pile; both piles
finish, and the killed one ends bit for bit where the same pile run without interruption ends."""
import json
import os
import signal
import subprocess
import tempfile
import time
import unittest

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd.runs import ensemble
from yadecd.testing import faults

PILE = ['--checkpoint-every', '0.5']          # pile.py options of every run (the plan's)
SIZE, RELAX = 40, 0.3


def yade_children(root):
    """pid → parent pid of the YADE processes running a pile of the ensemble in ``root``."""
    out = {}
    for pid in os.listdir('/proc'):
        if not pid.isdigit():
            continue
        try:
            with open('/proc/%s/cmdline' % pid, 'rb') as f:
                cmd = f.read().split(b'\0')
            with open('/proc/%s/stat' % pid) as f:
                ppid = int(f.read().rsplit(')', 1)[1].split()[1])
        except OSError:
            continue
        if any(root.encode() in c for c in cmd) and any(c.endswith(b'pile.py') for c in cmd) and b'setpriv' not in cmd[0]:
            out[int(pid)] = ppid
    return out


class TestWorkerKilledMidPile(unittest.TestCase):

    def test_killed_worker_resumes(self):
        with tempfile.TemporaryDirectory() as d:
            root = os.path.join(d, 'ens')
            cmd = ['/usr/bin/python3', os.path.join(SCRIPTS, 'pile_ensemble.py'), 'run', root, '--sizes', str(SIZE),
                   '--seeds', '1-2', '--relax', str(RELAX), '--jobs', '1', '--'] + PILE
            driver = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            run1 = os.path.join(root, 'n%d_s1' % SIZE)
            killed, deadline = None, time.time() + 300
            while killed is None and time.time() < deadline and driver.poll() is None:
                time.sleep(0.2)
                units = faults.units(run1) if os.path.isdir(os.path.join(run1, 'ckpt')) else []
                kids = yade_children(run1)
                if len(units) >= 2 and kids:
                    pid, worker = next(iter(kids.items()))
                    os.kill(worker, signal.SIGKILL)          # the Dask worker, not YADE
                    killed = (pid, worker)
            out, _ = driver.communicate(timeout=900)
            self.assertIsNotNone(killed, 'the first pile ended before a worker could be killed:\n' + out)
            self.assertEqual(driver.returncode, 0, out)
            with open(os.path.join(root, 'ensemble.json')) as f:
                status = json.load(f)['runs']
            self.assertEqual({k: v['state'] for k, v in status.items()}, {'n%d_s1' % SIZE: 'done', 'n%d_s2' % SIZE: 'done'})
            with open(os.path.join(run1, 'log.txt')) as f:
                log = f.read()
            self.assertEqual(log.count('=== '), 2, log)          # started, then resumed by the retried task
            self.assertIn('resume\n', log)
            self.assertIn('SIGTERM', log)                        # YADE stopped on its parent's death, at a checkpoint
            # the same pile without interruption, run directly
            ref = os.path.join(d, 'ref')
            subprocess.run(faults.pile_command(ref, ['--n-grains', str(SIZE), '--seed', '1', '--relax', str(RELAX),
                                                     '--epochs', ensemble.epochs(SIZE, RELAX)] + PILE),
                           check=True, capture_output=True, timeout=600)
            self.assertEqual(faults.compare_states(faults.final_state(run1), faults.final_state(ref)), '')


if __name__ == '__main__':
    unittest.main()

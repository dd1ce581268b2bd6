"""Fault injection for pile runs: kill -9 at random moments (some during checkpoint writes),
damaged checkpoints, a full disk; every run is resumed and its end compared bit for bit with an
uninterrupted run. Used by ``scripts/fault_injection.py`` (the full suite) and
``tests/runs/test_runstate.py`` (a fast version).

Pure Python and numpy (no YADE): pile runs are ``scripts/pile.py`` subprocesses under
``scripts/yade``, exactly as a user starts them.
"""
import glob
import json
import os
import signal
import subprocess
import time

import numpy as np

from ..runs import checkpoint as ck

REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..'))  # the checkout


def pile_command(run_dir, options=(), resume=False, repo=REPO):
    """The command line of one pile run (one thread)."""
    cmd = [os.path.join(repo, 'scripts', 'yade'), '-j1', '-n', '-x', os.path.join(repo, 'scripts', 'pile.py'),
           '--out', run_dir]
    return cmd + (['--resume'] if resume else list(options))


def final_state(run_dir):
    """Arrays of the run's last snapshot (positions, velocities, contacts, forces...)."""
    snaps = sorted(glob.glob(os.path.join(run_dir, 'snap_*.npz')))
    if not snaps:
        raise FileNotFoundError('no snapshot in %s' % run_dir)
    with np.load(snaps[-1]) as z:
        return {k: z[k] for k in z.files}


def _contacts_sorted(s):
    """A snapshot with its contact arrays in (id1, id2, contact point) order: YADE's interaction
    container does not keep one order through a save and load, and the order carries no physics
    (two clumps may touch at several points: the point breaks the tie)."""
    if 'c_id1' not in s or not len(s['c_id1']):
        return s
    point = np.asarray(s['c_point']).reshape(-1, 3)
    order = np.lexsort((point[:, 2], point[:, 1], point[:, 0], s['c_id2'], s['c_id1']))
    return {k: (v[order] if k.startswith('c_') else v) for k, v in s.items()}


def compare_states(a, b):
    """'' when two snapshots are equal bit for bit (contacts compared in (id1, id2) order), else
    the first difference."""
    a, b = _contacts_sorted(a), _contacts_sorted(b)
    if sorted(a) != sorted(b):
        return 'different arrays: %s vs %s' % (sorted(a), sorted(b))
    for k in sorted(a):
        if a[k].shape != b[k].shape:
            return '%s: shape %s vs %s' % (k, a[k].shape, b[k].shape)
        if not np.array_equal(a[k], b[k]):
            diff = np.abs(a[k].astype(float) - b[k].astype(float)).max() if a[k].dtype.kind in 'fiu' else '?'
            return '%s differs (max |difference| %s)' % (k, diff)
    return ''


def units(run_dir):
    """Verified-looking checkpoint units of a run: list of (seq, meta.json dict), oldest first."""
    root = os.path.join(run_dir, 'ckpt')
    out = []
    for name in sorted(os.listdir(root)) if os.path.isdir(root) else []:
        if name.isdigit():
            try:
                with open(os.path.join(root, name, 'meta.json')) as f:
                    out.append((int(name), json.load(f)))
            except (OSError, ValueError):
                pass
    return out


def writing_checkpoint(run_dir):
    """True while a checkpoint unit is being written (its temporary directory exists)."""
    return bool(glob.glob(os.path.join(run_dir, 'ckpt', '*.tmp')))


def damage(path, how, rng):
    """Damage a file: 'truncate' it to a random fraction, or 'flip' bytes in its middle."""
    size = os.path.getsize(path)
    if how == 'truncate':
        with open(path, 'r+b') as f:
            f.truncate(int(size * rng.uniform(0.1, 0.9)))
    elif how == 'flip':
        with open(path, 'r+b') as f:
            for _ in range(8):
                f.seek(int(rng.integers(0, max(1, size))))
                byte = f.read(1)
                f.seek(-len(byte), 1)
                f.write(bytes([(byte[0] if byte else 0) ^ 0xFF]))
    else:
        raise ValueError('damage: how must be truncate or flip, not %r' % how)


class KillCampaign:
    """Runs one pile to its end through kills and resumes, recording every fault.

    :param run_dir: the run directory (must not exist yet).
    :param options: pile.py options of the run (``--n-grains`` ...; include ``--checkpoint-every``).
    :param kill_times: wall-clock delays [s] after each start at which the run is killed; a
        negative delay means "at the next checkpoint write after |delay| s".
    :param damage_after: {kill index: (file name in the newest unit, 'truncate' | 'flip')}: damage
        the newest checkpoint after that kill, before resuming.
    """

    def __init__(self, run_dir, options, kill_times, damage_after=None, rng=None, env=None, log=print):
        self.run_dir, self.options, self.kill_times = run_dir, list(options), list(kill_times)
        self.damage_after = damage_after or {}
        self.rng = rng or np.random.default_rng(0)
        self.env, self.log = env, log
        self.events = []

    def _start(self, resume):
        logf = open(os.path.join(os.path.dirname(self.run_dir), os.path.basename(self.run_dir) + '.log'), 'a')
        proc = subprocess.Popen(pile_command(self.run_dir, self.options, resume), stdout=logf, stderr=subprocess.STDOUT,
                                env=self.env, start_new_session=True)
        return proc, logf

    def run(self, timeout=3600):
        """Run with every kill, then to the end; returns the list of fault records."""
        resume = False
        for k, delay in enumerate(self.kill_times):
            before = units(self.run_dir)
            proc, logf = self._start(resume)
            t0 = time.time()
            during_write = delay < 0
            while proc.poll() is None and time.time() - t0 < abs(delay):
                time.sleep(0.01)
            if during_write:
                while proc.poll() is None and not writing_checkpoint(self.run_dir) and time.time() - t0 < timeout:
                    time.sleep(0.0005)
            if proc.poll() is not None:          # it finished (or failed) before the kill
                logf.close()
                self.events.append(dict(kill=k, killed=False, returncode=proc.returncode))
                if proc.returncode != 0:
                    raise RuntimeError('pile run failed with exit %d before kill %d (see %s.log)'
                                       % (proc.returncode, k, self.run_dir))
                return self.events
            in_write = writing_checkpoint(self.run_dir)
            os.killpg(proc.pid, signal.SIGKILL)
            t_kill = time.time()
            proc.wait()
            logf.close()
            after = units(self.run_dir)
            newest = after[-1][1] if after else None
            # work lost: computing time of this start after its newest verified checkpoint (or,
            # when it wrote none, all of this start, YADE's start-up included)
            own = newest is not None and newest['written_unix'] > t0
            event = dict(kill=k, killed=True, wall_after_start_s=t_kill - t0, during_checkpoint_write=in_write,
                         units_before=len(before), units_after=len(after),
                         newest_unit_time_s=newest['meta']['time'] if newest else None,
                         checkpoint_written_by_this_start=own,
                         lost_s=t_kill - (newest['written_unix'] if own else t0))
            if k in self.damage_after and after:
                name, how = self.damage_after[k]
                seq = after[-1][0]
                damage(os.path.join(self.run_dir, 'ckpt', '%06d' % seq, name), how, self.rng)
                event['damaged'] = '%s of unit %d (%s)' % (name, seq, how)
                event['expect_unit'] = after[-2][0] if len(after) >= 2 else None
            self.events.append(event)
            self.log('faults: kill %d at %.1f s after its start%s; lost %.2f s%s'
                     % (k + 1, event['wall_after_start_s'], ' (during a checkpoint write)' if in_write else '',
                        event['lost_s'], '; damaged ' + event['damaged'] if 'damaged' in event else ''))
            resume = os.path.exists(os.path.join(self.run_dir, 'run.json'))
        proc, logf = self._start(resume)
        rc = proc.wait(timeout=timeout)
        logf.close()
        self.events.append(dict(kill=len(self.kill_times), killed=False, returncode=rc))
        if rc != 0:
            raise RuntimeError('pile run failed with exit %d after the kills (see %s.log)' % (rc, self.run_dir))
        return self.events

    def resumed_units(self):
        """From the run's log: the checkpoint each resume started from, and the units skipped."""
        path = os.path.join(os.path.dirname(self.run_dir), os.path.basename(self.run_dir) + '.log')
        with open(path) as f:
            text = f.read()
        resumed = [ln for ln in text.splitlines() if ln.startswith('resumed ')]
        skipped = [ln for ln in text.splitlines() if 'skipped' in ln and ln.startswith('checkpoint:')]
        return resumed, skipped


def fill(path, chunk=1 << 16):
    """Write zeros to ``path`` until the disk is full; returns the bytes written."""
    written = 0
    block = b'\0' * chunk
    with open(path, 'wb', buffering=0) as f:
        while True:
            try:
                f.write(block)
            except OSError:
                return written
            written += chunk


def fill_disk_trial(run_dir, options, filler, log_path=None, timeout=600, env=None):
    """A run whose disk fills up: started, the disk filled as soon as its first checkpoint exists,
    its exit awaited (it must fail with a clear error), its newest checkpoint checked, the space
    given back and the run resumed to its end. Returns a record of what happened."""
    log_path = log_path or os.path.join(os.path.dirname(os.path.dirname(filler)) or '.', 'fill_disk.log')
    with open(log_path, 'w') as logf:
        proc = subprocess.Popen(pile_command(run_dir, options), stdout=logf, stderr=subprocess.STDOUT, env=env,
                                start_new_session=True)
        t0 = time.time()
        while proc.poll() is None and not units(run_dir) and time.time() - t0 < timeout:
            time.sleep(0.01)
        filled = fill(filler)
        t_full = time.time()
        rc = proc.wait(timeout=timeout)
    with open(log_path) as f:
        text = f.read()
    errors = [ln for ln in text.splitlines() if 'error' in ln.lower()]
    record = dict(returncode=rc, filled_bytes=filled, seconds_to_failure=time.time() - t_full,
                  error=errors[-1] if errors else '', units_at_failure=len(units(run_dir)))
    try:
        latest = ck.CheckpointStore(run_dir).latest()
        record['last_unit_valid'] = latest is not None
        record['last_unit_time_s'] = latest[2]['meta']['time'] if latest else None
    except ck.CheckpointError as e:
        record['last_unit_valid'] = False
        record['last_unit_error'] = str(e)
    os.remove(filler)
    with open(log_path, 'a') as logf:
        proc = subprocess.run(pile_command(run_dir, resume=True), stdout=logf, stderr=subprocess.STDOUT, env=env,
                              timeout=timeout)
    record['resume_returncode'] = proc.returncode
    return record

"""Carry a pile run between machines: its portable part, small enough to commit.

A long pile (the 14 000-grain one takes many hours) outlives the machine it started on when the
machine is reset between sessions. :func:`carry` copies what a resume needs and what the
analyses read, and nothing machine-specific:

* ``run.json`` (the parameters), ``progress.csv`` (with the run's wall time so far) and
  ``segments.csv`` (where and when each segment ran, :mod:`yadecd.runs.cost`);
* the snapshots ``snap_<t>.npz`` at multiples of ``snap_every`` seconds (all when ``None``),
  always with the newest one and the one at the end of the feed (``n_grains / rate`` in run.json:
  the state the deposit analyses read);
* the newest *valid* checkpoint unit, reduced to its ``state.npz`` (the layout-independent
  state, :mod:`yadecd.runs.runstate`); YADE's archive ``scene.yade.gz`` is left out: it is the larger
  file and only loads into the very plugin build that wrote it.

The copy is a run directory: ``pile.py --out DEST --resume`` continues it through the state.npz
path (the same physical state; not bit-identical, as after any plugin change). Carrying the copy
back to a working directory is the same operation. The destination is written under a
temporary name and swapped in whole, so an interrupted carry leaves the previous copy intact;
``CARRIED.json`` in it records the source, the checkpoint, and what was left out.

A run carried while it goes on is carried again only when it has moved on
(:func:`carry_if_changed`), and :func:`watch` does so every few minutes until the run is done:
what ``pile_carry.py --every`` runs beside a long pile. :func:`stop_and_carry` ends a session's
pile: SIGTERM to the process that runs it (the pile checkpoints and stops), then the carry
(``pile_carry.py --stop``).

Pure Python (no YADE, no numpy): it runs under any interpreter.
"""
import json
import os
import shutil
import signal
import time

from .checkpoint import POINTER, CheckpointError, CheckpointStore, sha256

RUN_FILES = ('run.json', 'progress.csv', 'segments.csv')
SNAP_PREFIX, SNAP_SUFFIX = 'snap_', '.npz'
RECORD = 'CARRIED.json'
#: A run's carried copy of itself at the end of the feed (run.json, progress, one checkpoint reduced
#: to state.npz), which the runner keeps when the pile relaxes after the feed: the run's own
#: checkpoints are pruned to the newest two, and the forces at the end of the feed re-solved
#: tightly (``pile_tolerance.py RUN/at_feed_end``) need a checkpoint there (a snapshot holds no
#: impulses). :func:`carry` takes it along.
FEED_END_DIR = 'at_feed_end'


def snapshot_time(name):
    """Time [s] in a snapshot's file name ``snap_<t>.npz``, or None for any other name."""
    if not (name.startswith(SNAP_PREFIX) and name.endswith(SNAP_SUFFIX)):
        return None
    try:
        return float(name[len(SNAP_PREFIX):-len(SNAP_SUFFIX)])
    except ValueError:
        return None


def chosen_snapshots(names, snap_every=None, also=(), tol=1e-6):
    """The snapshot file names to carry, in time order: those at multiples of ``snap_every`` [s]
    (all when None), those at the times in ``also`` [s] and the newest one."""
    snaps = sorted((t, n) for n, t in ((n, snapshot_time(n)) for n in names) if t is not None)
    if snap_every is None:
        return [n for _, n in snaps]
    if not snap_every > 0:
        raise ValueError('snap_every must be a positive time in seconds (got %r)' % (snap_every,))
    keep = [n for t, n in snaps if abs(t / snap_every - round(t / snap_every)) * snap_every < tol
            or any(abs(t - a) < tol for a in also) or n == snaps[-1][1]]
    return keep


def feed_end(run):
    """End of the feed [s] of a pile run's parameters (``n_grains / rate``), or None when run.json
    does not give both."""
    try:
        return float(run['n_grains']) / float(run['rate'])
    except (KeyError, TypeError, ValueError, ZeroDivisionError):
        return None


def snapshots_to_carry(src, snap_every=None):
    """The snapshot file names :func:`carry` takes from the run directory ``src``
    (:func:`chosen_snapshots` with the end of the feed of its run.json kept)."""
    with open(os.path.join(src, 'run.json')) as f:
        end = feed_end(json.load(f))
    return chosen_snapshots(os.listdir(src), snap_every, also=() if end is None else (end,))


def carry(src, dest, snap_every=None, log=print, snapshots=True):
    """Copy the portable part of the pile run in ``src`` to ``dest`` (replaced whole if it exists):
    run.json, progress, the newest valid checkpoint reduced to state.npz, the snapshots
    :func:`snapshots_to_carry` chooses (none when ``snapshots`` is False) and the run's copy of
    itself at the end of the feed (:data:`FEED_END_DIR`) when it has one.

    :returns: the record written to ``dest/CARRIED.json``.
    :raises FileNotFoundError: ``src`` holds no run.json.
    :raises CheckpointError: ``src`` has checkpoints but none is valid, or none at all (nothing
        to resume from: carry the run after its first checkpoint).
    """
    src, dest = os.path.abspath(src), os.path.abspath(dest)
    if src == dest:
        raise ValueError('carry: source and destination are the same directory (%s)' % src)
    if not os.path.exists(os.path.join(src, 'run.json')):
        raise FileNotFoundError('carry: %s holds no pile run (no run.json)' % src)
    store = CheckpointStore(src)
    latest = store.latest()
    for m in store.messages:
        log('carry: ' + m)
    if latest is None:
        raise CheckpointError('carry: %s has no checkpoint yet; nothing would resume from the copy' % src)
    seq, unit, info = latest
    if 'state.npz' not in info.get('files', {}):
        raise CheckpointError('carry: checkpoint %d of %s holds no state.npz' % (seq, src))

    tmp = dest + '.carry-tmp'
    shutil.rmtree(tmp, ignore_errors=True)
    os.makedirs(tmp)
    for name in RUN_FILES:
        if os.path.exists(os.path.join(src, name)):
            shutil.copy2(os.path.join(src, name), os.path.join(tmp, name))
    snaps = snapshots_to_carry(src, snap_every) if snapshots else []
    for name in snaps:
        shutil.copy2(os.path.join(src, name), os.path.join(tmp, name))

    # the checkpoint unit, reduced to state.npz; its digest is checked again after the copy
    unit_dest = os.path.join(tmp, 'ckpt', '%06d' % seq)
    os.makedirs(unit_dest)
    shutil.copy2(os.path.join(unit, 'state.npz'), os.path.join(unit_dest, 'state.npz'))
    if sha256(os.path.join(unit_dest, 'state.npz')) != info['files']['state.npz']:
        shutil.rmtree(tmp, ignore_errors=True)
        raise CheckpointError('carry: state.npz of checkpoint %d changed while it was copied' % seq)
    dropped = sorted(set(info['files']) - {'state.npz'})
    reduced = dict(info, files={'state.npz': info['files']['state.npz']})
    with open(os.path.join(unit_dest, 'meta.json'), 'w') as f:
        json.dump(reduced, f, indent=1, sort_keys=True)
    with open(os.path.join(tmp, 'ckpt', POINTER), 'w') as f:
        json.dump({'current': seq, 'previous': None}, f)

    kept = os.path.join(src, FEED_END_DIR)
    with_feed_end = os.path.isdir(kept) and kept != dest
    if with_feed_end:
        shutil.copytree(kept, os.path.join(tmp, FEED_END_DIR))

    all_snaps = [n for n in os.listdir(src) if snapshot_time(n) is not None]
    record = {'feed_end_copy': with_feed_end, 'source': src, 'carried_unix': time.time(), 'checkpoint': seq,
              'time': info['meta'].get('time'), 'iter': info['meta'].get('iter'),
              'wall_s': info['meta'].get('wall_s'), 'snapshots': snaps,
              'snapshots_left_out': sorted(set(all_snaps) - set(snaps)), 'checkpoint_files_left_out': dropped}
    with open(os.path.join(tmp, RECORD), 'w') as f:
        json.dump(record, f, indent=1)
    copied = CheckpointStore(tmp).latest()
    if copied is None or copied[0] != seq:
        shutil.rmtree(tmp, ignore_errors=True)
        raise CheckpointError('carry: the copied checkpoint does not verify in %s' % tmp)

    old = dest + '.carry-old'
    shutil.rmtree(old, ignore_errors=True)
    if os.path.exists(dest):
        os.replace(dest, old)
    os.replace(tmp, dest)
    shutil.rmtree(old, ignore_errors=True)
    when = '%.3f' % record['time'] if isinstance(record['time'], (int, float)) else '?'
    log('carried %s -> %s: checkpoint %d at t=%s s, %d snapshots (%d left out)%s%s'
        % (src, dest, seq, when, len(snaps), len(record['snapshots_left_out']),
           ', without ' + ', '.join(dropped) if dropped else '', ', with its copy at the end of the feed' if with_feed_end else ''))
    return record


def is_done(run_dir):
    """True when the pile run in ``run_dir`` finished: its run.json has ``wall_time_s`` and
    ``finished`` (written after its last step) and a snapshot exists."""
    path = os.path.join(run_dir, 'run.json')
    if not os.path.exists(path):
        return False
    try:
        with open(path) as f:
            p = json.load(f)
    except (OSError, ValueError):
        return False
    return 'wall_time_s' in p and p.get('finished', True) and any(n.startswith(SNAP_PREFIX) for n in os.listdir(run_dir))


def up_to_date(src, dest, snap_every=None):
    """True when ``dest`` is a carried copy of ``src`` (its CARRIED.json) that holds the newest
    valid checkpoint of ``src``, the snapshots :func:`carry` would take now, ``src``'s finished
    state and its copy at the end of the feed if it has one: carrying again would copy the same things."""
    try:
        with open(os.path.join(dest, RECORD)) as f:
            before = json.load(f)
    except (OSError, ValueError):
        return False
    latest = CheckpointStore(src).latest()
    return (latest is not None and before.get('checkpoint') == latest[0] and is_done(dest) == is_done(src)
            and before.get('snapshots') == snapshots_to_carry(src, snap_every)
            and os.path.isdir(os.path.join(dest, FEED_END_DIR)) == os.path.isdir(os.path.join(src, FEED_END_DIR)))


def carry_if_changed(src, dest, snap_every=None, log=print):
    """:func:`carry` ``src`` to ``dest`` unless the copy is :func:`up_to_date` (then ``dest`` is
    not touched). Returns ``'carried'`` or ``'unchanged'``; raises as :func:`carry` does."""
    if os.path.exists(os.path.join(src, 'run.json')) and up_to_date(src, dest, snap_every):
        return 'unchanged'
    carry(src, dest, snap_every=snap_every, log=log)
    return 'carried'


def watch(src, dest, every, snap_every=None, log=print, sleep=time.sleep):
    """Carry ``src`` to ``dest`` now and every ``every`` minutes (:func:`carry_if_changed`) until
    the run is done and its finished state carried. A round that cannot carry (no checkpoint yet,
    a checkpoint pruned while it was copied) is logged and tried again at the next round.

    :returns: the number of rounds made.
    :raises ValueError: ``every`` is not a positive number of minutes.
    """
    if not (isinstance(every, (int, float)) and every > 0):
        raise ValueError('watch: every must be a positive number of minutes, not %r' % (every,))
    rounds = 0
    while True:
        rounds += 1
        try:
            outcome = carry_if_changed(src, dest, snap_every=snap_every, log=log)
        except (OSError, ValueError, RuntimeError) as e:      # CheckpointError is a RuntimeError
            outcome = 'not carried (%s: %s)' % (type(e).__name__, e)
        log('%s carry of %s: %s' % (time.strftime('%H:%M:%S'), src, outcome))
        if is_done(src) and up_to_date(src, dest, snap_every):      # up_to_date: the copy is done too
            return rounds
        sleep(60 * every)


def processes_running(run_dir, proc='/proc'):
    """Process ids whose command line holds ``--out PATH`` (or ``--out=PATH``) with PATH the run
    directory ``run_dir`` (a relative PATH taken from that process's working directory): the
    pile.py processes that run it, whatever launched them. Linux's /proc; the caller excluded."""
    target = os.path.realpath(run_dir)
    found = []
    for name in os.listdir(proc):
        if not name.isdigit() or int(name) == os.getpid():
            continue
        try:
            with open(os.path.join(proc, name, 'cmdline'), 'rb') as f:
                args = [a.decode(errors='replace') for a in f.read().split(b'\0')]
            cwd = os.readlink(os.path.join(proc, name, 'cwd'))
        except OSError:                                   # gone meanwhile, or not ours to read
            continue
        for k, arg in enumerate(args):
            path = arg[len('--out='):] if arg.startswith('--out=') else (args[k + 1] if arg == '--out' and k + 1 < len(args) else None)
            if path and os.path.realpath(os.path.join(cwd, path)) == target:
                found.append(int(name))
                break
    return sorted(found)


def stop_and_carry(src, dest, snap_every=None, timeout=600.0, log=print, proc='/proc'):
    """End a pile for the session: SIGTERM every process that runs ``src``
    (:func:`processes_running`; the pile writes a checkpoint and stops), wait until they are gone,
    then :func:`carry` ``src`` to ``dest`` (its newest checkpoint: the one written on the signal).

    :returns: the record of the carry.
    :raises RuntimeError: a process still runs ``timeout`` seconds after the signal (nothing is
        carried: the newest checkpoint would not be the last).
    """
    pids = processes_running(src, proc)
    if not pids:
        log('stop: no process runs %s; carrying it as it is' % src)
    for pid in pids:
        try:
            os.kill(pid, signal.SIGTERM)
            log('stop: SIGTERM sent to process %d (it runs %s)' % (pid, src))
        except ProcessLookupError:
            pass
    end = time.monotonic() + timeout
    while True:
        alive = [pid for pid in pids if not _exited(os.path.join(proc, str(pid)))]
        if not alive:
            break
        if time.monotonic() > end:
            raise RuntimeError('stop: process(es) %s still run %s %.0f s after SIGTERM; nothing carried'
                               % (', '.join(map(str, alive)), src, timeout))
        time.sleep(0.5)
    return carry(src, dest, snap_every=snap_every, log=log)


def _exited(proc_dir):
    """True when the process of ``proc_dir`` is gone, or has exited and waits to be reaped (a zombie)."""
    try:
        with open(os.path.join(proc_dir, 'stat')) as f:
            return f.read().rsplit(')', 1)[1].split()[0] == 'Z'
    except (OSError, IndexError):
        return True

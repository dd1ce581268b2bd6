"""Ensembles of sand piles: many runs of ``scripts/pile.py`` (sizes x seeds), run as tasks of
Dask's distributed engine (a local cluster by default, or any Dask cluster given its scheduler's
address), resumable, with a status file that records every run's fate.

No YADE, no numpy: the driver runs under Debian's ``/usr/bin/python3`` (with its
``python3-distributed``) and each task starts one YADE process per pile through
``scripts/yade``. Used by ``scripts/pile_ensemble.py``.

Layout of an ensemble directory::

    ensemble.json          plan (sizes, seeds, pile options) and one record per run
    n<N>_s<S>/             the run directory of the pile of N grains and seed S (pile.py layout)
    n<N>_s<S>/log.txt      its YADE output

A run is *done* when its ``run.json`` carries ``wall_time_s`` and ``finished`` (written by
:func:`yadecd.pile.run` after its last step) and a snapshot exists. Calling :func:`run_ensemble` again skips the
done runs and resumes the others from their checkpoints (``--resume``), so an ensemble survives a
killed driver. A run that fails (non-zero exit, a bad option) is recorded as ``failed`` with its
exit code and the tail of its log; the other runs go on.
"""
import json
import os
import signal
import subprocess
import sys
import time

from ..io import write_json_atomic
from ..pile.grains import SHAPES
from ..pile.protocol import DEFAULTS, feed_time
from . import cost as runcost
from .carry import is_done

RATE_DEFAULT = DEFAULTS['rate']     # grains per second
DT_DEFAULT = DEFAULTS['dt']         # s


def run_name(n_grains, seed, grain_shape='sphere'):
    """Directory name of one run of an ensemble: ``n1000_s3``, or ``dimer_n1000_s3`` for grains of
    another shape than the paper's spheres (so that records of several shapes can sit together)."""
    name = 'n%d_s%d' % (n_grains, seed)
    return name if grain_shape == 'sphere' else '%s_%s' % (grain_shape, name)


def epochs(n_grains, relax, rate=RATE_DEFAULT, dt=DT_DEFAULT):
    """Snapshot times [s] of an ensemble run: half the feed, end of the feed, end of the
    relaxation (when relax > 0). Formatted as pile.py's ``--epochs`` string."""
    t_feed = feed_time(n_grains, rate, dt)
    times = [0.5 * t_feed, t_feed] + ([t_feed + relax] if relax > 0 else [])
    return ','.join('%.4f' % t for t in times)


def parse_seeds(text):
    """'1-8' -> [1..8]; '1,3,5' -> [1, 3, 5]; mixed '1-3,7' allowed. Raises ValueError."""
    seeds = []
    for part in str(text).split(','):
        part = part.strip()
        if not part:
            continue
        if '-' in part[1:]:
            a, b = part.split('-', 1)
            lo, hi = int(a), int(b)
            if hi < lo:
                raise ValueError('seed range %r is empty' % part)
            seeds.extend(range(lo, hi + 1))
        else:
            seeds.append(int(part))
    if not seeds:
        raise ValueError('no seed in %r' % text)
    if len(set(seeds)) != len(seeds):
        raise ValueError('seeds repeat in %r' % text)
    return seeds


def _tail(path, n=12):
    try:
        with open(path, errors='replace') as f:
            return ''.join(f.readlines()[-n:])
    except OSError:
        return ''


class Ensemble:
    """The plan and status of an ensemble directory (``ensemble.json``)."""

    def __init__(self, root):
        self.root = os.path.abspath(root)
        self.path = os.path.join(self.root, 'ensemble.json')
        self.data = {'plan': {}, 'runs': {}}
        if os.path.exists(self.path):
            with open(self.path) as f:
                self.data = json.load(f)

    def save(self):
        """Write the status atomically (temporary file, then rename)."""
        os.makedirs(self.root, exist_ok=True)
        write_json_atomic(self.path, self.data, sort_keys=True)

    def plan(self, sizes, seeds, relax, options):
        """Add the runs sizes x seeds (existing records are kept). ``options`` are extra pile.py
        options (list of strings) applied to every run of the ensemble; they may not change once
        runs exist, and a grain shape must be known (:data:`yadecd.pile.grains.SHAPES`): a bad one
        is refused here, before any pile starts, not by each pile's YADE process."""
        shape = option_text(options, '--grain-shape', 'sphere')
        if shape not in SHAPES:
            raise ValueError('--grain-shape %r is not a grain shape (known: %s)' % (shape, ', '.join(SHAPES)))
        old = self.data.get('plan', {})
        if old and self.data['runs'] and (old.get('relax') != relax or old.get('options') != list(options)):
            raise ValueError('ensemble %s was planned with relax=%r options=%r; got relax=%r options=%r '
                             '(use another directory)' % (self.root, old.get('relax'), old.get('options'),
                                                          relax, list(options)))
        self.data['plan'] = {'relax': relax, 'options': list(options)}
        for n in sizes:
            for s in seeds:
                name = run_name(n, s, shape)
                self.data['runs'].setdefault(name, {'n_grains': n, 'seed': s, 'state': 'pending',
                                                    'attempts': 0})
        self.save()

    def runs(self):
        """The runs of the ensemble: ``{name: record}`` (grains, seed, state, attempts, ...)."""
        return self.data['runs']


def run_command(repo, run_dir, rec, plan, resume):
    """scripts/yade command line of one run (one thread)."""
    cmd = [os.path.join(repo, 'scripts', 'yade'), '-j1', '-n', '-x', os.path.join(repo, 'scripts', 'pile.py'),
           '--out', run_dir]
    if resume:
        return cmd + ['--resume']
    rate, dt = option_value(plan['options'], '--rate', RATE_DEFAULT), option_value(plan['options'], '--dt', DT_DEFAULT)
    return cmd + ['--n-grains', str(rec['n_grains']), '--seed', str(rec['seed']), '--relax', str(plan['relax']),
                  '--epochs', epochs(rec['n_grains'], plan['relax'], rate, dt)] + list(plan['options'])


def option_text(options, flag, default):
    """The value of ``flag`` in a pile.py option list (``['--dt', '1e-3']`` or ``['--dt=1e-3']``) as
    given, ``default`` when absent. Raises ValueError naming the flag when its value is missing."""
    options = list(options)
    for i, o in enumerate(options):
        if o == flag or o.startswith(flag + '='):
            text = o.split('=', 1)[1] if '=' in o else (options[i + 1] if i + 1 < len(options) else None)
            if text is None:
                raise ValueError('pile option %s needs a value' % flag)
            return text
    return default


def option_value(options, flag, default):
    """The float value of ``flag`` in a pile.py option list (``['--dt', '1e-3']`` or ``['--dt=1e-3']``),
    ``default`` when absent. Raises ValueError naming the flag when its value is missing or not a number."""
    text = option_text(options, flag, None)
    if text is None:
        return default
    try:
        return float(text)
    except ValueError:
        raise ValueError('pile option %s needs a number, got %r' % (flag, text)) from None


def run_pile(repo, run_dir, rec, plan):
    """Run one pile to its end in a YADE process of its own (on a Dask worker, or anywhere) and
    report: ``{'returncode', 'done', 'wall_s', 'resumed', 'error'}``.

    A run that has a ``run.json`` resumes from its checkpoint. The run directory's lock file
    (``.lock``, ``flock``) is taken before YADE starts and held by the YADE process itself (it
    inherits the descriptor), so that a retry of this task can never run beside a YADE process
    left by a dead worker: it waits until that one has stopped. YADE is started with a parent-death
    signal (``setpriv --pdeathsig TERM``): if the worker dies, YADE gets SIGTERM, which makes the
    pile write a checkpoint and stop, and the retry resumes from it."""
    import fcntl
    import shutil
    os.makedirs(run_dir, exist_ok=True)
    with open(os.path.join(run_dir, '.lock'), 'a') as lock:
        fcntl.flock(lock.fileno(), fcntl.LOCK_EX)
        resume = os.path.exists(os.path.join(run_dir, 'run.json'))
        cmd = run_command(repo, run_dir, rec, plan, resume)
        if shutil.which('setpriv'):
            cmd = ['setpriv', '--pdeathsig', 'TERM', '--'] + cmd
        start = time.time()
        with open(os.path.join(run_dir, 'log.txt'), 'a') as logf:
            logf.write('\n=== %s %s\n' % (time.strftime('%Y-%m-%d %H:%M:%S'), 'resume' if resume else 'start'))
            logf.flush()
            rc = subprocess.run(cmd, stdout=logf, stderr=subprocess.STDOUT, cwd=repo, pass_fds=(lock.fileno(),)).returncode
    done = rc == 0 and is_done(run_dir)
    return {'returncode': rc, 'done': done, 'wall_s': time.time() - start, 'resumed': resume,
            'error': '' if done else _tail(os.path.join(run_dir, 'log.txt'))}


def _client(jobs, scheduler):
    """A Dask client: of the scheduler at ``scheduler`` (an address: the ensemble spreads over its
    workers), or of a local cluster of ``jobs`` single-threaded worker processes."""
    from dask.distributed import Client, LocalCluster
    if scheduler:
        return Client(scheduler), None
    cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True, dashboard_address=None,
                           silence_logs=40)
    return Client(cluster), cluster


def run_ensemble(root, repo, jobs=2, order='small-first', log=print, retry_failed=False, scheduler=None):
    """Run every pending run of the ensemble in ``root`` on Dask (distributed): a local cluster of
    ``jobs`` single-threaded workers, or the cluster whose scheduler is at ``scheduler`` (its
    workers must see ``root`` and ``repo`` at the same paths and import yadecd: start them with
    ``PYTHONPATH=<repo>/py dask-worker <address> --nthreads 1``). One task per pile
    (:func:`run_pile`), one YADE process per task.

    Done runs are skipped; runs with a checkpoint resume; failed runs are retried only with
    ``retry_failed``. A worker that dies mid-pile makes its pile checkpoint and stop, and Dask runs
    the task again on another worker, which resumes it (after three worker deaths on one pile the
    run is recorded as failed). Returns the status dict of every run. SIGINT/SIGTERM stop the
    driver, whose local workers stop their piles at a checkpoint (they resume next time); the
    status file stays consistent."""
    from dask.distributed import as_completed
    ens = Ensemble(root)
    runs = ens.runs()
    todo = []
    for name, rec in runs.items():
        run_dir = os.path.join(ens.root, name)
        if is_done(run_dir):
            rec['state'] = 'done'
        elif rec['state'] == 'failed' and not retry_failed:
            continue
        else:
            rec['state'] = 'pending'
            todo.append(name)
    ens.save()
    if not todo:
        return runs
    key = (lambda k: (runs[k]['n_grains'], runs[k]['seed'])) if order == 'small-first' else \
        (lambda k: (-runs[k]['n_grains'], runs[k]['seed']))
    todo.sort(key=key)
    stop = {'flag': False}

    def _stop(signum, frame):
        stop['flag'] = True
        raise KeyboardInterrupt

    old_handlers = {s: signal.signal(s, _stop) for s in (signal.SIGINT, signal.SIGTERM)}
    client = cluster = None
    try:
        client, cluster = _client(jobs, scheduler)
        futures = {}
        for k, name in enumerate(todo):
            rec = runs[name]
            fut = client.submit(run_pile, repo, os.path.join(ens.root, name), dict(rec), ens.data['plan'],
                                key='pile-%s-%d' % (name, rec.get('attempts', 0)), pure=False, priority=len(todo) - k)
            futures[fut] = name
            rec.update(state='submitted', attempts=rec.get('attempts', 0) + 1)
        ens.save()
        log('ensemble: %d pile(s) submitted to %s' % (len(todo), scheduler or 'a local cluster of %d worker(s)' % jobs))
        for fut in as_completed(list(futures)):
            name = futures[fut]
            rec = runs[name]
            try:
                res = fut.result()
            except Exception as e:      # the task itself failed (KilledWorker after repeated deaths...)
                res = {'returncode': None, 'done': False, 'wall_s': None, 'resumed': None,
                       'error': '%s: %s' % (type(e).__name__, e)}
            rec['returncode'] = res['returncode']
            rec['wall_s'] = res['wall_s']
            if res['done']:
                rec['state'] = 'done'
                rec.pop('error', None)
            else:
                rec['state'] = 'failed'
                rec['error'] = res['error']
            ens.save()
            log('ensemble: %s %s (exit %s, %s)' % (name, rec['state'], res['returncode'],
                                                   '%.0f s' % res['wall_s'] if res['wall_s'] is not None else 'no time'))
    except KeyboardInterrupt:
        log('ensemble: stopped; interrupted piles resume from their checkpoints next time')
    finally:
        for name in todo:
            if runs[name]['state'] == 'submitted':
                runs[name]['state'] = 'pending'
        ens.save()
        for s, h in old_handlers.items():
            signal.signal(s, h)
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    return runs


def progress_of(run_dir):
    """Where an unfinished run stands, from its ``progress.csv`` and ``run.json``: dict ``time_s``,
    ``end_s`` (the end of its feed plus its relaxation; None without run.json), ``grains``,
    ``wall_s`` (its wall time so far, over all segments) and ``remaining_s`` (the wall time it
    still needs at its recent pace, :func:`yadecd.runs.cost.remaining_wall`; None without run.json
    or with too short a record); None before its first progress line."""
    path = os.path.join(run_dir, 'progress.csv')
    try:
        prog = runcost.read_progress(path) if os.path.exists(path) else {}
    except (ValueError, TypeError, IndexError):  # an empty file, or no header line yet
        return None
    if not all(k in prog and prog[k].size for k in ('time_s', 'grains', 'wall_s')):
        return None
    row = {k: float(prog[k][-1]) for k in ('time_s', 'grains', 'wall_s')}
    end = feed_end = None
    try:
        with open(os.path.join(run_dir, 'run.json')) as f:
            p = json.load(f)
        feed_end = feed_time(int(p['n_grains']), p.get('rate', DEFAULTS['rate']), p.get('dt', DEFAULTS['dt']))
        end = feed_end + float(p.get('relax', 0))
    except (OSError, ValueError, KeyError):
        pass
    return {'time_s': row['time_s'], 'end_s': end, 'grains': int(row['grains']), 'wall_s': row['wall_s'],
            'remaining_s': runcost.remaining_wall(prog, end, feed_end)}


def carry_ensemble(root, dest, snap_every=None, log=print):
    """Carry every run of the ensemble in ``root`` that has a checkpoint to ``dest/<name>``
    (:func:`yadecd.runs.carry.carry`: run.json, progress, snapshots, the newest valid checkpoint
    reduced to its state.npz), so that the ensemble outlives the machine it runs on: the driver
    resumes each copy from its checkpoint (``pile_carry.py`` back, or ``run`` on ``dest`` itself).

    Safe beside running piles: a checkpoint is copied only once complete and verified, and each
    destination is swapped in whole. A run whose copy already holds its newest checkpoint, its
    snapshots and its finished state is left as it is. One run's failure (a checkpoint pruned while
    it was copied, say) is logged and the others are still carried.

    :returns: dict name -> ``'carried'``, ``'unchanged'``, ``'no checkpoint'``, ``'not started'``
        or the error's text.
    """
    from .carry import carry_if_changed
    from .checkpoint import CheckpointStore
    ens = Ensemble(root)
    if not os.path.exists(ens.path):
        raise FileNotFoundError('carry: %s is not an ensemble directory (no ensemble.json)' % ens.root)
    if os.path.abspath(dest) == ens.root:
        raise ValueError('carry: the destination is the ensemble itself (%s)' % ens.root)
    outcome = {}
    for name in sorted(ens.runs()):
        src, out = os.path.join(ens.root, name), os.path.join(dest, name)
        if not os.path.exists(os.path.join(src, 'run.json')):
            outcome[name] = 'not started'
            continue
        if CheckpointStore(src).latest() is None:
            outcome[name] = 'no checkpoint'
            continue
        try:
            outcome[name] = carry_if_changed(src, out, snap_every=snap_every, log=log)
        except (OSError, ValueError, RuntimeError) as e:      # CheckpointError is a RuntimeError
            outcome[name] = '%s: %s' % (type(e).__name__, e)
            log('carry: %s not carried (%s)' % (name, outcome[name]))
    return outcome


def status_lines(root):
    """One line per run: name, state, attempts, and its wall time when it is done, where it
    stands when it is not (simulated time of its end, grains, wall time so far and, once its record
    is long enough, the wall time it still needs at its recent pace: :func:`progress_of`), the first
    error line when it failed."""
    ens = Ensemble(root)
    lines = []
    for name, rec in sorted(ens.runs().items(), key=lambda kv: (kv[1]['n_grains'], kv[1]['seed'])):
        run_dir = os.path.join(ens.root, name)
        done = is_done(run_dir)
        state = 'done' if done else rec['state']
        err = (rec.get('error') or '').strip().splitlines()
        where = ''
        if done and 'wall_s' in rec:
            where = '%.0f s' % rec['wall_s']
        elif not done:
            pr = progress_of(run_dir)
            if pr is not None:
                where = 't = %.2f%s s, %s grains, %.0f s of wall time so far' % (
                    pr['time_s'], '' if pr['end_s'] is None else ' of %.2f' % pr['end_s'], pr['grains'], pr['wall_s'])
                if pr['remaining_s'] is not None:
                    where += ', about %.0f min more at its recent pace' % (pr['remaining_s'] / 60)
        lines.append('%-12s %-9s attempts %d  %s%s' % (name, state, rec.get('attempts', 0), where,
                                                       ('  error: ' + err[-1]) if err and state == 'failed' else ''))
    return lines


if __name__ == '__main__':
    sys.exit('use scripts/pile_ensemble.py')

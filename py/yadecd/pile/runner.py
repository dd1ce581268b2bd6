"""Running a pile: :class:`PileRun` (start, resume from checkpoints, advance with progress lines,
an ETA and snapshots), branches of a run with other solver options, and :func:`run`, the one
entry point ``scripts/pile.py`` calls.
"""

import json
import math
import os
import signal
import time
import numpy as np
from yade import O

from ..io import write_json_atomic
from ..runs import cost as runcost, runstate
from ..runs.runstate import RunStateError  # noqa: F401 (reachable as yadecd.pile.RunStateError)
from ..runs.carry import FEED_END_DIR, carry
from ..runs.checkpoint import CheckpointStore, CheckpointError, has_checkpoint
from .build import Clock, Feeder, add_clump, add_grain, build_scene, solver_stats
from .protocol import (BRANCH_MAY_CHANGE, RESUME_MAY_CHANGE, UNSAVED_OPTIONS, check_params, creation_period, defaults,
                       disk_need, engine_options, feed_end_time, read_run_json, snapshot_times, upgrade)
from .write import snapshot


#: Wall time per simulated second of a fed pile grows as N^ETA_EXPONENT (contacts ∝ N, times the
#: sweeps per step); the value is the larger of those measured (docs/performance.md, "The time
#: step at scale"): a wrong ETA costs little on short runs.
ETA_EXPONENT = 1.7


def eta_seconds(t, t_end, t_feed_end, wall_per_sim_s, exponent=ETA_EXPONENT, points=200):
    """Wall time [s] left from simulated time ``t`` to ``t_end`` when a simulated second now costs
    ``wall_per_sim_s`` and its cost grows as the grain count to the power ``exponent``, the count
    growing in proportion to the time until ``t_feed_end`` and constant after it (the relaxation).
    A constant rate (``exponent`` 0) gives ``(t_end - t) * wall_per_sim_s``."""
    if t >= t_end:
        return 0.0
    n_now = max(min(t, t_feed_end), 1e-12)
    s = np.linspace(t, t_end, points)
    growth = (np.minimum(s, t_feed_end).clip(min=n_now) / n_now) ** exponent
    return float(wall_per_sim_s * np.trapz(growth, s))


def preflight(run_dir, p):
    """Fail before work: the run directory must be creatable, writable, and hold room for the
    run's checkpoints and snapshots. Raises OSError / CheckpointError with the cause."""
    try:
        os.makedirs(run_dir, exist_ok=True)
        probe = os.path.join(run_dir, '.write-probe')
        with open(probe, 'wb') as f:
            f.write(b'\0' * 4096)
            f.flush()
            os.fsync(f.fileno())
        os.remove(probe)
    except OSError as e:
        raise CheckpointError('run directory %s is not usable: %s' % (run_dir, e.strerror or e)) from e
    st = os.statvfs(run_dir)
    free, need = st.f_bavail * st.f_frsize, disk_need(p)
    if free < need:
        raise CheckpointError('run directory %s has %.1f MB free; this run needs about %.1f MB for its checkpoints '
                              'and snapshots' % (run_dir, free / 1e6, need / 1e6))


RUN_FILES = ('run.json', 'progress.csv', 'segments.csv', 'checkpoint.json', 'checkpoint.yade.gz')


def _run_json(run_dir, missing):
    """A run's parameters: its ``run.json`` (renamed keys mapped) over :func:`defaults` (options added since the run began
    take their defaults). ``missing`` (with one %s for the directory) is the error without it."""
    path = os.path.join(run_dir, 'run.json')
    if not os.path.exists(path):
        raise FileNotFoundError(missing % run_dir)
    p = defaults()
    p.update(read_run_json(path))
    return p


class PileRun:
    """One pile run in its directory: started, resumed from a checkpoint, advanced, checkpointed.

    A checkpoint is one verified unit of :class:`yadecd.runs.checkpoint.CheckpointStore` holding
    ``state.npz`` (the layout-independent state, :mod:`yadecd.runs.runstate`) and ``scene.yade.gz``
    (YADE's archive, the fast path: it resumes bit for bit when the plugin is the same)."""

    def __init__(self, run_dir, p, log):
        self.run_dir, self.p, self.log = run_dir, p, log
        self.store = CheckpointStore(run_dir)
        self.clock = Clock()
        self.births, self.done_snaps = {}, set()
        self.rng = np.random.default_rng(p['seed'])
        self.feeder = Feeder(p, self.rng, self.births, self.clock)
        self.resumed_from = None     # description of the checkpoint resumed from
        self.wall_before = 0.0       # wall time [s] of the segments before this one (a resumed run)
        self.segment_start = time.time()

    # ------------------------------------------------------------------ starting
    @classmethod
    def start(cls, run_dir, overrides, log=print, overwrite=False):
        """A new run: parameters checked, directory checked (an existing run is never replaced
        unless ``overwrite``), floor and engines built, ``run.json`` written."""
        p = defaults()
        p.update(upgrade({k: v for k, v in overrides.items() if v is not None}))
        check_params(p)
        if has_run(run_dir):
            if not overwrite:
                raise FileExistsError('%s already holds a pile run: pass resume=True (--resume) to continue it, or '
                                      'overwrite=True (--overwrite) to start it again' % run_dir)
            clear_run(run_dir)
        preflight(run_dir, p)
        self = cls(run_dir, p, log)
        p['n_paving'] = build_scene(p)
        write_json_atomic(os.path.join(run_dir, 'run.json'), p)
        return self

    @classmethod
    def resume(cls, run_dir, overrides, log=print):
        """Continue the run in ``run_dir`` from its newest valid checkpoint (a damaged one is
        reported and the one before it used). ``overrides`` may only change RESUME_MAY_CHANGE;
        a run killed before its first checkpoint starts again from its ``run.json``."""
        p = _run_json(run_dir, 'nothing to resume in %s: it holds no run.json')
        given = upgrade({k: v for k, v in overrides.items() if v is not None})
        unknown = set(given) - set(defaults())
        if unknown:
            raise ValueError('unknown pile parameters: %s' % ', '.join(sorted(unknown)))
        clash = ['%s (run: %r, given: %r)' % (k, p.get(k), v) for k, v in sorted(given.items())
                 if k not in RESUME_MAY_CHANGE and p.get(k) != v]
        if clash:
            raise ValueError('options differ from the run being resumed in %s: %s; only %s may change on resume'
                             % (run_dir, ', '.join(clash), ', '.join(RESUME_MAY_CHANGE)))
        p['stop_time'] = 0.0            # a stop applies to the segment it was given for
        p.update({k: v for k, v in given.items() if k in RESUME_MAY_CHANGE})
        check_params({k: v for k, v in p.items() if k in defaults()})
        preflight(run_dir, p)
        for name in os.listdir(run_dir):      # files a kill left half-written (snapshots, run.json)
            if name.endswith('.tmp') and os.path.isfile(os.path.join(run_dir, name)):
                os.remove(os.path.join(run_dir, name))
        self = cls(run_dir, p, log)
        if not self._load_newest():
            log('no checkpoint yet in %s: starting the run again' % run_dir)
            clear_run(run_dir, keep=('run.json',))
            p['n_paving'] = build_scene(p)
            return self
        self._truncate_progress()
        log('resumed %s at t=%.3f s, %d grains (%s)' % (run_dir, self.clock.time(), self.feeder.count, self.resumed_from))
        return self

    @classmethod
    def load(cls, run_dir, log=print):
        """The run's newest valid checkpoint loaded into ``O`` without continuing the run, for
        tools that re-solve or inspect a run's state: nothing in ``run_dir`` changes. Loads YADE's
        archive when the checkpoint has one written by this plugin, else rebuilds the scene from
        its ``state.npz`` (a carried run), as :meth:`resume` does; ``clock.time()`` is then the
        run's time and ``births`` every grain's birth time."""
        self = cls(run_dir, _run_json(run_dir, '%s holds no pile run: no run.json'), log)
        if not self._load_newest():
            raise FileNotFoundError('%s holds no valid checkpoint to load' % run_dir)
        return self

    def _load_newest(self):
        """Load the newest valid checkpoint (a damaged one is reported and the one before it
        used), or a first-release one, into ``O``; False when the run has none."""
        latest = self.store.latest()
        for m in self.store.messages:
            self.log('checkpoint: ' + m)
        if latest is not None:
            self._resume_unit(*latest)
        elif os.path.exists(os.path.join(self.run_dir, 'checkpoint.json')):
            self._resume_release_1()
        else:
            return False
        return True

    def _restore_counters(self, meta, births, near):
        self.births.update(births)
        self.rng.bit_generator.state = meta['rng']
        self.feeder.count = int(meta['created'])
        self.feeder.near = [int(i) for i in near]
        self.done_snaps.update(meta['snaps'])
        self.wall_before = float(meta['wall_s']) if 'wall_s' in meta else self._progress_wall(self.clock.time())

    def _progress_wall(self, t):
        """Wall time [s] of the last progress line at or before ``t`` (checkpoints written before they
        recorded the run's wall time: their first segment's progress lines count from the start)."""
        path, wall = os.path.join(self.run_dir, 'progress.csv'), 0.0
        if os.path.exists(path):
            with open(path) as f:
                for ln in f.readlines()[1:]:
                    parts = ln.strip().split(',')
                    if len(parts) >= 6 and _float(parts[0]) <= t + 0.5 * self.p['dt']:
                        wall = _float(parts[5])
        return wall if math.isfinite(wall) else 0.0

    def _resume_unit(self, seq, unit, info):
        meta = info['meta']
        data = runstate.read(os.path.join(unit, 'state.npz'))
        births = dict(zip(runstate.extra(data, 'birth_id').tolist(), runstate.extra(data, 'birth_time').tolist()))
        near = runstate.extra(data, 'near').tolist()
        scene = os.path.join(unit, 'scene.yade.gz')
        if meta.get('plugin_digest') == runstate.plugin_digest() and os.path.exists(scene):
            O.load(scene)
            # the solver options not saved with the scene come from the run's parameters
            unsaved = {key: self.p[key] for key in UNSAVED_OPTIONS if key in self.p}
            for attr, value in engine_options(unsaved).items():
                setattr(O.engines[-1], attr, value)
            self.clock.t0, self.clock.i0 = meta['time_offset'], meta['iter_offset']
            self.resumed_from = 'checkpoint %d, YADE archive: bit-identical continuation' % seq
        else:
            self.rebuild(data)
            self.resumed_from = ('checkpoint %d, rebuilt from state.npz: written by plugin %s, this is %s; the same '
                                 'physical state, not bit-identical to an uninterrupted run'
                                 % (seq, str(meta.get('plugin_digest'))[:12], runstate.plugin_digest()[:12]))
        if abs(self.clock.time() - meta['time']) > 1e-9 or self.clock.iter() != meta['iter']:
            raise CheckpointError('checkpoint %d is inconsistent: its scene is at t=%r, step %d, its record at t=%r, step %d'
                                  % (seq, self.clock.time(), self.clock.iter(), meta['time'], meta['iter']))
        self._restore_counters(meta, births, near)
        integ = O.engines[-1]
        if hasattr(integ, 'nUnconverged'):
            integ.nUnconverged = int(meta.get('n_unconverged', 0))

    def _resume_release_1(self):
        """Checkpoints of the first release (``checkpoint.yade.gz`` + ``checkpoint.json``)."""
        try:
            with open(os.path.join(self.run_dir, 'checkpoint.json')) as f:
                state = json.load(f)
        except ValueError as e:
            raise CheckpointError('first-release checkpoint %s/checkpoint.json is damaged (%s); it has no older copy'
                                  % (self.run_dir, e)) from e
        O.load(os.path.join(self.run_dir, 'checkpoint.yade.gz'))
        meta = dict(rng=state['rng'], created=state['created'], snaps=state['snaps'])
        self._restore_counters(meta, {int(k): v for k, v in state['births'].items()}, [])
        self.resumed_from = 'first-release checkpoint (checkpoint.yade.gz)'

    def rebuild(self, data):
        """The scene again from a run state, by the code that builds a new run: floor and engines
        (:func:`build_scene`), grains (:func:`add_grain`, :func:`add_clump` from the saved member
        centres), then positions, velocities and contacts with their warm-start impulses
        (:mod:`yadecd.runs.runstate`)."""
        p = self.p
        ids, kind, clump_of = data['body_id'], data['body_kind'], data['clump_id']
        n_paving = int(p['n_paving'])
        shape = p.get('grain_shape', 'sphere')
        grain_rows = slice(n_paving + 1, len(ids))
        if shape == 'sphere':   # spheres, none in a clump
            grains_ok = ((kind[grain_rows] == 1) & (clump_of[grain_rows] < 0)).all()
        else:                   # clumps and their members
            grains_ok = ((kind[grain_rows] == 2) | ((kind[grain_rows] == 1) & (clump_of[grain_rows] >= 0))).all()
        if len(ids) < n_paving + 1 or kind[0] != 0 or not (kind[1:n_paving + 1] == 1).all() or not grains_ok:
            raise runstate.RunStateError('run state does not hold a pile scene of %s grains (a wall, the paving, then the '
                                         'grains)' % shape)
        floor = np.column_stack([data['pos'][1:n_paving + 1, :2], data['radius'][1:n_paving + 1]])
        build_scene(p, floor=floor)
        members = {}                  # clump id -> its members' rows, in id order
        for k in np.flatnonzero(clump_of >= 0):
            members.setdefault(int(clump_of[k]), []).append(k)
        for k in range(n_paving + 1, len(ids)):
            if kind[k] == 1 and clump_of[k] < 0:
                add_grain(*data['pos'][k], data['radius'][k])
            elif kind[k] == 2:
                rows = members[int(ids[k])]
                add_clump(data['pos'][rows], float(data['radius'][rows[0]]), shape)
        runstate.restore_bodies(data)
        restored, skipped = runstate.restore_contacts(data)
        self.clock.t0, self.clock.i0 = float(data['time']), int(data['iter'])
        self.log('rebuilt from state.npz: %d bodies, %d contacts with their impulses%s'
                 % (len(ids), restored, ', %d pairs no longer in reach' % skipped if skipped else ''))

    def _truncate_progress(self):
        """Drop progress lines written after the checkpoint resumed from (they will be redone)."""
        path = os.path.join(self.run_dir, 'progress.csv')
        if not os.path.exists(path):
            return
        with open(path) as f:
            lines = f.readlines()
        t = self.clock.time() + 0.5 * self.p['dt']
        keep = lines[:1] + [ln for ln in lines[1:] if ln.count(',') >= 5 and _float(ln.split(',')[0]) <= t]
        with open(path + '.tmp', 'w') as f:
            f.writelines(keep)
        os.replace(path + '.tmp', path)

    # ------------------------------------------------------------------ checkpoints
    def checkpoint(self, now=None):
        """Write one checkpoint unit (between steps, never from inside O.run); it records the
        run's wall time up to ``now`` (default: the call), the same instant a segment's end
        measures its own wall time to, so that the segments' times add up to the run's."""
        t, it = self.clock.time(), self.clock.iter()
        bid = sorted(self.births)
        extra = dict(birth_id=np.array(bid, dtype=np.int64), birth_time=np.array([self.births[b] for b in bid]),
                     near=np.array(self.feeder.near, dtype=np.int64))
        meta = dict(time=t, iter=it, time_offset=self.clock.t0, iter_offset=self.clock.i0,
                    plugin_digest=runstate.plugin_digest(), yade_version=runstate.yade_version(),
                    rng=self.rng.bit_generator.state, created=self.feeder.count, snaps=sorted(self.done_snaps),
                    n_unconverged=int(getattr(O.engines[-1], 'nUnconverged', 0)),
                    wall_s=self.wall_before + ((time.time() if now is None else now) - self.segment_start))
        self.store.write({'state.npz': lambda path: runstate.capture(path, t, it, extra),
                          'scene.yade.gz': lambda path: O.save(path)}, meta)

    def keep_feed_end(self):
        """Checkpoint now (the end of the feed) and keep that checkpoint as the run's carried copy
        of itself in ``<run>/at_feed_end`` (:data:`yadecd.runs.carry.FEED_END_DIR`), which
        pruning never touches: ``pile_tolerance.py <run>/at_feed_end`` re-solves it tightly."""
        self.checkpoint()
        carry(self.run_dir, os.path.join(self.run_dir, FEED_END_DIR), snapshots=False, log=self.log)

    def _feed_end_pending(self, t_feed_end):
        """Whether this segment is to keep the end of the feed (:meth:`keep_feed_end`): the pile
        relaxes after the feed, the feed has not ended yet and no copy is kept already."""
        return (self.p['relax'] > 0 and self.clock.time() < t_feed_end - 0.5 * self.p['dt']
                and not os.path.isdir(os.path.join(self.run_dir, FEED_END_DIR)))

    # ------------------------------------------------------------------ stepping
    def advance(self, t_stop=None):
        """Run to ``t_stop`` (default: the end of the run, or the run's stop_time), with
        creations, snapshots, progress lines and checkpoints; returns the parameter dict.

        SIGTERM and SIGINT (a shutdown, Ctrl-C) stop the run at the end of the current chunk of
        steps with a checkpoint, so that nothing is lost: the dict then has ``stopped_by`` (the
        signal's name) and ``finished`` False; ``--resume`` continues bit for bit."""
        with _StopSignals() as stop:
            return self._advance(t_stop, stop)

    def _advance(self, t_stop, stop):
        p, clock, feeder = self.p, self.clock, self.feeder
        period = creation_period(p['rate'], p['dt'])
        t_feed_end = feed_end_time(p)
        t_end = t_feed_end + p['relax']
        t_stop = min(t_end, t_stop or p['stop_time'] or t_end)
        snaps = [t for t in snapshot_times(p, t_end) if '%.3f' % t not in self.done_snaps]
        keep_end = self._feed_end_pending(t_feed_end)
        wall0, sim0 = time.time(), clock.time()
        self.segment_start = wall0
        runcost.append_segment(self.run_dir, sim0, self.wall_before, O.numThreads)
        last_ck = last_log = time.time()
        t_log = sim0                     # simulated time at the last progress line
        progress = open(os.path.join(self.run_dir, 'progress.csv'), 'a')
        if progress.tell() == 0:
            progress.write('time_s,grains,contacts,sweeps,residual,wall_s\n')
        while clock.time() < t_stop - 0.5 * p['dt'] and not stop.name:
            if feeder.count < p['n_grains'] and clock.iter() % period == 0:
                feeder.create()
            steps = period - clock.iter() % period
            if snaps:
                steps = min(steps, max(1, int(round((snaps[0] - clock.time()) / p['dt']))))
            for t_next in ([t_stop, t_feed_end] if keep_end else [t_stop]):
                steps = min(steps, max(1, int(round((t_next - clock.time()) / p['dt']))))
            O.run(steps, True)
            t = clock.time()
            if snaps and t >= snaps[0] - 0.5 * p['dt']:
                tag = '%.3f' % snaps.pop(0)
                snapshot(os.path.join(self.run_dir, 'snap_%08.3f.npz' % t), self.births, p, t)
                if p['vtk']:
                    from yade import export
                    export.VTKExporter(os.path.join(self.run_dir, 'vtk_%08.3f' % t)).exportSpheres(what=dict(vel='b.state.vel'))
                self.done_snaps.add(tag)
            if keep_end and t >= t_feed_end - 0.5 * p['dt']:
                self.keep_feed_end()
                keep_end, last_ck = False, time.time()
            now = time.time()
            if now - last_log > 10 or t >= t_stop - 0.5 * p['dt']:
                rate = (t - sim0) / max(now - wall0, 1e-9)
                # the cost of a simulated second now (since the last line), grown with the grain count
                recent = (now - last_log) / (t - t_log) if t > t_log else float('inf')
                eta = eta_seconds(t, t_end, t_feed_end, recent) if math.isfinite(recent) else float('inf')
                contacts, sweeps, residual = solver_stats()
                self.log('t=%7.3f s  grains %6d/%d  contacts %6d  sweeps %4d  residual %.1e  %.3f sim-s/s  ETA %s'
                         % (t, feeder.count, p['n_grains'], contacts, sweeps, residual, rate,
                            duration(eta)))
                progress.write('%.6f,%d,%d,%d,%.3e,%.1f\n' % (t, feeder.count, contacts, sweeps, residual,
                                                              self.wall_before + now - wall0))  # the run's wall time
                progress.flush()
                last_log, t_log = now, t
            if now - last_ck > p['checkpoint_every']:
                self.checkpoint()
                last_ck = time.time()
        end = time.time()
        self.checkpoint(now=end)
        progress.close()
        p['wall_time_s'] = end - wall0           # this segment's (a resumed run: since the resume)
        p['wall_time_total_s'] = self.wall_before + p['wall_time_s']   # all segments
        p['finished'] = clock.time() >= t_end - 0.5 * p['dt']
        p['unconverged_steps'] = getattr(O.engines[-1], 'nUnconverged', 0)
        if stop.name:
            p['stopped_by'] = stop.name
            self.log('stopped by %s at t=%.4f s with a checkpoint: continue with --resume' % (stop.name, clock.time()))
        else:
            p.pop('stopped_by', None)
        write_json_atomic(os.path.join(self.run_dir, 'run.json'), p)
        return p


class _StopSignals:
    """Within the block, SIGTERM and SIGINT only record their name (``.name``): the run loop
    stops at its next chunk boundary and checkpoints. The previous handlers come back on exit.
    Only the main thread may set handlers; elsewhere nothing is changed."""

    def __init__(self):
        self.name, self.old = None, {}

    def _note(self, signum, frame):
        self.name = signal.Signals(signum).name

    def __enter__(self):
        try:
            for s in (signal.SIGTERM, signal.SIGINT):
                self.old[s] = signal.signal(s, self._note)
        except ValueError:          # not the main thread
            self.old = {}
        return self

    def __exit__(self, *exc):
        for s, h in self.old.items():
            signal.signal(s, h)
        return False


def duration(seconds):
    """'HH:MM:SS', with days in front when longer ('2d 03:04:05'); '?' when unknown."""
    if not math.isfinite(seconds) or seconds >= 1e8:
        return '?'
    days, rest = divmod(int(round(seconds)), 86400)
    return ('%dd ' % days if days else '') + time.strftime('%H:%M:%S', time.gmtime(rest))


def _float(text):
    try:
        return float(text)
    except ValueError:
        return float('inf')


def has_run(run_dir):
    """Whether ``run_dir`` holds a pile run (its run.json, or checkpoints)."""
    return os.path.exists(os.path.join(run_dir, 'run.json')) or has_checkpoint(run_dir)


def clear_run(run_dir, keep=()):
    """Remove a run's own files (run.json, progress, checkpoints, snapshots, VTK) and nothing else."""
    import shutil
    if not os.path.isdir(run_dir):
        return
    for name in os.listdir(run_dir):
        path = os.path.join(run_dir, name)
        if name in keep:
            continue
        if name in RUN_FILES or name.startswith(('snap_', 'vtk_')) or name.endswith('.tmp'):
            if os.path.isdir(path):
                shutil.rmtree(path)
            else:
                os.remove(path)
        elif name in ('ckpt', FEED_END_DIR):
            shutil.rmtree(path)


def branch(src, dest, options, log=print):
    """Start a branch of the pile run in ``src`` in ``dest``: the run's portable part copied
    (:func:`yadecd.runs.carry.carry`, from its newest valid checkpoint), the solver options among
    ``options`` (BRANCH_MAY_CHANGE) applied from that point on; any other option given must equal
    the source's. ``run.json`` of the branch keeps the source's parameters and history
    (progress, segments) and lists, under ``branches``, where it left its source: the source,
    the simulated time, the checkpoint, and each changed option as [before, after]. Continue it
    with ``resume``. Used to run a faster solver setting from a long run's state and compare
    the two, or to finish a run at that setting.

    :raises FileNotFoundError: ``src`` holds no run.json.
    :raises ValueError: an option outside BRANCH_MAY_CHANGE that differs from the source's, or a bad value.
    :raises FileExistsError: ``dest`` already holds a run (a branch never replaces one)."""
    from ..runs.carry import carry
    src_json = os.path.join(src, 'run.json')
    if not os.path.exists(src_json):
        raise FileNotFoundError('nothing to branch from in %s: it holds no run.json' % src)
    with open(src_json) as f:
        before = dict(defaults(), **upgrade(json.load(f)))
    options = upgrade({k: v for k, v in options.items() if v is not None})
    unknown = sorted(set(options) - set(defaults()))
    if unknown:
        raise ValueError('unknown pile parameters: %s' % ', '.join(unknown))
    clash = ['%s (source: %r, given: %r)' % (k, before.get(k), v) for k, v in sorted(options.items())
             if k not in BRANCH_MAY_CHANGE and before.get(k) != v]
    if clash:
        raise ValueError('a branch may change only %s; these differ from %s: %s'
                         % (', '.join(BRANCH_MAY_CHANGE), src, ', '.join(clash)))
    changes = {k: v for k, v in options.items() if k in BRANCH_MAY_CHANGE and before.get(k) != v}
    check_params({k: v for k, v in dict(before, **changes).items() if k in defaults()})
    if has_run(dest):
        raise FileExistsError('%s already holds a pile run: a branch never replaces one' % dest)
    record = carry(src, dest, log=log)
    path = os.path.join(dest, 'run.json')
    with open(path) as f:
        p = json.load(f)
    p.setdefault('branches', []).append({
        'source': os.path.abspath(src), 'time': record['time'], 'checkpoint': record['checkpoint'],
        'changes': {k: [before.get(k), v] for k, v in sorted(changes.items())}})
    p.update(changes)
    write_json_atomic(path, p)
    log('branch %s of %s at t=%.3f s: %s' % (dest, src, record['time'], ', '.join(
        '%s %r -> %r' % (k, before.get(k), v) for k, v in sorted(changes.items())) or 'no option changed'))
    return p


def run(run_dir, resume=False, log=print, overwrite=False, branch_from=None, **overrides):
    """Build (or resume) a pile in ``run_dir``; returns the run's parameter dict.

    Every check happens before the first step: bad parameters (ValueError), an existing run
    without ``resume`` or ``overwrite`` (FileExistsError), options that differ from the run being
    resumed (ValueError), an unwritable or too-full directory (CheckpointError). Progress lines
    give simulated time, grains, contacts, Gauss–Seidel sweeps and residual of the last step, the
    wall-clock rate and the ETA (the current cost of a simulated second, grown with the grain
    count: :func:`eta_seconds`). Snapshots go to ``snap_<t>.npz``; checkpoints to ``ckpt/``.
    ``branch_from``: start ``run_dir`` as a :func:`branch` of that run (the solver options among
    ``overrides`` changed), then continue it; other options must match the source's."""
    if branch_from is not None:
        branch(branch_from, run_dir, overrides, log)
        overrides = {k: v for k, v in overrides.items() if k in RESUME_MAY_CHANGE}
        resume = True
    if resume:
        return PileRun.resume(run_dir, overrides, log).advance()
    r = PileRun.start(run_dir, overrides, log, overwrite=overwrite)
    return r.advance()

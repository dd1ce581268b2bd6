"""Atomic, verified checkpoints for long runs (pure Python: no YADE, no numpy).

A checkpoint is one consistent unit: a directory ``<run>/ckpt/<seq>/`` holding the files of the
state (written by callables the caller gives) and ``meta.json`` with their SHA-256 digests. It is
written under a temporary name, flushed, renamed, read back and verified; only then does the
pointer ``<run>/ckpt/current.json`` switch to it. The previous good checkpoint is kept until the
next one is verified (``keep`` units are kept). On reading, a damaged or truncated unit (a digest
that does not match, a missing file, unreadable metadata) is reported, moved aside as
``<seq>.damaged`` (kept for inspection, never read again) and the next older one is used; a
damaged pointer is replaced by a scan of the units.

A kill at any moment leaves either the old pointer (the new unit is a ``.tmp`` directory or an
unreferenced unit, both ignored or reused) or the new one (the unit is complete and verified).
A full disk or an unwritable directory raises :class:`CheckpointError` naming the cause, with
the last good checkpoint untouched.
"""
import errno
import hashlib
import json
import os
import shutil
import time

from ..io import fsync_dir, write_json_atomic

FORMAT = 'yadecd-checkpoint'
FORMAT_VERSION = 1
POINTER = 'current.json'


class CheckpointError(RuntimeError):
    """A checkpoint could not be written, or no valid checkpoint could be read."""


def sha256(path, chunk=1 << 20):
    """Hex SHA-256 digest of a file."""
    h = hashlib.sha256()
    with open(path, 'rb') as f:
        for block in iter(lambda: f.read(chunk), b''):
            h.update(block)
    return h.hexdigest()


class CheckpointStore:
    """The checkpoints of one run directory.

    :param run_dir: the run's directory (``ckpt/`` is created inside).
    :param keep: verified units kept (at least 2: the newest and the one before it).
    """

    def __init__(self, run_dir, keep=2):
        if keep < 2:
            raise ValueError('keep must be at least 2 (the previous checkpoint is kept until the next is verified)')
        self.root = os.path.join(os.path.abspath(run_dir), 'ckpt')
        self.keep = keep
        self.messages = []          # what reading had to skip, for the run's log

    # ------------------------------------------------------------------ writing
    def _units(self):
        """Sequence numbers of the complete-looking units, newest first."""
        if not os.path.isdir(self.root):
            return []
        seqs = [int(n) for n in os.listdir(self.root) if n.isdigit() and os.path.isdir(os.path.join(self.root, n))]
        return sorted(seqs, reverse=True)

    def _pointer(self):
        try:
            with open(os.path.join(self.root, POINTER)) as f:
                p = json.load(f)
            return int(p['current']), p
        except (OSError, ValueError, KeyError, TypeError):
            return None, None

    def write(self, writers, meta=None):
        """Write one checkpoint unit and switch the pointer to it.

        :param writers: dict file name -> callable(path) that writes that file.
        :param meta: JSON-ready dict stored in ``meta.json`` (run parameters, counters...).
        :returns: the new unit's sequence number.
        :raises CheckpointError: the disk is full, the directory unwritable, a writer failed, or
            the unit did not verify; the previous checkpoint is left as it was.
        """
        units = self._units()
        seq = (units[0] + 1) if units else 1
        final = os.path.join(self.root, '%06d' % seq)
        tmp = final + '.tmp'
        try:
            os.makedirs(self.root, exist_ok=True)
            shutil.rmtree(tmp, ignore_errors=True)
            os.makedirs(tmp)
            digests = {}
            for name, writer in writers.items():
                if os.sep in name or name in ('meta.json', POINTER):
                    raise ValueError('bad checkpoint file name %r' % name)
                path = os.path.join(tmp, name)
                writer(path)
                if not os.path.isfile(path):
                    raise CheckpointError('checkpoint writer for %r wrote no file' % name)
                fsync_dir(path)
                digests[name] = sha256(path)
            info = {'format': FORMAT, 'format_version': FORMAT_VERSION, 'seq': seq, 'written_unix': time.time(),
                    'files': digests, 'meta': meta or {}}
            write_json_atomic(os.path.join(tmp, "meta.json"), info, sort_keys=True)
            os.replace(tmp, final)
            fsync_dir(self.root)
            problem = self._verify(final)
            if problem:
                raise CheckpointError('checkpoint %d did not verify after writing: %s' % (seq, problem))
            previous, _ = self._pointer()
            write_json_atomic(os.path.join(self.root, POINTER), {'current': seq, 'previous': previous}, sort_keys=True)
        except OSError as e:
            shutil.rmtree(tmp, ignore_errors=True)
            if e.errno == errno.ENOSPC:
                cause = 'the disk is full'
            elif e.errno in (errno.EACCES, errno.EROFS, errno.EPERM):
                cause = 'the directory is not writable'
            else:
                cause = str(e)
            raise CheckpointError('checkpoint not written in %s: %s; the last good checkpoint (%s) is intact'
                                  % (self.root, cause, self._pointer()[0])) from e
        except Exception:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        self._prune(seq)
        return seq

    def _prune(self, newest):
        for seq in self._units():
            if seq <= newest - self.keep:
                shutil.rmtree(os.path.join(self.root, '%06d' % seq), ignore_errors=True)
        for name in os.listdir(self.root):
            if name.endswith('.tmp') and os.path.isdir(os.path.join(self.root, name)):
                shutil.rmtree(os.path.join(self.root, name), ignore_errors=True)

    # ------------------------------------------------------------------ reading
    def _verify(self, unit_dir):
        """'' when the unit is complete and every digest matches, else what is wrong."""
        try:
            with open(os.path.join(unit_dir, 'meta.json')) as f:
                info = json.load(f)
        except (OSError, ValueError) as e:
            return 'meta.json unreadable (%s)' % e
        if info.get('format') != FORMAT:
            return 'not a %s unit' % FORMAT
        if info.get('format_version', 0) > FORMAT_VERSION:
            return 'format version %s is newer than this plugin reads (%d)' % (info.get('format_version'), FORMAT_VERSION)
        for name, digest in info.get('files', {}).items():
            path = os.path.join(unit_dir, name)
            if not os.path.isfile(path):
                return '%s is missing' % name
            if sha256(path) != digest:
                return '%s is damaged (digest mismatch)' % name
        return ''

    def latest(self):
        """The newest valid checkpoint: (seq, unit directory, meta.json dict), or None when the run
        has none. Skipped units are described in ``self.messages``.

        :raises CheckpointError: checkpoints exist but none is valid."""
        self.messages = []
        current, pointer = self._pointer()
        units = self._units()
        if pointer is None and os.path.exists(os.path.join(self.root, POINTER)):
            self.messages.append('checkpoint pointer damaged: scanning the checkpoint units')
        order = ([current] if current in units else []) + [u for u in units if u != current]
        if current is not None and current not in units:
            self.messages.append('checkpoint pointer names unit %d, which is missing' % current)
        for seq in order:
            unit = os.path.join(self.root, '%06d' % seq)
            problem = self._verify(unit)
            if not problem:
                if seq != current:             # the pointer named a damaged or missing unit: repair it
                    try:
                        write_json_atomic(os.path.join(self.root, POINTER), {'current': seq, 'previous': None}, sort_keys=True)
                    except OSError:
                        pass
                with open(os.path.join(unit, 'meta.json')) as f:
                    return seq, unit, json.load(f)
            aside = unit + '.damaged'          # kept for inspection, never read again
            try:
                shutil.rmtree(aside, ignore_errors=True)
                os.replace(unit, aside)
                problem += ' (moved aside to %s)' % os.path.basename(aside)
            except OSError:
                pass
            self.messages.append('checkpoint %d skipped: %s' % (seq, problem))
        if units:
            raise CheckpointError('no valid checkpoint in %s: %s' % (self.root, '; '.join(self.messages)))
        return None


def has_checkpoint(run_dir):
    """Whether ``run_dir`` holds a checkpoint to resume from: a unit of this store, or a
    first-release ``checkpoint.json``."""
    root = os.path.join(run_dir, 'ckpt')
    if os.path.isdir(root) and any(n.isdigit() or n == POINTER for n in os.listdir(root)):
        return True
    return os.path.exists(os.path.join(run_dir, 'checkpoint.json'))

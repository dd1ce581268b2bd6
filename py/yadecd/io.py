"""Writing files that must survive a kill, and benchmark records that say where they came from.

One helper per mechanism, used by every module and script:

- :func:`fsync_dir`, :func:`write_json_atomic`, :func:`write_bytes_atomic`: a file is written
  under a temporary name, flushed and fsynced, renamed over its target, and the directory entry
  fsynced, so that a kill or a power cut leaves either the old file or the new one, never half.
- :func:`jsonable`: a JSON-ready copy of numbers computed with numpy (nan and inf become null).
- :func:`write_csv`: measurement records (benchmarks, sweeps), every row carrying the machine,
  the commit and the date it was measured on (:func:`provenance`).
- :func:`host_description`: this machine's name and processor.

Pure Python (numpy only for :func:`jsonable`): imports without YADE.
"""
import csv
import datetime
import json
import math
import os
import platform
import socket
import subprocess

__all__ = ['fsync_dir', 'write_json_atomic', 'write_bytes_atomic', 'jsonable', 'host_description', 'append_csv',
           'provenance', 'write_csv', 'PROVENANCE_FIELDS']


def fsync_dir(path):
    """fsync the directory ``path`` (makes a rename in it durable)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_bytes_atomic(path, data):
    """Write ``data`` (bytes) to ``path`` atomically and durably (temporary file, fsync, rename,
    fsync of the directory)."""
    tmp = path + '.tmp'
    with open(tmp, 'wb') as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    fsync_dir(os.path.dirname(os.path.abspath(path)))


def write_json_atomic(path, data, sort_keys=False, indent=1):
    """Write ``data`` as JSON to ``path`` atomically and durably (see :func:`write_bytes_atomic`).
    Numpy values are converted by :func:`jsonable`."""
    text = json.dumps(jsonable(data), indent=indent, sort_keys=sort_keys)
    write_bytes_atomic(path, text.encode())


def jsonable(value):
    """JSON-ready copy: numpy scalars and arrays to Python, nan and inf to None."""
    import numpy as np
    if isinstance(value, dict):
        return {k: jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    return value


def rss_mb(pid=None):
    """Resident memory (VmRSS) of process ``pid`` (default: this one) in MB, from /proc; nan where
    /proc does not say."""
    with open('/proc/%s/status' % ('self' if pid is None else int(pid))) as f:
        for line in f:
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024.0
    return float('nan')


def host_description():
    """(host name, CPU model and clock) of this machine."""
    info = {}
    try:
        with open('/proc/cpuinfo') as f:
            for line in f:
                key, _, value = line.partition(':')
                info.setdefault(key.strip(), value.strip())
    except OSError:
        pass
    cpu = info.get('model name') or platform.machine()
    return socket.gethostname(), cpu + (' @ %s MHz' % info['cpu MHz'].split('.')[0] if 'cpu MHz' in info else '')


PROVENANCE_FIELDS = ('measured_utc', 'host', 'cpu', 'commit')


def _commit():
    here = os.path.dirname(os.path.abspath(__file__))
    try:
        out = subprocess.run(['git', '-C', here, 'rev-parse', '--short=12', 'HEAD'], capture_output=True,
                             text=True, timeout=10)
        dirty = subprocess.run(['git', '-C', here, 'status', '--porcelain', '--untracked-files=no'],
                               capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return 'unknown'
    if out.returncode != 0:
        return 'unknown'    # an installed copy, outside a checkout
    return out.stdout.strip() + ('+dirty' if dirty.stdout.strip() else '')


def provenance():
    """Where and when a measurement is made: {'measured_utc', 'host', 'cpu', 'commit'} (the
    checkout's commit, '+dirty' when it has uncommitted changes, 'unknown' outside a checkout)."""
    host, cpu = host_description()
    return {'measured_utc': datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%dT%H:%M:%SZ'),
            'host': host, 'cpu': cpu, 'commit': _commit()}


def write_csv(path, rows, log=print, stamp=True):
    """Write ``rows`` (dicts with the same keys, in the order of the first) to the CSV file
    ``path``, creating its directory, atomically; says where. With ``stamp`` (the default) every
    row also carries :data:`PROVENANCE_FIELDS` (the machine, the commit and the date of the
    measurement), unless it has them already."""
    if not rows:
        raise ValueError('write_csv: no rows to write to %s' % path)
    if stamp:
        prov = provenance()
        rows = [dict(r, **{k: v for k, v in prov.items() if k not in r}) for r in rows]
    fields = list(rows[0])
    for r in rows[1:]:
        fields += [k for k in r if k not in fields]
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    tmp = path + '.tmp'
    with open(tmp, 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)
    os.replace(tmp, path)
    log('wrote %s' % path)
    return path


def append_csv(path, row, fields, start=False, stamp=True):
    """Append one record ``row`` (a dict over ``fields``) to the CSV file ``path``, for
    measurements written as they come (a crash loses nothing). ``start``: begin the file anew
    (directory created, header written). With ``stamp`` the row also carries
    :data:`PROVENANCE_FIELDS`, which the header then lists after ``fields``."""
    fields = list(fields) + ([k for k in PROVENANCE_FIELDS if k not in fields] if stamp else [])
    if start or not os.path.exists(path):
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        with open(path, 'w', newline='') as f:
            csv.DictWriter(f, fieldnames=fields).writeheader()
    if row is None:
        return path
    if stamp:
        row = dict(row, **{k: v for k, v in _provenance_cached().items() if k not in row})
    with open(path, 'a', newline='') as f:
        csv.DictWriter(f, fieldnames=fields, extrasaction='raise').writerow(row)
    return path


_PROVENANCE = None


def _provenance_cached():
    """:func:`provenance`, asked of git once per process (the time is the first row's)."""
    global _PROVENANCE
    if _PROVENANCE is None:
        _PROVENANCE = provenance()
    return _PROVENANCE

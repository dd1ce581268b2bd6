#!/usr/bin/env python3
"""Carry a pile run between machines (yadecd.runs.carry): its portable part, small enough to commit.

    python3 scripts/pile_carry.py SRC_RUN DEST [--snap-every T] [--every MIN | --stop [--timeout S]]

Copies run.json, progress.csv, the snapshots at multiples of T seconds (all by default; the
newest always) and the newest valid checkpoint reduced to its state.npz (YADE's archive is left
out) into DEST, replacing it whole. Continue the copy with
``scripts/yade -n -x scripts/pile.py --out DEST --resume``; carrying it back to a working
directory is the same command. With ``--every MIN`` it carries again every MIN minutes, only
when the run has moved on (a new checkpoint or snapshot, its end), until the run is done and
carried: start it beside a long pile so that the pile outlives the machine. With ``--stop`` it
ends the pile first: SIGTERM to the process running SRC_RUN (``pile.py --out SRC_RUN``; it writes a
checkpoint and stops), then the carry of that checkpoint: the end of a session in one command.
Needs no YADE and no numpy.
"""
import argparse
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

from yadecd.runs.carry import carry, stop_and_carry, watch  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('src', help='run directory to carry (holds run.json and ckpt/)')
    ap.add_argument('dest', help='destination directory (replaced whole)')
    ap.add_argument('--snap-every', type=float, default=None,
                    help='carry only the snapshots at multiples of this many seconds (and the newest); default all')
    ap.add_argument('--every', type=float, default=None, metavar='MIN',
                    help='carry again every MIN minutes (when the run has moved on) until it is done and carried')
    ap.add_argument('--stop', action='store_true',
                    help='first SIGTERM the process running SRC (it checkpoints and stops) and wait for it')
    ap.add_argument('--timeout', type=float, default=600.0, metavar='S',
                    help='with --stop: seconds to wait for the pile to stop (default 600)')
    a = ap.parse_args(argv)
    if a.stop and a.every is not None:
        ap.error('--stop and --every do not go together (stop a pile, or carry it while it runs)')
    if not a.timeout > 0:
        ap.error('--timeout must be a positive number of seconds')
    if a.every is not None and not a.every > 0:
        ap.error('--every must be a positive number of minutes')
    if a.snap_every is not None and not a.snap_every > 0:
        ap.error('--snap-every must be a positive time in seconds')
    try:
        if a.stop:
            stop_and_carry(a.src, a.dest, snap_every=a.snap_every, timeout=a.timeout, log=lambda m: print(m, flush=True))
        elif a.every is None:
            carry(a.src, a.dest, snap_every=a.snap_every)
        else:
            watch(a.src, a.dest, a.every, snap_every=a.snap_every, log=lambda m: print(m, flush=True))
    except (OSError, ValueError, RuntimeError) as e:
        raise SystemExit('pile_carry: %s' % e)


if __name__ == '__main__':
    main()

#!/usr/bin/env python3
"""Sweeps to the tolerance of saved steps under solver-option variants of the core benchmark.
Sweep counts do not depend on the machine's load (the same bits on any run), so this needs no
quiet machine; one step's count moves with rounding by up to 2x either way (docs/performance.md),
so variants are ranked on the total over many steps.

    /usr/bin/python3 scripts/bench/sweep_counts.py /work/steps/full60_*.cdp ... \\
        --variant w50='--stall-window 50' --variant w30='--stall-window 30' \\
        --bench build/cd_core_bench --csv docs/data/stall_window_steps.csv

Each --variant is NAME='cd_core_bench options'; the first is the reference of the ratios printed.
"""
import argparse
import os
import shlex
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(__file__)), '..', '..', 'py'))  # this checkout's yadecd

from yadecd.io import write_csv  # noqa: E402
from core_ab import parse  # noqa: E402  (this directory's: the figures of a cd_core_bench report)


def sweeps(bench, path, options, threads=1):
    """Sweeps of the core benchmark's solve of the step ``path`` with ``options`` (a list)."""
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    cmd = [bench, path, '--repeat', '1', '--k1', '1', '--k2', '2'] + options
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    figures = parse(proc.stdout)
    if proc.returncode != 0 or 'sweeps' not in figures:
        raise RuntimeError('%s failed or gave no sweep count:\n%s' % (' '.join(cmd), proc.stdout[-2000:] + proc.stderr[-2000:]))
    return int(figures['sweeps'])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('steps', nargs='+', help='saved steps (.cdp)')
    ap.add_argument('--variant', action='append', required=True, help="NAME='options' (repeatable; the first is the reference)")
    ap.add_argument('--bench', default='build/cd_core_bench')
    ap.add_argument('--threads', type=int, default=1)
    ap.add_argument('--csv', required=True)
    args = ap.parse_args()
    variants = []
    for v in args.variant:
        name, sep, opts = v.partition('=')
        if not sep or not name:
            sys.exit('--variant must be NAME=options, not %r' % v)
        variants.append((name, shlex.split(opts)))
    missing = [s for s in args.steps if not os.path.exists(s)]
    if missing:
        sys.exit('no such step file: %s' % ', '.join(missing))
    rows = []
    for path in args.steps:
        row = dict(step=os.path.basename(path))
        for name, opts in variants:
            row[name] = sweeps(args.bench, path, opts, args.threads)
        print(', '.join('%s %s' % kv for kv in row.items()), flush=True)
        rows.append(dict(row, threads=args.threads))
    ref = variants[0][0]
    total = {name: sum(r[name] for r in rows) for name, _ in variants}
    print('total sweeps: ' + ', '.join('%s %d (%.3f)' % (n, t, t / total[ref]) for n, t in total.items()))
    print('steps with fewer sweeps than %s: ' % ref + ', '.join(
        '%s %d of %d' % (n, sum(r[n] < r[ref] for r in rows), len(rows)) for n, _ in variants[1:]))
    write_csv(args.csv, rows)       # with the machine, commit and date


if __name__ == '__main__':
    main()

#!/usr/bin/env python3
"""Siconos' 3D frictional-contact solvers on saved steps of the engine: iterations and time to
the engine's own accuracy, from the engine's warm start.

    /usr/bin/python3 scripts/bench/siconos_solvers.py STEP.hdf5 [STEP.hdf5 ...]
        [--solvers NSGS,ADMM,NSN_AC,PROX,VI_EG,VI_FPP] [--start guess|zero]
        [--budgets 25,50,100,200,400,800,1600] [--max-seconds 900] [--max-memory-gb 6]
        [--out docs/data/siconos_solvers.csv]

STEP.hdf5 is a step's problem in FCLIB's layout with the engine's solution and its warm start as
the guess, as ``scripts/bench/siconos_crosscheck.py --export-only`` writes it. Every solver starts
from the guess (or zero) and runs at Siconos' default options for each iteration budget in turn
(its own stopping test made unreachable), until the common residual (``yadecd.export.fclib.residual``:
Siconos' relative natural-map error, rho = 1) is at most the engine's on the same step, or its
budgets or ``--max-seconds`` are spent. One CSV row per run: the budget, the iterations done, the
seconds, the residual reached. A budget that reaches the engine's residual bounds the iterations
needed from above (within the factor between two budgets). Each solver runs in a child process
whose address space is capped at ``--max-memory-gb`` (Siconos' semismooth Newton built a
24 GB Jacobian on a 37 000-contact step and was killed by the kernel, beside two running piles):
a solver that dies gets a row saying how, and the others still run.

One NSGS iteration is one sweep over the contacts, as one of the engine's sweeps is; the other
methods' iterations cost one or more products with W, a linear solve or a Newton step, so the
seconds, measured in one run on the same machine, are the comparison across methods. Needs
Siconos' Python module (Debian's python3-siconos, installed by the set-up) and h5py; no YADE.
"""
import argparse
import multiprocessing
import os
import resource
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd (README: which yadecd)
from yadecd.export import fclib  # noqa: E402
from yadecd.io import append_csv  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.realpath(sys.argv[0]))))
FIELDS = ['file', 'contacts', 'solver', 'start', 'budget', 'iterations', 'seconds', 'residual',
          'engine_residual', 'reached', 'siconos_info']   # then yadecd.io's provenance (time, host, cpu, commit)


def positive_ints(text):
    values = [int(v) for v in text.split(',') if v.strip()]
    if not values or min(values) < 1 or values != sorted(set(values)):
        raise argparse.ArgumentTypeError('need increasing positive integers, e.g. 25,50,100')
    return values


def solver_names(text):
    names = [v.strip().upper() for v in text.split(',') if v.strip()]
    bad = [v for v in names if v not in fclib.SICONOS_SOLVERS]
    if not names or bad:
        raise argparse.ArgumentTypeError('unknown solver(s) %s; known: %s' % (', '.join(bad) or '(none)', ', '.join(fclib.SICONOS_SOLVERS)))
    return names


def runs_to_target(W, q, mu, r0, target, solver, budgets, max_seconds, log=print):
    """Run ``solver`` from ``r0`` for each budget in turn until the common residual is at most
    ``target``, the budgets are spent, or the next run would likely pass ``max_seconds`` in all
    (estimated from the last run's seconds per iteration). Yields one dict per run."""
    spent = 0.0
    for k, budget in enumerate(budgets):
        s = fclib.solve_siconos(W, q, mu, tol=1e-300, max_iter=budget, r0=r0, solver=solver)
        res = fclib.residual(W, q, mu, s['r'])
        spent += s['seconds']
        row = dict(budget=budget, iterations=s['iterations'], seconds=s['seconds'], residual=res,
                   reached=bool(res <= target), siconos_info=s['info'])
        log('  %-7s budget %5d: %5d iterations, %8.2f s, residual %.3e%s'
            % (solver, budget, s['iterations'], s['seconds'], res, '  (reached the engine\'s)' if row['reached'] else ''))
        yield row
        if row['reached'] or not np.isfinite(res):
            return
        per_iteration = s['seconds'] / max(s['iterations'], 1)
        nxt = budgets[k + 1] if k + 1 < len(budgets) else None
        if nxt is not None and spent + per_iteration * nxt > max_seconds:
            log('  %-7s stopped: the next budget (%d) would pass --max-seconds' % (solver, nxt))
            return


def solver_child(W, q, mu, r0, target, solver, budgets, max_seconds, max_bytes, write):
    """Body of the child process of one solver: address space capped, rows written as they come."""
    resource.setrlimit(resource.RLIMIT_AS, (max_bytes, max_bytes))
    for row in runs_to_target(W, q, mu, r0, target, solver, budgets, max_seconds, log=lambda m: print(m, flush=True)):
        write(row)


def run_solver(W, q, mu, r0, target, solver, budgets, max_seconds, max_bytes, write):
    """:func:`solver_child` in a forked process; a child that dies (out of memory, a crash in
    Siconos) is reported as one more row (``siconos_info``: how it died). Returns its exit code."""
    child = multiprocessing.get_context('fork').Process(
        target=solver_child, args=(W, q, mu, r0, target, solver, budgets, max_seconds, max_bytes, write))
    child.start()
    child.join()
    if child.exitcode != 0:
        how = 'died: signal %d' % -child.exitcode if child.exitcode < 0 else 'died: exit %d (memory cap %.1f GB?)' % (
            child.exitcode, max_bytes / 2 ** 30)
        print('  %-7s %s' % (solver, how), flush=True)
        write(dict(budget='', iterations='', seconds='', residual=float('nan'), reached=False, siconos_info=how))
    return child.exitcode


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('steps', nargs='+', help='FCLIB files (siconos_crosscheck.py --export-only)')
    ap.add_argument('--solvers', type=solver_names, default=list(fclib.SICONOS_SOLVERS))
    ap.add_argument('--start', choices=('guess', 'zero'), default='guess', help="the engine's warm start (the file's guess) or zero")
    ap.add_argument('--budgets', type=positive_ints, default=[25, 50, 100, 200, 400, 800, 1600])
    ap.add_argument('--max-seconds', type=float, default=900.0, help='per solver and step')
    ap.add_argument('--max-memory-gb', type=float, default=6.0, help="cap on each solver's address space")
    ap.add_argument('--out', default=os.path.join(REPO, 'docs', 'data', 'siconos_solvers.csv'))
    a = ap.parse_args(argv)
    if not a.max_seconds > 0:
        ap.error('--max-seconds must be > 0')
    if not a.max_memory_gb > 0:
        ap.error('--max-memory-gb must be > 0')
    for path in a.steps:
        try:
            pb = fclib.read(path)
        except (OSError, ValueError) as e:
            ap.error('%s: %s' % (path, e))
        if 'r' not in pb:
            ap.error('%s holds no /solution: the engine\'s residual is the target' % path)
        if a.start == 'guess' and 'guess' not in pb:
            ap.error('%s holds no /guesses (write it with siconos_crosscheck.py --export-only), or use --start zero' % path)
        W, q, mu = pb['W'], pb['q'], pb['mu']
        target = fclib.residual(W, q, mu, pb['r'])
        r0 = pb['guess'] if a.start == 'guess' else np.zeros_like(q)
        print('%s: %d contacts, engine residual %.3e, start %s (residual %.3e)'
              % (path, len(mu), target, a.start, fclib.residual(W, q, mu, r0)), flush=True)
        for solver in a.solvers:
            t0 = time.perf_counter()
            common = dict(file=os.path.basename(path), contacts=len(mu), solver=solver, start=a.start, engine_residual=target)
            run_solver(W, q, mu, r0, target, solver, a.budgets, a.max_seconds, int(a.max_memory_gb * 2 ** 30),
                       lambda row: append_csv(a.out, dict(row, **common), FIELDS))
            print('  %-7s %.1f s in all' % (solver, time.perf_counter() - t0), flush=True)
    print('wrote', a.out)
    return 0


if __name__ == '__main__':
    sys.exit(main())

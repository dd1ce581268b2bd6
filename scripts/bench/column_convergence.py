"""What the Gauss–Seidel tolerance guarantees on a tall column (cold start, one step).

    yade -n -x scripts/bench/column_convergence.py [--n 10 40 160] [--out docs/data/column_convergence.csv]

For a column of n equal spheres resting on a wall, started at rest with no warm start, one CD
step is solved with several tolerances. The exact floor force is n·m·g; the table reports the
sweeps taken, the residual reached and the relative floor-force error, then the same for a
warm-started sequence of steps (the way a simulation actually runs). Prints and saves CSV.
"""
import argparse
import sys
import time

from yade import O
import os
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', '..', 'py'))  # this checkout's yadecd (README: which yadecd)
import yadecd
from yadecd import scenes  # noqa: E402
from yadecd.io import write_csv  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument('--n', type=int, nargs='+', default=[10, 40, 160])
ap.add_argument('--tolerances', type=float, nargs='+', default=[1e-2, 1e-3, 1e-4, 1e-6, 1e-8])
ap.add_argument('--max-iter', type=int, default=200000)
ap.add_argument('--out', default='docs/data/column_convergence.csv')
a = ap.parse_args(sys.argv[1:])

rows = []
print('%5s %8s %8s %10s %12s %10s %s' % ('n', 'tol', 'mode', 'sweeps', 'residual', 'floor err', 'ms'))
for n in a.n:
    for tol in a.tolerances:
        for mode in ('cold', 'warm20'):
            sc = scenes.column(n, tolerance=tol, maxIter=a.max_iter, warnUnconverged=False)
            cd = yadecd.integrator()
            W = n * sc['m'] * 9.81
            t0 = time.time()
            steps = 1 if mode == 'cold' else 20
            sweeps = 0
            for _ in range(steps):
                O.step()
                sweeps += cd.iterations
            ms = (time.time() - t0) * 1e3
            f = O.interactions[0, sc['ids'][0]].phys.normalForce[2]
            err = abs(f / W - 1)
            rows.append(dict(n=n, tolerance=tol, mode=mode, steps=steps, sweeps=sweeps, residual=cd.residual,
                             floor_force_rel_error=err, wall_ms=ms, converged=cd.converged))
            print('%5d %8.0e %8s %10d %12.3e %10.2e %.1f' % (n, tol, mode, sweeps, cd.residual, err, ms))
            sys.stdout.flush()
write_csv(a.out, rows)

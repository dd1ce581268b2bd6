"""Siconos' solvers on FCLIB files (yadecd.export.fclib, scripts/bench/siconos_solvers.py) on a
constructed problem whose solution is known in closed form: contacts that share no body (W block
diagonal), some sticking (r = −W⁻¹q inside the cone, u = 0), some open (q_N > 0: r = 0). The FCLIB
file keeps a guess; every solver offered reaches the exact solution; the script writes its rows,
reports a solver that dies without stopping the others, and names bad input. Needs Siconos (python3-siconos); no YADE scene."""
import csv
import os
import subprocess
import sys
import tempfile
import unittest

import numpy as np
import scipy.sparse as sp

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd.export import fclib


def known_problem():
    """Six independent contacts: four sticking, two open. Returns W, q, mu and the exact r."""
    wn = np.array([1.0, 2.0, 0.5, 4.0, 1.5, 3.0])
    wt = 2.5 * wn                                    # a sphere's tangential block is larger than its normal one
    mu = np.full(6, 0.4)
    q = np.zeros((6, 3))
    q[:, 0] = [-1.0, -2.0, -0.3, -4.0, 0.7, 0.2]     # the last two separate: open
    q[:4, 1] = [0.5, -1.2, 0.1, 2.0]                 # tangential pushes well inside the cones
    q[:4, 2] = [0.3, 0.4, -0.2, -1.0]
    W = sp.block_diag([np.diag([a, b, b]) for a, b in zip(wn, wt)], format='csr')
    r = np.zeros((6, 3))
    r[:4, 0] = -q[:4, 0] / wn[:4]
    r[:4, 1:] = -q[:4, 1:] / wt[:4, None]
    assert np.all(np.hypot(r[:, 1], r[:, 2]) < mu * r[:, 0] + 1e-15)
    return W, q.ravel(), mu, r.ravel()


class TestFclibGuess(unittest.TestCase):

    def test_round_trip_with_guess(self):
        W, q, mu, r = known_problem()
        guess = 0.5 * r
        self.assertLess(fclib.residual(W, q, mu, r), 1e-15)          # the closed form solves it
        self.assertGreater(fclib.residual(W, q, mu, guess), 0.1)
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, 'step.hdf5')
            fclib.write(path, dict(W=W, q=q, mu=mu, r=r, u=W @ r + q), description='known', guess=guess)
            back = fclib.read(path)
            np.testing.assert_array_equal(back['guess'], guess)
            np.testing.assert_array_equal(back['r'], r)
            self.assertEqual((back['W'] != W).nnz, 0)
            fclib.write(path, dict(W=W, q=q, mu=mu, r=r, u=W @ r + q))
            self.assertNotIn('guess', fclib.read(path))
            with self.assertRaisesRegex(ValueError, 'guess has 3 entries'):
                fclib.write(path, dict(W=W, q=q, mu=mu, r=r, u=W @ r + q), guess=np.zeros(3))


class TestSiconosSolvers(unittest.TestCase):

    def test_every_solver_finds_the_solution(self):
        W, q, mu, r = known_problem()
        for name in fclib.SICONOS_SOLVERS:
            with self.subTest(solver=name):
                s = fclib.solve_siconos(W, q, mu, tol=1e-12, max_iter=5000, solver=name)
                self.assertLess(fclib.residual(W, q, mu, s['r']), 1e-8)
                np.testing.assert_allclose(s['r'], r, atol=1e-7)
        with self.assertRaisesRegex(ValueError, "unknown solver 'NEWTON'"):
            fclib.solve_siconos(W, q, mu, solver='NEWTON')

    def test_script(self):
        W, q, mu, r = known_problem()
        script = os.path.join(SCRIPTS, 'bench', 'siconos_solvers.py')
        python = '/usr/bin/python3' if os.path.exists('/usr/bin/python3') else sys.executable
        with tempfile.TemporaryDirectory() as d:
            step, out = os.path.join(d, 'step.hdf5'), os.path.join(d, 'rows.csv')
            # the "engine" stopped at a residual of about 1e-4: the solvers' target
            r_engine = r * (1 + 1e-4)
            fclib.write(step, dict(W=W, q=q, mu=mu, r=r_engine, u=W @ r_engine + q), guess=0.5 * r)
            run = lambda *extra: subprocess.run([python, script, step, '--out', out] + list(extra),  # noqa: E731
                                                capture_output=True, text=True, timeout=300)
            p = run('--solvers', 'NSGS,VI_FPP', '--budgets', '1,25,50')
            self.assertEqual(p.returncode, 0, p.stderr)
            with open(out) as f:
                rows = list(csv.DictReader(f))
            target = fclib.residual(W, q, mu, r_engine)
            self.assertEqual({row['solver'] for row in rows}, {'NSGS', 'VI_FPP'})
            for row in rows:
                self.assertEqual((row['file'], row['contacts'], row['start']), ('step.hdf5', '6', 'guess'))
                self.assertAlmostEqual(float(row['engine_residual']), target, delta=1e-6 * target)
                self.assertEqual(row['reached'] == 'True', float(row['residual']) <= target)
            # a solver stops at the first budget that reaches the target: only the last row of each reached
            for name in ('NSGS', 'VI_FPP'):
                mine = [row for row in rows if row['solver'] == name]
                self.assertEqual([row['reached'] for row in mine], ['False'] * (len(mine) - 1) + ['True'])
            # NSGS solves independent contacts exactly in one sweep
            self.assertEqual(rows[0]['solver'], 'NSGS')
            self.assertEqual((rows[0]['budget'], rows[0]['reached']), ('1', 'True'))
            # a solver that dies (here: no memory left under the cap) gets a row saying so, the next still runs
            os.remove(out)
            p = run('--solvers', 'VI_EG,NSGS', '--budgets', '5', '--max-memory-gb', '0.01')
            self.assertEqual(p.returncode, 0, p.stderr)
            with open(out) as f:
                rows = list(csv.DictReader(f))
            self.assertEqual([row['solver'] for row in rows], ['VI_EG', 'NSGS'])
            for row in rows:
                self.assertRegex(row['siconos_info'], '^died: ')
                self.assertEqual((row['reached'], row['residual']), ('False', 'nan'))
            # bad input names the culprit (argparse's exit 2)
            for extra, culprit in ((['--solvers', 'NSGS,BOGUS'], 'BOGUS'), (['--budgets', '50,25'], 'increasing'),
                                   (['--max-seconds', '0'], '--max-seconds'),
                                   (['--max-memory-gb', '-1'], '--max-memory-gb')):
                p = run(*extra)
                self.assertEqual(p.returncode, 2)
                self.assertIn(culprit, p.stderr)
            fclib.write(step, dict(W=W, q=q, mu=mu, r=r, u=W @ r + q))
            p = run('--solvers', 'NSGS')
            self.assertEqual(p.returncode, 2)
            self.assertIn('/guesses', p.stderr)
            p = run('--solvers', 'NSGS', '--start', 'zero', '--budgets', '5')
            self.assertEqual(p.returncode, 0, p.stderr)


if __name__ == '__main__':
    unittest.main()

"""The engine's frictional contact problem as sparse matrices, in FCLIB's HDF5 layout, and solved
by Siconos — so that any step of a YADE CD run can be checked by an independent solver.

The problem of one step (``ContactDynamicsIntegrator.problem()``) is the local one of FCLIB
(Acary, Brémond, Koziara, Pérignon, "FCLIB: a collection of discrete 3D frictional contact
problems", 2014): find r, u with u = W r + q and, per contact (normal component first),
r ∈ C_μ, û = u + μ|u_T| e_N ∈ C_μ*, r ⊥ û. Restitution enters through the law's W and q, so
the problem is the engine's exactly.

FCLIB file layout written here (what ``fclib_write_local`` / ``fclib_write_solution`` write):
``/fclib_local/spacedim`` (int 3), ``/fclib_local/W/{nzmax, m, n, nz, p, i, x}`` (compressed
columns, ``nz = -1``, 32-bit integers), ``/fclib_local/vectors/{q, mu}``,
``/fclib_local/info/{title, description, math_info}`` (strings), when a solution is given,
``/solution/{u, r}``, and when a guess is given (the engine's warm start, say),
``/guesses/number_of_guesses`` = 1 and ``/guesses/1/{u, r}`` (what ``fclib_write_guesses`` writes).

Pure numpy/scipy/h5py; Siconos (Debian's ``python3-siconos``) only in :func:`solve_siconos`.
"""
import time
import warnings

import numpy as np
import scipy.sparse as sp

__all__ = ['local_problem', 'write', 'read', 'residual', 'solve_siconos']


def local_problem(engine=None):
    """The last step's problem of ``engine`` (default: the scene's CD integrator) as a dict:
    ``W`` (scipy CSR, 3n×3n), ``q``, ``mu``, ``r`` (the engine's impulses), ``u = W r + q``, ``ids``."""
    if engine is None:
        from .. import integrator
        engine = integrator()
    raw = engine.problem()
    n3 = len(raw['q'])
    W = sp.coo_matrix((raw['vals'], (raw['rows'], raw['cols'])), shape=(n3, n3)).tocsr()
    W.sum_duplicates()
    r = raw['r']
    return dict(W=W, q=raw['q'], mu=raw['mu'], r=r, u=W @ r + raw['q'], ids=raw['ids'])


def write(path, problem, title='', description='', math_info='', solution=True, guess=None):
    """Write ``problem`` (a :func:`local_problem` dict) to the FCLIB HDF5 file ``path``
    (overwritten). ``solution``: also store the engine's (r, u) as ``/solution``. ``guess``: an
    impulse vector (3n) stored as FCLIB's one guess, with its u = W r + q."""
    import h5py
    W = sp.csc_matrix(problem['W'])
    W.sum_duplicates()
    q, mu = np.asarray(problem['q'], float), np.asarray(problem['mu'], float)
    if W.shape != (len(q), len(q)) or len(q) != 3 * len(mu):
        raise ValueError('fclib.write: W is %s, q has %d entries, mu %d: need 3n×3n, 3n, n' % (W.shape, len(q), len(mu)))
    i32 = lambda x: np.asarray(x, dtype=np.int32)
    with h5py.File(path, 'w') as f:
        f['/fclib_local/spacedim'] = i32([3])
        g = f.create_group('/fclib_local/W')
        g['nzmax'], g['m'], g['n'], g['nz'] = i32([W.nnz]), i32([W.shape[0]]), i32([W.shape[1]]), i32([-1])
        g['p'], g['i'], g['x'] = i32(W.indptr), i32(W.indices), np.asarray(W.data, float)
        f['/fclib_local/vectors/q'] = q
        f['/fclib_local/vectors/mu'] = mu
        info = f.create_group('/fclib_local/info')
        for key, text in (('title', title), ('description', description), ('math_info', math_info)):
            if text:
                info[key] = np.bytes_(text)
        if solution:
            f['/solution/r'] = np.asarray(problem['r'], float)
            f['/solution/u'] = np.asarray(problem['u'], float)
        if guess is not None:
            g = np.asarray(guess, float)
            if g.shape != q.shape:
                raise ValueError('fclib.write: the guess has %d entries, the problem %d' % (g.size, q.size))
            f['/guesses/number_of_guesses'] = i32([1])
            f['/guesses/1/r'] = g
            f['/guesses/1/u'] = W @ g + q


def read(path):
    """Read a local FCLIB problem: dict with ``W`` (CSR), ``q``, ``mu`` and, when stored,
    ``r`` and ``u`` of ``/solution`` and ``guess`` (the r of the first of ``/guesses``).
    Compressed-column, compressed-row and triplet W."""
    import h5py
    with h5py.File(path, 'r') as f:
        if '/fclib_local' not in f:
            raise ValueError('%s holds no /fclib_local problem (global FCLIB problems are not read)' % path)
        g = f['/fclib_local/W']
        m, n, nz = int(g['m'][0]), int(g['n'][0]), int(g['nz'][0])
        p, i, x = g['p'][()], g['i'][()], g['x'][()]
        if nz == -1:
            W = sp.csc_matrix((x, i, p), shape=(m, n))
        elif nz == -2:
            W = sp.csr_matrix((x, i, p), shape=(m, n))
        elif nz >= 0:  # triplet: p holds column indices, i row indices (CSparse)
            W = sp.coo_matrix((x[:nz], (i[:nz], p[:nz])), shape=(m, n))
        else:
            raise ValueError('%s: unknown FCLIB matrix storage nz=%d' % (path, nz))
        out = dict(W=W.tocsr(), q=f['/fclib_local/vectors/q'][()], mu=f['/fclib_local/vectors/mu'][()])
        if '/solution' in f:
            out['r'], out['u'] = f['/solution/r'][()], f['/solution/u'][()]
        if '/guesses/1/r' in f:
            out['guess'] = f['/guesses/1/r'][()]
    return out


def residual(W, q, mu, r):
    """One residual for every solver: Siconos' relative error of the natural map with ρ = 1,
    sqrt(Σ_α |r_α − P_C(r_α − û_α)|²) / ‖q‖, û = u + μ|u_T| e_N, u = W r + q."""
    r = np.asarray(r, float).reshape(-1, 3)
    u = (W @ r.ravel() + q).reshape(-1, 3)
    mu = np.asarray(mu, float)
    ut = np.hypot(u[:, 1], u[:, 2])
    z = r.copy()
    z[:, 0] -= u[:, 0] + mu * ut
    z[:, 1:] -= u[:, 1:]
    return np.sqrt(((r - project_cone(z, mu)) ** 2).sum()) / max(np.linalg.norm(q), 1e-300)


def project_cone(z, mu):
    """Row-wise Euclidean projection of z (k×3, normal first) onto the cones C_μ."""
    zn, zt = z[:, 0], np.hypot(z[:, 1], z[:, 2])
    out = np.zeros_like(z)
    inside = (zn >= 0) & (zt <= mu * zn)
    out[inside] = z[inside]
    polar = (mu * zt <= -zn) | (zt == 0)
    edge = ~inside & ~polar
    a = (mu[edge] * zt[edge] + zn[edge]) / (1 + mu[edge] ** 2)
    out[edge, 0] = a
    out[edge, 1:] = (mu[edge] * a / zt[edge])[:, None] * z[edge, 1:]
    return out


#: Siconos' 3D frictional-contact solvers :func:`solve_siconos` offers, by short name
#: (``SICONOS_FRICTION_3D_<name>``; Acary, Brémond & Huber, INRIA RR-9118, 2017, compare them):
#: nonsmooth Gauss–Seidel, ADMM, semismooth Newton on Alart–Curnier's function, the proximal-point
#: method, extragradient and fixed-point projection on the variational inequality.
SICONOS_SOLVERS = ('NSGS', 'ADMM', 'NSN_AC', 'PROX', 'VI_EG', 'VI_FPP')


def solve_siconos(W, q, mu, tol=1e-8, max_iter=100000, r0=None, solver='NSGS'):
    """Solve with Siconos (``SICONOS_FRICTION_3D_<solver>``, one of :data:`SICONOS_SOLVERS`;
    default NSGS) from ``r0`` (default 0), at Siconos' default options but ``tol`` and ``max_iter``.
    Returns dict r, u, info (0: converged), iterations, error (Siconos' own), seconds."""
    import siconos.numerics as sn
    if solver not in SICONOS_SOLVERS:
        raise ValueError('solve_siconos: unknown solver %r (one of %s)' % (solver, ', '.join(SICONOS_SOLVERS)))
    n = len(mu)
    with warnings.catch_warnings():  # scipy keeps 32-bit indices; Siconos converts (untimed)
        warnings.filterwarnings('ignore', message='Performance warning')
        problem = sn.FrictionContactProblem(3, n, sp.coo_matrix(W), np.asarray(q, float), np.asarray(mu, float))
    opts = sn.SolverOptions(getattr(sn, 'SICONOS_FRICTION_3D_' + solver))
    opts.iparam[sn.SICONOS_IPARAM_MAX_ITER] = int(max_iter)
    opts.dparam[sn.SICONOS_DPARAM_TOL] = float(tol)
    r = np.zeros(3 * n) if r0 is None else np.array(r0, float)
    u = np.zeros(3 * n)
    t0 = time.perf_counter()
    info = sn.fc3d_driver(problem, r, u, opts)
    seconds = time.perf_counter() - t0
    return dict(r=r, u=u, info=info, iterations=int(opts.iparam[sn.SICONOS_IPARAM_ITER_DONE]),
                error=float(opts.dparam[sn.SICONOS_DPARAM_RESIDU]), seconds=seconds)

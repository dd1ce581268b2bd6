"""Where a step's Gauss–Seidel work goes: the per-contact, per-sweep trace of one solve.

``build/cd_core_bench STEP.cdp --trace PREFIX`` writes, for one solve of a saved step, every
contact's update W_NN|Δr| in every sweep and its natural-map residual after the sweep (both in
m/s, the velocity units of the solver's residual), with each contact's point. This module reads
such a trace and measures how the work is spread:

- ``threshold``: the per-contact scale θ₀ = tolerance·‖q‖/√n, the root-mean-square residual a
  contact may keep when the step just converges (the solver stops at √(Σ|e_k|²)/‖q‖ ≤ tolerance);
- ``active_fraction``: the share of contacts whose update (or residual) exceeds a threshold, sweep
  by sweep;
- ``last_active``: per contact, the last sweep in which it exceeded the threshold;
- ``top_share``: how much of a sweep's Σ(change²) the largest few contacts carry;
- ``binned_mean``: a quantity averaged in (radius, height) bins of the pile, sparse bins masked;
- ``summary`` and ``figure``: the table and the figure of docs/performance.md.

Pure NumPy (Matplotlib for the figure): runs without YADE.
"""
import json
import os

import numpy as np


def load(prefix):
    """The trace written by ``cd_core_bench --trace PREFIX``: a dict with ``change`` and
    ``residual`` (sweeps × contacts, float32, m/s), ``points`` (contacts × 3, m) and ``meta``
    (q_norm, tolerance, sweeps, contacts, up, ...)."""
    paths = {k: '%s_%s' % (prefix, k) for k in ('change.npy', 'residual.npy', 'contacts.csv', 'meta.json')}
    for p in paths.values():
        if not os.path.exists(p):
            raise FileNotFoundError('%s: no such file (write the trace with cd_core_bench STEP --trace %s)' % (p, prefix))
    with open(paths['meta.json']) as f:
        meta = json.load(f)
    change = np.load(paths['change.npy'])
    residual = np.load(paths['residual.npy'])
    points = np.loadtxt(paths['contacts.csv'], delimiter=',', skiprows=1, ndmin=2)[:, :3]
    if change.shape != residual.shape or change.shape[1] != len(points):
        raise ValueError('%s: the trace arrays disagree (change %s, residual %s, %d contacts)'
                         % (prefix, change.shape, residual.shape, len(points)))
    return dict(change=change, residual=residual, points=points, meta=meta)


def threshold(meta):
    """θ₀ = tolerance·‖q‖/√n [m/s]: every contact at θ₀ makes the residual exactly the tolerance."""
    n = int(meta['contacts'])
    if n <= 0:
        raise ValueError('a trace without contacts has no threshold')
    return float(meta['tolerance']) * float(meta['q_norm']) / np.sqrt(n)


def active_fraction(values, theta, sweeps=None):
    """Share of contacts with value > theta in each sweep (1-based ``sweeps``; all when None).
    Sweeps past the end of the solve are NaN (the solve had stopped)."""
    values = np.asarray(values)
    frac = (values > theta).mean(axis=1) if values.shape[1] else np.zeros(len(values))
    if sweeps is None:
        return frac
    return np.array([frac[s - 1] if 1 <= s <= len(frac) else np.nan for s in sweeps])


def last_active(values, theta):
    """Per contact, the last sweep (1-based) in which its value exceeded theta; 0: never."""
    above = np.asarray(values) > theta
    ns = above.shape[0]
    flipped = above[::-1]
    any_above = flipped.any(axis=0)
    return np.where(any_above, ns - np.argmax(flipped, axis=0), 0)


def top_share(row, share):
    """Fraction of Σ row² carried by the largest ``share`` (0–1) of the contacts (at least one
    contact); NaN when the row is all zero."""
    v = np.sort(np.asarray(row, dtype=float) ** 2)[::-1]
    total = v.sum()
    if total == 0:
        return np.nan
    k = max(1, int(round(share * len(v))))
    return v[:k].sum() / total


def cylindrical(points, up=(0, 0, 1), axis_point=None):
    """Radius from the vertical axis through ``axis_point`` (default: the points' mean position
    across ``up``) and height along ``up``."""
    up = np.asarray(up, dtype=float)
    up = up / np.linalg.norm(up)
    p = np.asarray(points, dtype=float)
    z = p @ up
    flat = p - np.outer(z, up)
    centre = flat.mean(axis=0) if axis_point is None else (np.asarray(axis_point, float) - (np.asarray(axis_point, float) @ up) * up)
    return np.linalg.norm(flat - centre, axis=1), z


def binned_mean(r, z, v, r_edges, z_edges, min_count=5):
    """Mean of v over the contacts of each (r, z) bin, and the counts; bins with fewer than
    ``min_count`` contacts are NaN (too few to say)."""
    r, z, v = (np.asarray(a, dtype=float) for a in (r, z, v))
    count, _, _ = np.histogram2d(r, z, bins=[r_edges, z_edges])
    total, _, _ = np.histogram2d(r, z, bins=[r_edges, z_edges], weights=v)
    with np.errstate(invalid='ignore', divide='ignore'):
        mean = total / count
    mean[count < min_count] = np.nan
    return mean, count


def summary(trace, sweeps=(1, 5, 10, 20, 50, 100, 150), factors=(1, 10)):
    """Rows of the work table: per sweep, the shares of contacts whose update and whose residual
    exceed factor·θ₀, and the share of the sweep's Σ change² carried by the top 1 % and 10 %."""
    theta = threshold(trace['meta'])
    ch, res = trace['change'], trace['residual']
    rows = []
    for s in list(sweeps) + [ch.shape[0]]:
        if s > ch.shape[0] or any(r['sweep'] == s for r in rows):
            continue
        row = dict(sweep=s)
        for f in factors:
            row['update>%gθ' % f] = float(active_fraction(ch, f * theta, [s])[0])
            row['residual>%gθ' % f] = float(active_fraction(res, f * theta, [s])[0])
        row['top1%'] = top_share(ch[s - 1], 0.01)
        row['top10%'] = top_share(ch[s - 1], 0.10)
        rows.append(row)
    return rows


def figure(trace, path, title=''):
    """Three panels: the shares of contacts above θ₀ and 10θ₀ sweep by sweep; the last sweep in
    which each (r, z) bin's contacts were still updated by more than θ₀ (bin mean); the share of
    late work (updates² after sweep 20) per bin. Sparse bins are left blank and say so."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    theta = threshold(trace['meta'])
    ch = trace['change']
    ns = ch.shape[0]
    r, z = cylindrical(trace['points'], trace['meta'].get('up', (0, 0, 1)))
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.2))
    s = np.arange(1, ns + 1)
    for f, style in ((1, '-'), (10, '--')):
        ax[0].plot(s, active_fraction(ch, f * theta), 'C0' + style, label='update > %gθ₀' % f)
        ax[0].plot(s, active_fraction(trace['residual'], f * theta), 'C1' + style, label='residual > %gθ₀' % f)
    ax[0].set_xlabel('sweep')
    ax[0].set_ylabel('share of contacts')
    ax[0].set_ylim(0, 1)
    ax[0].legend(fontsize=8)
    ax[0].set_title('contacts still working (θ₀ = tol·‖q‖/√n = %.2g m/s)' % theta, fontsize=9)
    r_edges = np.linspace(0, r.max() * 1.0001 + 1e-12, 25)
    z_edges = np.linspace(z.min(), z.max() * 1.0001 + 1e-12, 17)
    last, _ = binned_mean(r, z, last_active(ch, theta), r_edges, z_edges)
    late = (ch[min(20, ns):].astype(float) ** 2).sum(axis=0)
    late_share, _ = binned_mean(r, z, late / max(late.sum(), 1e-300) * len(late), r_edges, z_edges)
    for a, data, label in ((ax[1], last, 'mean last sweep with update > θ₀'),
                           (ax[2], late_share, 'late work per contact / pile mean (sweeps > 20)')):
        im = a.pcolormesh(r_edges * 100, z_edges * 100, np.ma.masked_invalid(data).T, shading='flat',
                          cmap='viridis')
        fig.colorbar(im, ax=a, label=label)
        a.set_xlabel('radius [cm]')
        a.set_ylabel('height [cm]')
        a.set_title('blank: fewer than 5 contacts in the bin', fontsize=8)
    fig.suptitle(title or 'where the sweeps of one step work: %d contacts, %d sweeps' % (ch.shape[1], ns), fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

"""Fabric of the contact network: orientation histograms, the fabric tensor, and how much the
contact forces change between two solves of the same step.
"""

import math
import numpy as np

from .snapshots import as_snapshot, grain_contacts


def contact_orientation_histogram(snap, n_bins=18, include_floor=False, include_zero=False):
    """Orientation of the contact normals (equivalently of the contact planes, which are normal
    to them), for contacts between two non-fixed grains (plus pile-floor ones if
    ``include_floor``; zero-force contacts only if ``include_zero``).

    Normals are lines (n and -n are the same). ``theta`` = angle of the normal from the vertical
    in [0, 90] deg (= angle of the contact plane on the horizontal). ``psi`` = orientation of the
    normal projected in the meridian plane of the contact point, angle from +e_r towards +e_z
    folded into (-90, 90] deg (unweighted; for a contact on the axis e_r = 0 and psi = ±90).

    :returns: dict ``theta_edges_deg``, ``theta_counts``, ``theta_density`` (counts divided by
        the isotropic expectation N·(cos θa - cos θb): 1 everywhere for isotropy),
        ``psi_edges_deg`` (2·n_bins bins over [-90, 90]), ``psi_counts``, ``n_contacts``,
        ``fabric`` = mean n⊗n (3x3, trace 1), ``fabric_eigenvalues`` (decreasing),
        ``anisotropy`` = sqrt(3/2 · D:D) with D = fabric - I/3 (0 isotropic, 1 all parallel),
        ``fabric_zz``.
    """
    snap = as_snapshot(snap)
    cont = grain_contacts(snap)
    f1, f2 = snap['fixed'][cont['i1']], snap['fixed'][cont['i2']]
    use = ~f1 & ~f2
    if include_floor:
        use |= f1 != f2
    if not include_zero:
        use &= np.linalg.norm(cont['force'], axis=1) > 0
    normal = cont['normal'][use]
    normal = normal / np.linalg.norm(normal, axis=1)[:, None] if len(normal) else normal
    theta = np.degrees(np.arccos(np.clip(np.abs(normal[:, 2]), 0, 1)))
    edges = np.linspace(0, 90, n_bins + 1)
    counts, _ = np.histogram(theta, bins=edges)
    expect = len(normal) * (np.cos(np.radians(edges[:-1])) - np.cos(np.radians(edges[1:])))
    n_r = (normal * cont['e_r'][use]).sum(axis=1)
    psi = np.degrees(np.arctan2(normal[:, 2], n_r))
    psi = np.where(psi > 90, psi - 180, np.where(psi <= -90, psi + 180, psi))
    psi_edges = np.linspace(-90, 90, 2 * n_bins + 1)
    psi_counts, _ = np.histogram(psi, bins=psi_edges)
    out = {'theta_edges_deg': edges, 'theta_counts': counts,
           'theta_density': np.where(expect > 0, counts / np.where(expect > 0, expect, 1), np.nan),
           'psi_edges_deg': psi_edges, 'psi_counts': psi_counts, 'n_contacts': int(len(normal))}
    out.update(fabric_tensor(normal))
    return out


def fabric_tensor(normals):
    """Fabric tensor F = mean of n⊗n over unit normals (n, 3), its eigenvalues (decreasing),
    the scalar anisotropy sqrt(3/2 · D:D) with D = F - I/3 (0 isotropic, 1 all parallel) and
    F_zz. Returns a dict (nan entries when there is no normal)."""
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    if len(normals) == 0:
        nan = float('nan')
        return {'fabric': np.full((3, 3), nan), 'fabric_eigenvalues': np.full(3, nan),
                'anisotropy': nan, 'fabric_zz': nan}
    F = normals.T @ normals / len(normals)
    D = F - np.eye(3) / 3
    return {'fabric': F, 'fabric_eigenvalues': np.sort(np.linalg.eigvalsh(F))[::-1],
            'anisotropy': float(math.sqrt(1.5 * (D * D).sum())), 'fabric_zz': float(F[2, 2])}


def force_change(a, b, top=(10, 100, 1000, 5000)):
    """How the contact forces of two solves of the same step differ, and where (the drift of an
    unconverged solve: ``scripts/bench/force_drift.py``).

    Contacts are matched by their body pair; the change of one is the norm of its force
    difference. Returns the contacts matched and unmatched, the relative total change
    Σ|ΔF| / Σ|F_b|, the share of Σ|ΔF| carried by the ``top`` contacts that change most (a
    change spread over the pile gives small shares, a few culprits large ones), the largest
    single share, and quartiles of the contact points' height and distance to the axis for the
    1000 that change most (or all, if fewer) against all matched contacts [m].

    :param a, b: snapshots (dicts with ``c_id1``, ``c_id2``, ``c_force``, ``c_point``).
    """
    def index(s):
        return {(int(i), int(j)): k for k, (i, j) in enumerate(zip(s['c_id1'], s['c_id2']))}
    ka, kb = index(a), index(b)
    common = [k for k in ka if k in kb]
    if not common:
        raise ValueError('force_change: the two solves share no contact')
    ia, ib = np.array([ka[k] for k in common]), np.array([kb[k] for k in common])
    d = np.linalg.norm(np.asarray(a['c_force'])[ia] - np.asarray(b['c_force'])[ib], axis=1)
    total, mag = d.sum(), np.linalg.norm(np.asarray(b['c_force'])[ib], axis=1).sum()
    order = np.argsort(-d, kind='stable')
    shares = np.cumsum(d[order]) / total if total > 0 else np.zeros(len(d))
    pts = np.asarray(a['c_point'])[ia]
    r, z = np.hypot(pts[:, 0], pts[:, 1]), pts[:, 2]
    worst = order[:min(1000, len(order))]
    quart = lambda x: [float(v) for v in np.percentile(x, [25, 50, 75])]  # noqa: E731
    return dict(matched=len(common), only_a=len(ka) - len(common), only_b=len(kb) - len(common),
                rel_total=float(total / mag) if mag > 0 else float('nan'),
                top_share={int(n): float(shares[min(n, len(d)) - 1]) for n in top},
                largest_share=float(shares[0]),
                worst_z_m=quart(z[worst]), worst_r_m=quart(r[worst]), all_z_m=quart(z), all_r_m=quart(r))

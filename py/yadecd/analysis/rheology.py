"""The μ(I) and φ(I) rheology from the steady states of periodic shear runs
(:mod:`yadecd.compare.shear`, ``scripts/shear_rheology.py``): records, the linear laws
μ = μ_s + b·I and φ = φ_c − a·I fitted with the runs' error bars, the table and the figure.
Pure numpy and matplotlib (no YADE).

Published values drawn beside the runs (:data:`LITERATURE`) are labelled with their source and
their system; they are not the same system as ours unless said.
"""
import csv
import glob
import json
import math
import os

import numpy as np

__all__ = ['LITERATURE', 'PROTOCOL', 'FIGURE_SERIES', 'variant_of', 'load_records', 'read_samples', 'solver_work', 'coulomb_excess', 'weighted_line', 'fit_laws',
           'table_markdown', 'drift_cell', 'variants_markdown', 'figure']

#: the reference protocol of each method (the defaults of ``scripts/shear_rheology.py`` and of
#: :func:`yadecd.compare.shear.build`): CD's shear strain per step, largest step over t_i, solver
#: tolerance and normal restitution; MD's Young's modulus over p, normal and tangential restitution
#: (Hertz–Mindlin's viscous damping) and time step over YADE's P-wave step (``safety``). A run with
#: other values is a *variant*: kept out of the fitted laws and compared with its reference run.
PROTOCOL = {
    'cd': dict(dgamma=5e-4, dt_max=0.05, tolerance=1e-3, en_cd=0.0),
    'md': dict(young_over_p=1e5, en_md=0.1, es_md=0.1, safety=0.5),
}

#: published μ(I) laws drawn for reference: name → (μ_s, μ_2, I_0, source, system)
LITERATURE = {
    'jop2006': (math.tan(math.radians(20.9)), math.tan(math.radians(32.76)), 0.279,
                'Jop, Forterre & Pouliquen, Nature 441, 727 (2006)', 'glass beads, experiments (inclined planes)'),
}


#: the series of :func:`figure`: (method, variant as :func:`variant_of` names it, marker, colour, label).
#: Besides the reference runs, MD without its tangential viscous damping (``es_md`` = 1), the MD whose
#: contact forces keep within Coulomb's bound (YADE's Hertz–Mindlin law adds that damping to a sticking
#: contact's force beyond the bound: docs/compare.md)
FIGURE_SERIES = (
    ('cd', '', 'o', 'C0', 'CD (this plugin)'),
    ('md', '', 's', 'C3', "YADE's MD (Hertz–Mindlin, e_n = e_t = 0.1)"),
    ('md', 'es_md=1', 'D', 'C2', "MD within Coulomb's bound (no tangential damping)"),
)


def mu_of_I(I, mu_s, mu_2, I0):
    """The μ(I) law of Jop et al. (2006): μ_s + (μ_2 − μ_s)/(1 + I_0/I)."""
    I = np.asarray(I, dtype=float)
    return mu_s + (mu_2 - mu_s) / (1.0 + I0 / I)


def variant_of(method, options):
    """How the run options ``options`` differ from the reference :data:`PROTOCOL` of ``method``:
    '' for a reference run, else 'name=value' pairs (an option a record lacks has its reference value)."""
    ref = PROTOCOL[method]
    unknown = sorted(set(options) - set(ref))
    if unknown:
        raise ValueError('unknown %s shear option(s): %s' % (method, ', '.join(unknown)))
    return ', '.join('%s=%g' % (k, options[k]) for k in ref if k in options and float(options[k]) != float(ref[k]))


def load_records(directory):
    """The run records (``<method>_I<I>_n<N>_s<seed>[_<tag>].json``) of a shear directory, as a list
    of dicts with method, I (measured in the bulk), its error, mu, phi and their errors, the wall's
    normal stress, the variant (:func:`variant_of`; '' for the reference protocol), sorted by
    method and I."""
    out = []
    for path in sorted(glob.glob(os.path.join(directory, '*_I*_n*_s*.json'))):
        if path.endswith('.ckpt.json'):          # a run's checkpoint bookkeeping, not its record
            continue
        with open(path) as f:
            r = json.load(f)
        s = r['summary']
        out.append(dict(method=r['method'], I_set=r['I'], I=s['I']['mean'], I_err=s['I']['sem'],
                        mu=s['mu']['mean'], mu_err=s['mu']['sem'], mu_drift=s['mu']['drift_z'],
                        phi=s['phi']['mean'], phi_err=s['phi']['sem'], phi_drift=s['phi']['drift_z'],
                        I_drift=s['I'].get('drift_z'),
                        normal_stress=s['normal_stress']['mean'], p=r['p'], sweeps=s.get('sweeps'), n=r['n'],
                        steps=r['steps'], travel=r.get('strain'), skip=s.get('skip_strain'), wall_s=r['wall_s'], dt=r['dt'], ti=r['ti'], samples=s['samples'], path=path,
                        variant=variant_of(r['method'], r.get('options', {}))))
    return sorted(out, key=lambda r: (r['method'], r['I']))


def read_samples(path):
    """A run's samples file (``<stem>.csv``, the columns of
    :data:`yadecd.compare.shear.SAMPLE_FIELDS`) as a list of dicts of floats."""
    with open(path, newline='') as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def solver_work(samples, lo, hi):
    """CD's solver work over the wall travel (strain) window (lo, hi] of a run's samples (dicts
    with step, strain and sweeps, the mean sweeps per step of each sample's steps): the samples in
    the window, the mean sweeps per step, the steps per unit strain (between the window's first and
    last samples) and their product, the sweeps per unit strain, which compares runs at different
    time steps. Raises ValueError when fewer than two samples fall in the window."""
    w = [r for r in samples if lo < r['strain'] <= hi]
    if len(w) < 2:
        raise ValueError('solver_work: %d sample(s) in the strain window (%g, %g]' % (len(w), lo, hi))
    sweeps = sum(r['sweeps'] for r in w) / len(w)
    steps = (w[-1]['step'] - w[0]['step']) / (w[-1]['strain'] - w[0]['strain'])
    return dict(samples=len(w), sweeps_per_step=sweeps, steps_per_strain=steps, sweeps_per_strain=sweeps * steps)


def coulomb_excess(fn, ft, mu, rtol=1e-6):
    """How far contact forces go beyond Coulomb's bound |F_t| ≤ μ·F_n. ``fn``: the normal force
    magnitudes [N], ``ft``: the tangential force magnitudes [N] (arrays of one length), ``mu``: the
    friction coefficient. Only loaded contacts (F_n > 0) count. Returns a dict: ``loaded`` (their
    number), ``over`` (the share of them with |F_t| > μ·F_n·(1 + ``rtol``)), ``excess_mean`` (the
    mean of |F_t|/(μ·F_n) − 1 over those, 0 when none), ``excess_max`` (its largest value, 0 when
    none), ``mobilised`` (the mean of min(|F_t|/(μ·F_n), 1) over the loaded contacts: the
    friction mobilised within the bound) and ``tangential_share`` (the part of Σ|F_t| beyond the
    bound, Σ max(|F_t| − μ·F_n, 0)/Σ|F_t|). Raises ValueError for arrays of different lengths, a
    negative force or a friction coefficient that is not positive."""
    fn, ft = np.asarray(fn, dtype=float).ravel(), np.asarray(ft, dtype=float).ravel()
    if fn.shape != ft.shape:
        raise ValueError('coulomb_excess: %d normal and %d tangential forces' % (fn.size, ft.size))
    if (fn < 0).any() or (ft < 0).any():
        raise ValueError('coulomb_excess: force magnitudes must be non-negative')
    if not mu > 0:
        raise ValueError('coulomb_excess: the friction coefficient must be positive, not %r' % (mu,))
    loaded = fn > 0
    fn, ft = fn[loaded], ft[loaded]
    if fn.size == 0:
        return dict(loaded=0, over=0.0, excess_mean=0.0, excess_max=0.0, mobilised=float('nan'), tangential_share=0.0)
    ratio = ft / (mu * fn)
    over = ratio > 1.0 + rtol
    beyond = np.maximum(ft - mu * fn, 0.0)
    total = ft.sum()
    return dict(loaded=int(fn.size), over=float(over.mean()),
                excess_mean=float((ratio[over] - 1.0).mean()) if over.any() else 0.0,
                excess_max=float((ratio[over] - 1.0).max()) if over.any() else 0.0,
                mobilised=float(np.minimum(ratio, 1.0).mean()),
                tangential_share=float(beyond.sum() / total) if total > 0 else 0.0)


def weighted_line(x, y, err):
    """Least-squares line y = a + b·x weighted by 1/err²: (a, b, σ_a, σ_b, χ²/dof). The
    parameter errors are scaled by sqrt(χ²/dof) when the scatter exceeds the error bars (> 1),
    so that bars too small for the data do not make the fit look sharper than it is. Needs
    three points with finite positive errors; otherwise nan everywhere."""
    x, y, err = (np.asarray(v, dtype=float) for v in (x, y, err))
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(err) & (err > 0)
    x, y, err = x[ok], y[ok], err[ok]
    nan = float('nan')
    if len(x) < 3:
        return nan, nan, nan, nan, nan
    w = 1.0 / err ** 2
    A = np.array([[w.sum(), (w * x).sum()], [(w * x).sum(), (w * x * x).sum()]])
    rhs = np.array([(w * y).sum(), (w * x * y).sum()])
    cov = np.linalg.inv(A)
    a, b = cov @ rhs
    chi2 = float((w * (y - a - b * x) ** 2).sum() / (len(x) - 2))
    scale = max(1.0, chi2)
    return float(a), float(b), float(math.sqrt(cov[0, 0] * scale)), float(math.sqrt(cov[1, 1] * scale)), chi2


def fit_laws(records, method, I_max=0.1):
    """μ = μ_s + b·I and φ = φ_c − a·I fitted to the runs of ``method`` with I ≤ ``I_max``.
    Variants (runs off the reference protocol) are left out.
    Returns a dict {mu_s, mu_s_err, b, b_err, phi_c, phi_c_err, a, a_err, chi2_mu, chi2_phi, points}."""
    rs = [r for r in records if r['method'] == method and r['I'] <= I_max and not r.get('variant')]
    I = [r['I'] for r in rs]
    mu_s, b, mu_s_e, b_e, chi_mu = weighted_line(I, [r['mu'] for r in rs], [r['mu_err'] for r in rs])
    phi_c, slope, phi_c_e, slope_e, chi_phi = weighted_line(I, [r['phi'] for r in rs], [r['phi_err'] for r in rs])
    return dict(mu_s=mu_s, mu_s_err=mu_s_e, b=b, b_err=b_e, phi_c=phi_c, phi_c_err=phi_c_e, a=-slope, a_err=slope_e,
                chi2_mu=chi_mu, chi2_phi=chi_phi, points=len(rs))


def table_markdown(records):
    """One row per run: method, I, μ, φ with their batch-means errors, the wall's mean normal
    stress over the imposed p (1 when the control holds), steps, wall time, and the drift check
    (:func:`drift_cell`). Reference runs only (variants: :func:`variants_markdown`)."""
    lines = ['| method | I (bulk) | μ = τ/p | φ (central half) | wall normal stress / p | wall travel / gap (window) | steps | time step / t_i | sweeps per step | wall [s] | drift z of μ, φ, I |',
             '| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |']
    for r in (r for r in records if not r.get('variant')):
        travel = '%g (%g–%g)' % (r['travel'], r['skip'], r['travel']) if r.get('travel') and r.get('skip') is not None else '–'
        lines.append('| %s | %.4g ± %.2g | %.4f ± %.4f | %.4f ± %.4f | %.4f | %s | %d | %s | %s | %.0f |' % (
            r['method'].upper(), r['I'], r['I_err'], r['mu'], r['mu_err'], r['phi'], r['phi_err'], r['normal_stress'] / r['p'],
            travel, r['steps'], '%.3g' % (r['dt'] / r['ti']),
            '%.0f' % r['sweeps'] if r['method'] == 'cd' and r['sweeps'] is not None else '–', r['wall_s'])
            + ' %s |' % drift_cell(r))
    return '\n'.join(lines) + '\n'


def drift_cell(r, limit=3.0):
    """The drift z-scores of μ, φ and I (second half of the steady window against the first, in
    standard errors), with 'not steady' when one exceeds ``limit``."""
    zs = [r.get(k) for k in ('mu_drift', 'phi_drift', 'I_drift')]
    text = ', '.join('%.1f' % z if z is not None and math.isfinite(z) else '–' for z in zs)
    if any(z is not None and math.isfinite(z) and abs(z) > limit for z in zs):
        text += ' (not steady)'
    return text


def variants_markdown(records):
    """One row per variant run against the reference run of the same method, nominal I and travel
    (the longest travel when none matches): the differences in μ, φ and the bulk I with their
    combined standard errors and their z = Δ/σ. '' when there is no variant."""
    rows = []
    for v in (r for r in records if r.get('variant')):
        refs = [r for r in records if not r.get('variant') and r['method'] == v['method'] and r['I_set'] == v['I_set']]
        same = [r for r in refs if r.get('travel') == v.get('travel')]
        ref = (same or sorted(refs, key=lambda r: r.get('travel') or 0))[-1] if refs else None
        cells = []
        for key in ('mu', 'phi', 'I'):
            if ref is None:
                cells.append('–')
                continue
            d, e = v[key] - ref[key], math.hypot(v[key + '_err'], ref[key + '_err'])
            cells.append('%+.4f ± %.4f (z %+.1f)' % (d, e, d / e if e > 0 else float('nan')))
        rows.append('| %s | %g | %s | %.4f ± %.4f | %.4f ± %.4f | %.4g | %s | %s | %s | %.0f | %s |' % (
            v['method'].upper(), v['I_set'], v['variant'], v['mu'], v['mu_err'], v['phi'], v['phi_err'], v['I'],
            cells[0], cells[1], cells[2], v['wall_s'], drift_cell(v)))
    if not rows:
        return ''
    return '\n'.join(['| method | nominal I | variant | μ | φ | I (bulk) | Δμ against the reference run | Δφ | ΔI | wall [s] | drift z of μ, φ, I |',
                      '| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |'] + rows) + '\n'


def figure(records, path, fits=None):
    """μ(I) and φ(I) of the series of :data:`FIGURE_SERIES` with error bars (95 %: 2.26 batch-means
    standard errors; open markers for runs whose steady window still drifts), each method's fitted
    lines (``fits``, through its reference runs), and the published law of :data:`LITERATURE`;
    log I axis. Runs of other variants are not drawn."""
    from .figures import new_figure, save_figure
    fig = new_figure(9.0, 3.6)
    ax_mu, ax_phi = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    fig.subplots_adjust(wspace=0.3)
    allI = [r['I'] for r in records if r['I'] > 0]
    if not allI:
        ax_mu.text(0.5, 0.5, 'no runs', transform=ax_mu.transAxes, ha='center')
        return save_figure(fig, path)
    grid = np.logspace(math.log10(min(allI)) - 0.2, math.log10(max(allI)) + 0.2, 100)
    for method, variant, marker, colour, label in FIGURE_SERIES:
        rs = [r for r in records if r['method'] == method and r.get('variant', '') == variant]
        for k, r in enumerate(rs):       # open markers: the run's steady window still drifts
            face = 'none' if 'not steady' in drift_cell(r) else colour
            for ax, key in ((ax_mu, 'mu'), (ax_phi, 'phi')):
                ax.errorbar([r['I']], [r[key]], yerr=[2.26 * r[key + '_err']], fmt=marker, color=colour, mfc=face,
                            label=label if k == 0 else None, capsize=2, ms=4)
        f = (fits or {}).get(method) if not variant else None
        if rs and f and math.isfinite(f['mu_s']):
            ax_mu.plot(grid, f['mu_s'] + f['b'] * grid, '-', color=colour, lw=0.8)
            ax_phi.plot(grid, f['phi_c'] - f['a'] * grid, '-', color=colour, lw=0.8)
    for name, (mu_s, mu_2, I0, source, system) in LITERATURE.items():
        ax_mu.plot(grid, mu_of_I(grid, mu_s, mu_2, I0), 'k--', lw=0.8, label='%s (%s)' % (source.split(',')[0] + ' 2006', system.split(',')[0]))
    for ax, name in ((ax_mu, 'μ = τ / p'), (ax_phi, 'solid fraction φ')):
        ax.set_xscale('log')
        ax.set_xlabel('inertial number I')
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    ax_mu.legend(fontsize=7, loc='upper left')
    ax_phi.legend(fontsize=7, loc='lower left')
    fig.suptitle('Plane shear between rough walls at imposed pressure (periodic in x, y), frictional spheres (μ_p = 0.5); '
                 'bars: 95 % batch means; open markers: not steady (drift > 3 standard errors)', fontsize=8)
    return save_figure(fig, path)

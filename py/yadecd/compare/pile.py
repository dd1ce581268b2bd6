"""CD against MD on a small pile by the paper's protocol (the job of ``scripts/compare_pile.py``):
the same protocol (same seed, same feed) run with the CD engine and with YADE's linear soft
contacts at several stiffnesses, each analysed by :func:`yadecd.report.analyse`."""
import csv
import json
import os
import shutil

import numpy as np

from ..io import append_csv

CASES = {
    'cd': ('CD, tolerance 1e-3', dict(method='CD', tolerance=1e-3)),
    'cd_plain': ('CD, tolerance 1e-3, plain Gauss–Seidel', dict(method='CD', tolerance=1e-3, momentum=False)),
    'cd_loose': ('CD, tolerance 1e-2', dict(method='CD', tolerance=1e-2)),
    'md_1e6': ('MD linear, E = 1e6 Pa', dict(method='MD', young=1e6)),
    'md_1e7': ('MD linear, E = 1e7 Pa', dict(method='MD', young=1e7)),
    'md_1e8': ('MD linear, E = 1e8 Pa', dict(method='MD', young=1e8)),
}
FIELDS = ['case', 'label', 'method', 'young_Pa', 'dt_s', 'steps', 'wall_s', 'wall_per_sim_s', 'grains', 'contacts',
          'slope_deg', 'slope_err_deg', 'chord_angle_deg', 'slope_ls_window_deg', 'H_cm', 'p_center_dPa', 'p_center_err_dPa', 'p_peak_dPa', 'p_peak_radius_cm',
          'hydrostatic_dPa', 'p_center_over_hydrostatic', 'floor_load_over_weight', 'overlap_max_over_d',
          'overlap_mean_over_d', 'unconverged_steps']

def _allowance(i, beyond_allowance):
    """The overlap a CD contact may keep [m] when ``beyond_allowance`` (0 for MD contacts and
    allowances not yet set), else 0."""
    a = getattr(i.phys, 'overlapAllowance', 0.0) if beyond_allowance else 0.0
    return a if np.isfinite(a) else 0.0


def overlaps(beyond_allowance=False):
    """Largest and mean overlap of grain–grain contacts over the mean diameter [-].
    ``beyond_allowance``: only what exceeds each CD contact's ``CDPhys.overlapAllowance`` (the
    overlap a state was built with, which CD keeps): the overlap CD itself adds."""
    from yade import O
    from yade.wrapper import Sphere
    d = 2 * np.mean([b.shape.radius for b in O.bodies if isinstance(b.shape, Sphere)])
    pen = [max(0.0, i.geom.penetrationDepth - _allowance(i, beyond_allowance)) for i in O.interactions
           if i.isReal and isinstance(O.bodies[i.id1].shape, Sphere) and isinstance(O.bodies[i.id2].shape, Sphere)]
    return (max(pen) / d, np.mean(pen) / d) if pen else (0.0, 0.0)


def loaded_overlaps(beyond_allowance=True):
    """Largest and mean overlap over the mean diameter [-] of the grain–grain contacts that carry
    a force, from the bodies' *positions* (the state at the end of the step, measured alike for
    both methods: CD's contact geometry is that of its mid-step predictor, so a moving grain's
    contact shows an overlap of up to h/2 times its approach speed there, and CD counts open
    contacts within its alert distance, MD only touching ones). ``beyond_allowance``: CD's
    overlap allowances (a state's construction overlaps) are subtracted."""
    from yade import O
    from yade.wrapper import Sphere
    from .measure import gap
    d = 2 * np.mean([b.shape.radius for b in O.bodies if isinstance(b.shape, Sphere)])
    pen = []
    for i in O.interactions:
        b1, b2 = O.bodies[i.id1], O.bodies[i.id2]
        if not (i.isReal and isinstance(b1.shape, Sphere) and isinstance(b2.shape, Sphere)):
            continue
        if (i.phys.normalForce + i.phys.shearForce).norm() == 0:
            continue
        pen.append(max(0.0, -gap(b1, b2) - _allowance(i, beyond_allowance)))
    return (max(pen) / d, np.mean(pen) / d, len(pen)) if pen else (0.0, 0.0, 0)


def run_case(key, opts):
    """Build and run one case by the pile protocol, analyse it, return its CSV row."""
    from yade import O
    from .. import pile
    from ..analysis import report
    label, settings = CASES[key]
    run_dir = os.path.join(opts.out, key)
    shutil.rmtree(run_dir, ignore_errors=True)
    p = pile.run(run_dir, n_grains=opts.grains, relax=opts.relax, seed=opts.seed, snap_every=1e9,
                 grain_shape=getattr(opts, 'grain_shape', 'sphere'), **settings)
    omax, omean = overlaps()
    s = report.analyse(run_dir, os.path.join(run_dir, 'figures'))
    sim = O.time
    return dict(case=key, label=label, method=p['method'], young_Pa=p['young'] if p['method'] == 'MD' else '',
                dt_s=p['dt'], steps=O.iter, wall_s=p['wall_time_s'], wall_per_sim_s=p['wall_time_s'] / sim,
                grains=s['n_pile_grains'], contacts=s['n_contacts'], slope_deg=s['slope_deg'],
                slope_err_deg=s['slope_err_deg'], chord_angle_deg=s['chord_angle_deg'],
                slope_ls_window_deg=s['slope_ls_window_deg'], H_cm=s['H_cm'], p_center_dPa=s['p_center_dPa'],
                p_center_err_dPa=s['p_center_err_Pa'] * 10, p_peak_dPa=s['p_peak_dPa'],
                p_peak_radius_cm=s['p_peak_radius_cm'], hydrostatic_dPa=s['hydrostatic_dPa'],
                p_center_over_hydrostatic=s['p_center_over_hydrostatic'],
                floor_load_over_weight=s['floor_load_over_weight'], overlap_max_over_d=omax,
                overlap_mean_over_d=omean, unconverged_steps=p['unconverged_steps'])


def plot(rows, opts):
    """Ground pressure profiles and cost against interpenetration; returns the figure's path."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.6))
    missing = []
    for row in rows:
        with open(os.path.join(opts.out, row['case'], 'figures', 'summary.json')) as f:
            s = json.load(f)
        prof = s.get('rings') or {}
        r, p = prof.get('r_mid_m'), prof.get('pressure_Pa')
        hydro = row['hydrostatic_dPa']
        if r and p and hydro not in (None, '', 'None'):
            a1.plot(np.array(r) * 100, np.array(p) * 10 / float(hydro), 'o-', ms=3, label=row['label'])
        else:   # a pile too small for an apex height has no hydrostatic reference
            missing.append(row['label'])
    if missing:
        a1.text(0.02, 0.02, 'no profile (no hydrostatic reference): ' + '; '.join(missing), transform=a1.transAxes, fontsize=7)
    a1.axhline(1, color='k', lw=0.8, ls=':')
    a1.set_xlabel('r [cm]')
    a1.set_ylabel('ground pressure / hydrostatic ρ_bulk g H')
    a1.set_title('Ground pressure, %d-grain pile' % opts.grains)
    a1.legend(fontsize=8)
    for row in rows:
        marker = 's' if row['method'] == 'CD' else 'o'
        a2.loglog(float(row['wall_per_sim_s']), max(float(row['overlap_max_over_d']), 1e-7), marker, ms=8, label=row['label'])
    a2.set_xlabel('wall time per simulated second [s]')
    a2.set_ylabel('largest overlap / mean diameter')
    a2.set_title('Cost against interpenetration')
    a2.legend(fontsize=8)
    fig.tight_layout()
    path = os.path.join(opts.out, 'compare_pile.png')
    fig.savefig(path, dpi=120)
    print('wrote', path)
    return path



def main(opts, repo):
    """Run the cases ``opts.cases`` (or with ``opts.plot_only`` reload the CSV), plot, and with
    ``opts.docs`` copy the CSV and figure into ``repo``'s docs. Returns the exit status."""
    csv_path = os.path.join(opts.out, 'compare_pile.csv')
    os.makedirs(opts.out, exist_ok=True)
    if opts.plot_only:
        with open(csv_path) as f:
            rows = list(csv.DictReader(f))
    else:
        rows = []
        append_csv(csv_path, None, FIELDS, start=True)
        for key in [k for k in opts.cases.split(',') if k]:
            if key not in CASES:
                raise SystemExit('unknown case %r (known: %s)' % (key, ', '.join(CASES)))
            print('=== %s' % CASES[key][0], flush=True)
            row = run_case(key, opts)
            rows.append({k: str(v) for k, v in row.items()})
            append_csv(csv_path, row, FIELDS)
            print('  ' + ', '.join('%s=%s' % (k, ('%.4g' % v) if isinstance(v, float) else v) for k, v in row.items()), flush=True)
    png = plot(rows, opts)
    if opts.docs:
        shutil.copy(csv_path, os.path.join(repo, 'docs', 'data', 'compare_pile.csv'))
        shutil.copy(png, os.path.join(repo, 'docs', 'figures', 'compare_pile.png'))
    return 0

#!/usr/bin/env python3
"""Figures and summary of a sand-pile run (Moreau, section IV).

    python3 scripts/pile_figures.py RUN_DIR [--epoch T] [--fossil T1 T2]... [--out DIR]

RUN_DIR holds snap_<time>.npz files (and run.json); a single snapshot file is accepted too.
Writes fig0..fig7 PNGs, summary.json and paper_table.md (the pile's numbers beside the paper's, in
its units) into DIR (default RUN_DIR/figures) and prints the main numbers. Needs numpy and matplotlib only: works with Debian's /usr/bin/python3 and inside YADE
(``yade -n -x scripts/pile_figures.py RUN_DIR ...``); it never imports yade (the yadecd package
imports without YADE; this script uses the repository's copy, py/yadecd).
"""
import argparse
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)


def parse(argv):
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('run', help='run directory (snap_<time>.npz files) or one snapshot file')
    p.add_argument('--epoch', type=float, default=None, help='time [s] of the snapshot analysed (default: last)')
    p.add_argument('--fossil', type=float, nargs=2, action='append', metavar=('T1', 'T2'),
                   help='birth-time interval [s] of a fossil layer (repeatable; first one in Fig. 2)')
    p.add_argument('--out', default=None, help='output directory (default RUN/figures)')
    p.add_argument('--half-thickness', type=float, default=0.01, help='slice half thickness [m] (1 cm)')
    p.add_argument('--ring-width', type=float, default=None, help='ground-pressure ring width [m]')
    args = p.parse_args(argv)
    if not os.path.exists(args.run):
        p.error('%s does not exist (a run directory or a snapshot file)' % args.run)
    if not args.half_thickness > 0:
        p.error('--half-thickness must be a positive length [m] (got %r)' % args.half_thickness)
    if args.ring_width is not None and not args.ring_width > 0:
        p.error('--ring-width must be a positive length [m] (got %r)' % args.ring_width)
    return args


def main(argv=None):
    args = parse(sys.argv[1:] if argv is None else argv)
    from yadecd.analysis import report as figures
    base = args.run if os.path.isdir(args.run) else os.path.dirname(os.path.abspath(args.run))
    out = args.out or os.path.join(base, 'figures')
    s = figures.analyse(args.run, out, epoch=args.epoch, fossil=args.fossil,
                        half_thickness=args.half_thickness, ring_width=args.ring_width)
    fmt = lambda v, f='%.4g': 'n/a' if v is None else f % v
    print('snapshot %s (t = %s s): %d grains, %d contacts' % (s['snapshot'], fmt(s['time_s']),
                                                              s['n_grains'], s['n_contacts']))
    if s['slope_deg'] is None:
        print('slope: %s (chord angle %s deg); H %s cm, base radius %s cm'
              % (s['slope_note'], fmt(s['chord_angle_deg'], '%.1f'), fmt(s['H_cm']), fmt(s['base_radius_cm'])))
    else:
        print('flank slope %s ± %s deg (paper 26), chord angle %s deg, H %s cm, base radius %s cm'
              % (fmt(s['slope_deg'], '%.1f'), fmt(s['slope_err_deg'], '%.1f'), fmt(s['chord_angle_deg'], '%.1f'),
                 fmt(s['H_cm']), fmt(s['base_radius_cm'])))
    dip = s['dip']
    print('central dip D = %s, 95%% interval [%s, %s] (%s contacts in the disc)%s'
          % (fmt(dip['D'], '%.2f'), fmt(dip['ci95'][0], '%.2f'), fmt(dip['ci95'][1], '%.2f'), dip['n_disc'],
             ('; ' + dip['note']) if dip['note'] else ''))
    print('floor pressure: centre %s dPa, peak %s dPa at r = %s cm, hydrostatic %s dPa'
          % (fmt(s['p_center_dPa']), fmt(s['p_peak_dPa']), fmt(s['p_peak_radius_cm']), fmt(s['hydrostatic_dPa'])))
    rc = s['reciprocity']
    print('reciprocity: %d pairs, relative difference median %s (null pairing %s)'
          % (rc['n_pairs'], fmt(rc['rel_median'], '%.3f'), fmt(rc['rel_null_median'], '%.3f')))
    for name, why in s.get('figures_skipped', {}).items():
        print('%s: %s' % (name, why))
    print('written: %s, %s' % (os.path.join(out, 'summary.json'), os.path.join(out, 'paper_table.md')))
    return 0


if __name__ == '__main__':
    sys.exit(main())

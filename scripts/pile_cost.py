#!/usr/bin/env python3
"""What a pile run's wall time went into: cost per simulated second and all-in cost per
contact-sweep, per window of simulated time and per segment (host), from the run's own
progress.csv and segments.csv (module yadecd.runs.cost).

    python3 scripts/pile_cost.py RUN_DIR [--window 2] [--out DIR] [--against OTHER_RUN [--bin 400]]

Prints a table and, for an unfinished run, where it stands and about how much wall time it still
needs at its recent pace; writes cost.csv and cost.png into DIR (default RUN_DIR). --against
compares the solver's work (contact-sweeps per simulated second, machine-free) with another run
of the same pile at equal grain counts, e.g. the paper's h = 2e-4 s against h = 1e-3 s, and writes
against.csv and against.png. A run carried between
machines ran on hosts of different speed: the ns per contact-sweep column tells them apart. Needs numpy and matplotlib
only (Debian's /usr/bin/python3 or YADE's).
"""
import argparse
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)



def axes_pair(title, top, bottom, xlabel, size=(9, 6.5)):
    """A figure of two panels sharing their grains axis: labels, title and grid set, the lower
    panel from zero. Returns (pf, fig, ax, bx), pf the figures module that saves it."""
    from yadecd.analysis import figures as pf
    fig = pf.new_figure(*size)
    ax, bx = fig.add_subplot(2, 1, 1), fig.add_subplot(2, 1, 2)
    ax.set_title(title, fontsize=9)
    ax.set_ylabel(top)
    bx.set_ylabel(bottom)
    bx.set_xlabel(xlabel)
    for a in (ax, bx):
        a.grid(alpha=0.3)
    return pf, fig, ax, bx


def figure(rows, segments, path, title):
    """Wall time per simulated second and all-in ns per contact-sweep along the run, one colour
    per segment, into ``path``."""
    import numpy as np
    pf, fig, ax, bx = axes_pair(title, 'wall time per simulated second [s]', 'all-in cost per contact-sweep [ns]',
                                'grains at the end of the window')
    for seg in sorted({r['segment'] for r in rows}):
        sel = [r for r in rows if r['segment'] == seg]
        label = ('before segments were recorded' if seg < 0 else
                 'segment %d: %s, %s thread(s)' % (seg, segments[seg]['cpu'], segments[seg]['threads']))
        g = np.array([r['grains'] for r in sel])
        ax.plot(g, [r['wall_per_sim_s'] for r in sel], 'o-', ms=3, label=label)
        bx.plot(g, [r['ns_per_contact_sweep'] for r in sel], 'o-', ms=3, label=label)
    ax.set_yscale('log')
    bx.set_ylim(bottom=0)
    ax.legend(fontsize=6)
    bx.legend(fontsize=6)
    bx.text(0.01, 0.97, 'wall time / Σ steps × contacts × sweeps (sweeps sampled once per progress line)',
            transform=bx.transAxes, fontsize=6, va='top')
    return pf.save_figure(fig, path)


def against_figure(rows, path, names):
    """Sweeps per step of both runs (``names``: run, other) and the ratio of their work per
    simulated second, by grains."""
    pf, fig, ax, bx = axes_pair('%s against %s' % names, 'sweeps per step (sampled)',
                                'contact-sweeps per simulated second,\n%s / %s' % names, 'grains', size=(8, 6))
    g = [0.5 * (r['grains_from'] + r['grains_to']) for r in rows]
    ax.plot(g, [r['sweeps_per_step'] for r in rows], 'o-', ms=3, label=names[0])
    ax.plot(g, [r['other_sweeps_per_step'] for r in rows], 's-', ms=3, label=names[1])
    ax.legend(fontsize=7)
    bx.plot(g, [r['work_ratio'] for r in rows], 'o-', ms=3, color='k')
    bx.axhline(1.0, color='0.6', lw=0.8)
    bx.set_ylim(bottom=0)
    return pf.save_figure(fig, path)


def against(run, other, bin_grains, out):
    """Print and save the work of ``run`` against ``other`` by grains (yadecd.runs.cost.compare_work)."""
    from yadecd.io import write_csv
    from yadecd.runs import cost as runcost
    from yadecd import analysis as pa
    rows = []
    for d in (run, other):
        dt = pa.run_parameters(d).get('dt')
        if not dt:
            raise ValueError('%s holds no run.json with the time step' % d)
        rows.append(runcost.work_by_grains(runcost.read_progress(os.path.join(d, 'progress.csv')), dt, bin_grains))
    cmp = runcost.compare_work(*rows)
    print('work against %s (contact-sweeps per simulated second; sweeps sampled once per progress line)' % other)
    print('%13s %10s %10s %9s' % ('grains', 'sweeps run', 'sw. other', 'run/other'))
    for r in cmp:
        print('%6d-%-6d %10.0f %10.0f %9.2f' % (r['grains_from'], r['grains_to'], r['sweeps_per_step'],
                                                 r['other_sweeps_per_step'], r['work_ratio']))
    write_csv(os.path.join(out, 'against.csv'), cmp)
    names = tuple(os.path.basename(os.path.abspath(d)) for d in (run, other))
    print('wrote %s' % against_figure(cmp, os.path.join(out, 'against.png'), names))


def standing(run):
    """One line: finished, or where the run stands and the wall time it still needs at its recent
    pace (yadecd.runs.ensemble.progress_of, the estimate ``pile_ensemble.py status`` gives)."""
    from yadecd.runs import ensemble as ens
    if ens.is_done(run):
        return 'finished'
    now = ens.progress_of(run)
    if now is None:
        return 'not started'
    line = 'stands at t = %.3f s of %s s, %d grains, %.2f h of wall time so far' % (
        now['time_s'], '?' if now['end_s'] is None else '%.3f' % now['end_s'], now['grains'], now['wall_s'] / 3600)
    if now['remaining_s'] is not None:
        line += '; about %.1f h more at its recent pace (a planning figure)' % (now['remaining_s'] / 3600)
    return line


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('run')
    p.add_argument('--window', type=float, default=2.0, help='window of simulated time [s]')
    p.add_argument('--out', default=None, help='output directory (default RUN_DIR)')
    p.add_argument('--against', default=None, metavar='OTHER_RUN',
                   help='another run of the same pile: compare the solver work per simulated second by grains')
    p.add_argument('--bin', type=int, default=400, help='grain bin width of --against')
    args = p.parse_args(argv)
    if not args.window > 0:
        p.error('--window must be > 0')
    if args.bin <= 0:
        p.error('--bin must be > 0')
    if args.against and not os.path.exists(os.path.join(args.against, 'progress.csv')):
        p.error('--against %s holds no progress.csv' % args.against)
    progress = os.path.join(args.run, 'progress.csv')
    if not os.path.exists(progress):
        p.error('%s holds no progress.csv' % args.run)
    from yadecd.io import write_csv
    from yadecd.runs import cost as runcost
    from yadecd import analysis as pa
    params = pa.run_parameters(args.run)
    dt = params.get('dt')
    if not dt:
        p.error('%s holds no run.json with the time step' % args.run)
    segments = runcost.read_segments(os.path.join(args.run, 'segments.csv'))
    rows = runcost.cost_windows(runcost.read_progress(progress), dt, args.window, segments)
    if not rows:
        p.error('%s: too few progress lines for a window of %g s' % (args.run, args.window))
    print('%9s %9s %4s %7s %8s %10s %10s' % ('t from', 't to', 'seg', 'grains', 'contacts', 'wall/sim-s', 'ns/c-sweep'))
    for r in rows:
        print('%9.3f %9.3f %4d %7d %8d %10.1f %10.1f' % (r['t_from_s'], r['t_to_s'], r['segment'], r['grains'],
                                                         r['contacts'], r['wall_per_sim_s'], r['ns_per_contact_sweep']))
    wall = sum(r['wall_s'] for r in rows)
    print('wall time in these windows %.0f s (%.2f h)' % (wall, wall / 3600))
    for k, s in enumerate(segments):
        print('segment %d: from t = %.3f s, %s thread(s), %s, %s' % (k, s['t_start_s'], s['threads'], s['host'], s['cpu']))
    print(standing(args.run))
    out = args.out or args.run
    write_csv(os.path.join(out, 'cost.csv'), rows)
    path = figure(rows, segments, os.path.join(out, 'cost.png'),
                  '%s: %d grains, h = %g s' % (os.path.basename(os.path.abspath(args.run)), params.get('n_grains', 0), dt))
    print('wrote %s' % path)
    if args.against:
        try:
            against(args.run, args.against, args.bin, out)
        except ValueError as e:
            p.error(str(e))
    return 0


if __name__ == '__main__':
    sys.exit(main())

#!/usr/bin/env python3
"""What the floor's plane adds to the central dip: per snapshot, D measured on the paving grains
(the paper's floor, what the ensembles report) and on the paving plus the plane between them, and
the plane's share of the loads; per grain shape and size, the mean change of D with its 95 %
interval over piles (paired: the same snapshot both ways).

    /usr/bin/python3 scripts/pile_plane_load.py RUN_OR_SNAPSHOT ... [--epoch relaxed] \\
        [--csv docs/data/plane_load.csv] [--table docs/data/plane_load.md]

A run directory gives its last snapshot (``--epoch relaxed``) or the one nearest the end of its
feed (``--epoch feed``); a ``.npz`` path is taken as it is. Clumps' members are smaller than the
paving grains and reach the plane between them more often than spheres do (docs/pile.md,
"Grain shape"). numpy only (no YADE needed).
"""
import argparse
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)


def snapshot_of(path, epoch):
    """The snapshot path a command-line argument stands for, and its run's parameters."""
    from yadecd import analysis as pa
    from yadecd.pile.protocol import DEFAULTS, feed_time
    run_dir = path if os.path.isdir(path) else os.path.dirname(path)
    params = pa.run_parameters(run_dir)
    if not os.path.isdir(path):
        return path, params
    snaps = pa.list_snapshots(path)
    if not snaps:
        raise SystemExit('%s: no snapshot' % path)
    if epoch == 'relaxed':
        return snaps[-1][1], params
    if 'n_grains' not in params:
        raise SystemExit('%s: no run.json with n_grains beside the snapshots: the end of the feed is unknown' % path)
    t_feed = feed_time(int(params['n_grains']), params.get('rate', DEFAULTS['rate']), params.get('dt', DEFAULTS['dt']))
    return min(snaps, key=lambda s: abs(s[0] - t_feed))[1], params


def measure(snap_path, params):
    """One row: D on the paving and with the plane, and the plane's shares of the loads."""
    from yadecd import analysis as pa
    from yadecd.analysis import ground
    snap = pa.load_snapshot(snap_path)
    paving, both = pa.central_dip(snap), pa.central_dip(snap, plane=True)
    plane = ground.plane_loads(snap)[1]
    floor = plane.sum() + ground.paving_loads(snap)[1].sum()

    def share(part, whole):
        return float(part / whole) if whole > 0 else float('nan')
    return {'snapshot': snap_path, 'grain_shape': params.get('grain_shape', 'sphere'),
            'n_grains': int(params.get('n_grains', 0)), 'seed': params.get('seed'), 'time_s': snap['time'],
            'D_paving': paving['D'], 'D_with_plane': both['D'], 'D_change': both['D'] - paving['D'],
            'plane_share_floor': share(plane.sum(), floor),
            'plane_share_disc': share(both['p_disc_Pa'] - paving['p_disc_Pa'], both['p_disc_Pa']),
            'plane_share_annulus': share(both['p_ring_Pa'] - paving['p_ring_Pa'], both['p_ring_Pa']),
            'n_plane_contacts': int(len(plane)),
            'weight_N': float(pa.grain_masses(snap)[~snap['fixed']].sum() * snap['g'])}


def summary(rows):
    """Per (shape, grains): piles, the mean plane share of the floor load, and the mean change of D
    with its 95 % interval over piles."""
    from yadecd import analysis as pa
    groups = {}
    for r in rows:
        groups.setdefault((r['grain_shape'], r['n_grains']), []).append(r)
    out = []
    for (shape, n), rs in sorted(groups.items(), key=lambda kv: (kv[0][0] != 'sphere', kv[0])):
        ch, sh = pa.mean_interval([r['D_change'] for r in rs]), pa.mean_interval([r['plane_share_floor'] for r in rs])
        out.append({'grain_shape': shape, 'n_grains': n, 'piles': len(rs), 'plane_share_floor_mean': sh['mean'],
                    'D_change_mean': ch['mean'], 'D_change_ci95': ch['ci95'],
                    'D_change_min': min(r['D_change'] for r in rs), 'D_change_max': max(r['D_change'] for r in rs)})
    return out


def table_markdown(groups):
    """The per-shape summary ``groups`` as a markdown table (plane share of the floor load, change
    of D with the plane, its interval over piles)."""
    lines = ['| shape | grains | piles | plane share of the floor load | D with the plane − D on the paving: mean [95 %] | smallest, largest |',
             '| --- | --- | --- | --- | --- | --- |']
    for g in groups:
        lo, hi = g['D_change_ci95']
        interval = '[%+.3f, %+.3f]' % (lo, hi) if g['piles'] > 1 else '(one pile, no interval)'
        lines.append('| %s | %d | %d | %.1f %% | %+.3f %s | %+.3f, %+.3f |'
                     % (g['grain_shape'], g['n_grains'], g['piles'], 100 * g['plane_share_floor_mean'], g['D_change_mean'],
                        interval, g['D_change_min'], g['D_change_max']))
    return '\n'.join(lines) + '\n'


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('paths', nargs='+', help='run directories or snapshot files')
    p.add_argument('--epoch', choices=('relaxed', 'feed'), default='relaxed')
    p.add_argument('--csv', help='write the per-snapshot rows here')
    p.add_argument('--table', help='write the per-shape summary (markdown) here')
    a = p.parse_args(argv)
    for path in a.paths:
        if not os.path.exists(path):
            p.error('%s does not exist (a run directory or a snapshot file)' % path)
    from yadecd.io import write_csv
    rows = []
    for path in a.paths:
        snap, params = snapshot_of(path, a.epoch)
        rows.append(measure(snap, params))
        r = rows[-1]
        print('%-7s %6d s%-3s D %+.3f -> %+.3f (plane: %.1f %% of the floor load)'
              % (r['grain_shape'], r['n_grains'], r['seed'], r['D_paving'], r['D_with_plane'], 100 * r['plane_share_floor']))
    table = table_markdown(summary(rows))
    print(table)
    if a.csv:
        write_csv(a.csv, rows)
    if a.table:
        with open(a.table, 'w') as f:
            f.write('D on the paving grains and with the plane between them (`scripts/pile_plane_load.py`, %s piles)\n\n' % a.epoch)
            f.write(table)
    return rows


if __name__ == '__main__':
    main()

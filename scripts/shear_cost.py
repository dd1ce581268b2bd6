#!/usr/bin/env python3
"""CD's solver work per unit wall travel in shear runs (scripts/shear_rheology.py), over one strain
window, so that runs at different time steps compare (yadecd.analysis.rheology.solver_work).

    /usr/bin/python3 scripts/shear_cost.py OUT/cd_I0.01_n2000_s1.csv OUT2/cd_I0.01_n2000_s1_dt0.5.csv ... \\
        [--window 0.1 0.3] [--out docs/data/shear_qs_timestep.csv]

Prints one row per run (time step over t_i from the run's record beside its samples, mean sweeps
per step, steps and sweeps per unit strain) and, with --out, writes them (with provenance).
"""
import argparse
import json
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

from yadecd.analysis import rheology  # noqa: E402
from yadecd.io import write_csv  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('runs', nargs='+', help="runs' samples files (<stem>.csv, a <stem>.json record beside each)")
    ap.add_argument('--window', nargs=2, type=float, default=(0.1, 0.3), metavar=('LO', 'HI'))
    ap.add_argument('--out', default=None)
    a = ap.parse_args(argv)
    rows = []
    for path in a.runs:
        record_path = path[:-len('.csv')] + '.json'
        if not path.endswith('.csv') or not os.path.exists(record_path):
            ap.error('%s: a run\'s samples file with its record %s beside it' % (path, record_path))
        with open(record_path) as f:
            record = json.load(f)
        if record['method'] != 'cd':
            ap.error('%s: not a CD run' % path)
        work = rheology.solver_work(rheology.read_samples(path), *a.window)
        rows.append(dict(run=os.path.basename(path[:-len('.csv')]), I_set=record['I'], dt_over_ti=record['dt'] / record['ti'],
                         tolerance=record['options']['tolerance'], window=' '.join('%g' % w for w in a.window), **work))
        print('%-36s h/t_i %.4g  sweeps/step %7.1f  steps/strain %6.0f  sweeps/strain %.3g' % (
            rows[-1]['run'], rows[-1]['dt_over_ti'], work['sweeps_per_step'], work['steps_per_strain'], work['sweeps_per_strain']))
    if a.out:
        write_csv(a.out, rows)


if __name__ == '__main__':
    main()

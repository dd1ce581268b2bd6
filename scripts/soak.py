"""Soak test: a 2000-grain pile run for an hour with its memory sampled (docs/reliability.md).

    /usr/bin/python3 scripts/soak.py FINISHED_RUN_DIR [--out out/soak] [--hours 1] [--every 15]

Continues a finished pile run (e.g. an ensemble's ``n2000_s1``) as a relaxation of ``--hours``
of wall time, through ``scripts/pile.py --resume`` with checkpoints every 60 s, exactly as a long
run goes: the grain count is fixed, so memory has no reason to grow. Samples the YADE process's
resident memory (VmRSS) and the run's progress every ``--every`` seconds, stops the run with
SIGTERM at the end, and writes ``soak.csv``, ``soak.json`` (growth rate by a least-squares line
after the first 5 minutes, and the scatter about it) and ``soak_rss.png`` in --out.
"""
import argparse
import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, 'py'))  # this checkout's yadecd (README: which yadecd)
from yadecd.io import rss_mb  # noqa: E402



def last_progress(run_dir):
    """(simulated time, grains, contacts) of the last progress line of the run; nan and zeros
    before there is one."""
    try:
        with open(os.path.join(run_dir, 'progress.csv')) as f:
            lines = f.readlines()
        t, grains, contacts = lines[-1].split(',')[:3]
        return float(t), int(grains), int(contacts)
    except (OSError, ValueError, IndexError):
        return float('nan'), 0, 0


def main(argv=None):
    ap = argparse.ArgumentParser(prog='soak.py', description=__doc__.split('\n')[0])
    ap.add_argument('source', help='a finished pile run directory')
    ap.add_argument('--out', default='out/soak')
    ap.add_argument('--hours', type=float, default=1.0)
    ap.add_argument('--every', type=float, default=15.0, help='sampling period [s]')
    ap.add_argument('--plot-only', action='store_true', help='redraw soak_rss.png from --out/soak.csv and soak.json')
    a = ap.parse_args(argv)
    if a.plot_only:
        for name in ('soak.csv', 'soak.json'):
            if not os.path.isfile(os.path.join(a.out, name)):
                ap.error('--plot-only needs %s in --out %s (written by a soak run)' % (name, a.out))
        data = np.loadtxt(os.path.join(a.out, 'soak.csv'), delimiter=',', skiprows=1)
        with open(os.path.join(a.out, 'soak.json')) as f:
            plot(data, json.load(f), os.path.join(a.out, 'soak_rss.png'))
        return 0
    if not os.path.exists(os.path.join(a.source, 'run.json')):
        ap.error('%s holds no pile run' % a.source)
    if os.path.exists(a.out):
        ap.error('%s exists: choose another --out' % a.out)
    if a.hours <= 0 or a.every <= 0:
        ap.error('--hours and --every must be positive')
    run_dir = os.path.join(a.out, 'run')
    shutil.copytree(a.source, run_dir, ignore=shutil.ignore_patterns('snap_*', 'vtk_*', 'log.txt'))
    with open(os.path.join(run_dir, 'run.json')) as f:
        p = json.load(f)
    p['relax'] = p['relax'] + 1000.0          # far more relaxation than an hour can run
    p['checkpoint_every'] = 60.0
    p['epochs'] = '1e6'                       # no snapshot during the soak
    for k in ('wall_time_s', 'finished'):
        p.pop(k, None)
    with open(os.path.join(run_dir, 'run.json'), 'w') as f:
        json.dump(p, f, indent=1)
    cmd = [os.path.join(REPO, 'scripts', 'yade'), '-j1', '-n', '-x', os.path.join(REPO, 'scripts', 'pile.py'),
           '--out', run_dir, '--resume']
    logf = open(os.path.join(a.out, 'log.txt'), 'w')
    proc = subprocess.Popen(cmd, stdout=logf, stderr=subprocess.STDOUT, start_new_session=True)
    rows, t0 = [], time.time()
    try:
        while time.time() - t0 < a.hours * 3600 and proc.poll() is None:
            t_sim, grains, contacts = last_progress(run_dir)
            rows.append((time.time() - t0, rss_mb(proc.pid), t_sim, grains, contacts))
            print('soak: %6.0f s  RSS %7.1f MB  t=%.3f s  contacts %d' % (rows[-1][:3] + (contacts,)), flush=True)
            time.sleep(a.every)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(timeout=60)
        logf.close()
    with open(os.path.join(a.out, 'soak.csv'), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['wall_s', 'rss_mb', 'sim_time_s', 'grains', 'contacts'])
        w.writerows(rows)
    data = np.array(rows)
    late = data[data[:, 0] >= 300]
    summary = dict(source=a.source, hours=a.hours, samples=len(rows), exit_before_end=proc.returncode,
                   rss_first_mb=float(data[0, 1]), rss_at_5min_mb=float(late[0, 1]) if len(late) else None,
                   rss_end_mb=float(data[-1, 1]), rss_max_mb=float(np.nanmax(data[:, 1])),
                   sim_time_start_s=float(data[0, 2]), sim_time_end_s=float(data[-1, 2]),
                   contacts_start=int(data[0, 4]), contacts_end=int(data[-1, 4]))
    if len(late) >= 3:
        slope, icpt = np.polyfit(late[:, 0] / 3600, late[:, 1], 1)
        resid = late[:, 1] - (slope * late[:, 0] / 3600 + icpt)
        summary.update(growth_mb_per_hour=float(slope), scatter_mb=float(resid.std()),
                       growth_over_run_mb=float(slope * (late[-1, 0] - late[0, 0]) / 3600))
    with open(os.path.join(a.out, 'soak.json'), 'w') as f:
        json.dump(summary, f, indent=1)
    plot(data, summary, os.path.join(a.out, 'soak_rss.png'))
    print(json.dumps(summary, indent=1))
    return 0


def plot(data, s, path):
    """Resident memory against wall time, with the growth line fitted in ``s``, into ``path``."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ax.plot(data[:, 0] / 60, data[:, 1], '.-', ms=3, lw=0.8, label='resident memory (VmRSS)')
    ax.set_xlabel('wall time [min]')
    ax.set_ylabel('RSS [MB]')
    settled = data[data[:, 0] >= 120, 1]       # after YADE's start-up and the first checkpoints
    if len(settled):
        lo, hi = settled.min(), settled.max()
        ax.set_ylim(lo - max(5.0, hi - lo), hi + max(5.0, hi - lo))
        ax.text(0.01, 0.03, 'first 2 min (start-up, first checkpoints): 0 to %.0f MB, off scale' % settled[0],
                transform=ax.transAxes, fontsize=7)
    title = 'Soak: %d-grain pile relaxing, checkpoint every 60 s' % (data[-1, 3] or 0)
    if 'growth_mb_per_hour' in s:
        title += '\ngrowth after 5 min: %+.2f MB/h (scatter %.2f MB)' % (s['growth_mb_per_hour'], s['scatter_mb'])
    ax.set_title(title, fontsize=9)
    ax2 = ax.twinx()
    ax2.plot(data[:, 0] / 60, data[:, 4], color='0.6', lw=0.8, label='contacts')
    ax2.set_ylabel('contacts', color='0.4')
    ax.legend(loc='lower right', fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == '__main__':
    sys.exit(main())

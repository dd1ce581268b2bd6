"""What a pile run's wall time went into, from its own records: ``progress.csv`` (simulated time,
grains, contacts, sweeps, residual, the run's wall time) and ``segments.csv`` (one line per
segment: when and where it ran). Pure numpy: no YADE.

A long run is carried between machines and sessions, and the machines differ (by a factor of
about three per contact-sweep between the hosts in docs/performance.md). Its total wall time
only means something with that cost beside it, so :func:`cost_windows` gives, per window of
simulated time and per segment, the wall time per simulated second and the **all-in cost per
contact-sweep**: the window's wall time over Σ steps × contacts × sweeps. Each progress line
samples the sweeps of one step only (steps vary 300–1300 sweeps), so the estimate is a ratio of
sums over many lines, not a per-line number; a window of fewer than ``min_lines`` lines is not
reported.
"""
import csv
import os
import time
import warnings

import numpy as np

from ..io import host_description

SEGMENT_FIELDS = ('started_unix', 't_start_s', 'wall_before_s', 'threads', 'host', 'cpu')


def append_segment(run_dir, t_start, wall_before, threads):
    """Record the start of a run segment (a start or a resume) in ``run_dir/segments.csv``."""
    path = os.path.join(run_dir, 'segments.csv')
    new = not os.path.exists(path) or os.path.getsize(path) == 0
    host, cpu = host_description()
    with open(path, 'a', newline='') as f:
        w = csv.writer(f)
        if new:
            w.writerow(SEGMENT_FIELDS)
        w.writerow(['%.1f' % time.time(), '%.6f' % t_start, '%.1f' % wall_before, threads, host, cpu])
    return path


def read_progress(path):
    """``progress.csv`` as a dict of float arrays (time_s, grains, contacts, sweeps, residual, wall_s);
    a line with the wrong number of fields (the last one, cut short by a full disk) is passed over."""
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')     # numpy warns of every line it passes over
        a = np.genfromtxt(path, delimiter=',', names=True, ndmin=1, invalid_raise=False)
    return {k: np.asarray(a[k], dtype=float) for k in a.dtype.names}


def read_segments(path):
    """``segments.csv`` as a list of dicts in the order of their simulated start time (the order
    :func:`cost_windows` numbers them in; a resume from an older checkpoint after a crash starts
    earlier than the segment before it); empty when the file is absent (runs older than it)."""
    if not os.path.exists(path):
        return []
    with open(path, newline='') as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        r['t_start_s'] = float(r['t_start_s'])
        r['started_unix'] = float(r['started_unix'])
        r['wall_before_s'] = float(r['wall_before_s'])
    return sorted(rows, key=lambda r: r['t_start_s'])


def cost_windows(progress, dt, window_s, segments=(), min_lines=5):
    """Cost of a run per window of simulated time, split at segment starts.

    :param progress: :func:`read_progress`'s dict.
    :param dt: the run's time step [s].
    :param window_s: window length in simulated time [s].
    :param segments: :func:`read_segments`'s list, numbered in order of start time (the interval of two progress lines that
        straddles a segment start is left out: part of it was run, and lost, by the segment before).
    :returns: list of dicts: window start and end [s], segment index (−1 without segments), grains
        and contacts at the window's end, wall time [s], simulated time [s], wall per simulated
        second, steps, all-in ns per contact-sweep, number of progress intervals.
    """
    t, w = progress['time_s'], progress['wall_s']
    work = progress['contacts'] * progress['sweeps']
    starts = sorted(s['t_start_s'] for s in segments)
    rows = []
    if len(t) < 2:
        return rows
    t0, t1, dw = t[:-1], t[1:], np.diff(w)
    ok = (t1 > t0) & (dw >= 0)
    for s in starts:
        ok &= ~((t0 < s - 0.5 * dt) & (t1 > s + 0.5 * dt))
    seg = np.searchsorted(np.array(starts), t0 + 0.5 * dt, side='right') - 1 if starts else np.full(len(t0), -1)
    win = np.floor(t0 / window_s + 1e-9).astype(int)   # by the interval's start
    for key in sorted(set(zip(win[ok], seg[ok]))):
        m = ok & (win == key[0]) & (seg == key[1])
        if m.sum() < min_lines:
            continue
        steps = np.round((t1[m] - t0[m]) / dt)
        wall, sim = float(dw[m].sum()), float((t1[m] - t0[m]).sum())
        last = np.flatnonzero(m)[-1] + 1
        rows.append({'t_from_s': float(t0[m][0]), 't_to_s': float(t1[m][-1]), 'segment': int(key[1]),
                     'grains': int(progress['grains'][last]), 'contacts': int(progress['contacts'][last]),
                     'wall_s': wall, 'sim_s': sim, 'wall_per_sim_s': wall / sim, 'steps': int(steps.sum()),
                     'ns_per_contact_sweep': 1e9 * wall / float((steps * work[1:][m]).sum()),
                     'intervals': int(m.sum())})
    return rows


def remaining_wall(progress, end_s, feed_end_s, min_intervals=8, max_intervals=400):
    """Wall time [s] an unfinished run still needs at the pace of its own recent past, or None
    when its record is too short to say.

    During the feed the cost per simulated second grows with the pile (more contacts, more
    sweeps per step), close to a power of the simulated time: c(t) = a·t^β. Each interval
    between two progress lines in the second half of the record gives a rate Δwall/Δt at its
    middle time, and a, β come from a Theil–Sen fit of log rate on log t (the median of the
    pairwise slopes, then the median intercept), so that intervals slowed by a pause or by
    another process (each lands in one interval) move the fit little; β is kept in [0, 3]. The
    rest of the feed costs ∫ c dt up to ``feed_end_s``; the relaxation (to ``end_s``) at the rate
    the feed ends with. A run already relaxing: the median rate of its intervals times the time
    left. A longer record is thinned evenly over the whole second half to ``max_intervals``
    intervals, so that β is fitted over the half's whole span of log t (the latest intervals
    alone span too little of it: on the paper's full pile at t = 30 s the latest 400 gave 35 h
    and the latest 200 gave 17 h, the whole half 20 h). Fewer than ``min_intervals``: None.

    :param progress: :func:`read_progress`'s dict (``time_s``, ``wall_s``).
    :param end_s: simulated time at which the run ends [s].
    :param feed_end_s: simulated time at which its feed ends [s] (≤ ``end_s``).
    """
    t = np.asarray(progress.get('time_s', ()), dtype=float)
    w = np.asarray(progress.get('wall_s', ()), dtype=float)
    if t.size < 2 or end_s is None or feed_end_s is None:
        return None
    now = float(t[-1])
    if now >= end_s:
        return 0.0
    dt, dw = np.diff(t), np.diff(w)
    mid = 0.5 * (t[1:] + t[:-1])
    ok = (dt > 0) & (dw > 0) & (t[:-1] >= 0.5 * now)
    mid, rate = mid[ok], dw[ok] / dt[ok]
    if rate.size > max_intervals:
        pick = np.unique(np.round(np.linspace(0, rate.size - 1, max_intervals)).astype(int))
        mid, rate = mid[pick], rate[pick]
    if rate.size < min_intervals:
        return None
    if now >= feed_end_s:
        return float(np.median(rate) * (end_s - now))
    x, y = np.log(mid), np.log(rate)
    i, j = np.triu_indices(x.size, 1)
    keep = x[j] != x[i]
    beta = float(np.clip(np.median((y[j] - y[i])[keep] / (x[j] - x[i])[keep]), 0.0, 3.0))
    a = float(np.exp(np.median(y - beta * x)))
    feed = a / (beta + 1) * (feed_end_s ** (beta + 1) - now ** (beta + 1))
    relax = a * feed_end_s ** beta * (end_s - feed_end_s)
    return float(feed + relax)


def work_by_grains(progress, dt, bin_grains, min_lines=5):
    """The solver's work per simulated second along a run, by the pile's size: machine-free, so
    that two runs of one pile under two protocols (time steps, tolerances) can be compared even
    when they ran on different hosts or thread counts.

    Each interval between two progress lines stands for its Δt/dt steps, with the contacts and
    the sweeps of the step its closing line sampled. Per bin of the grain count at the interval's
    end: the steps' mean sweeps Σ steps·sweeps / Σ steps and the contact-sweeps per simulated
    second Σ steps·contacts·sweeps / Σ Δt. A bin of fewer than ``min_lines`` intervals is not
    reported.

    The closing line samples the last step of a stretch of steps that ended after ten seconds of
    wall time, so a long stretch is a little more likely to be sampled than a short one; with
    step-to-step scatter of the sweeps (CV ≈ 0.4 measured) and 5–25 steps per stretch the bias
    is a few per cent at most (more only where the sweeps vary slowly over many stretches).

    :param progress: :func:`read_progress`'s dict.
    :param dt: the run's time step [s].
    :param bin_grains: bin width in grains.
    :returns: list of dicts: bin's grain range, intervals, steps, simulated time [s], mean
        contacts, mean sweeps per step, contact-sweeps per simulated second.
    """
    if not bin_grains > 0 or not dt > 0:
        raise ValueError('work_by_grains: bin_grains and dt must be > 0 (got %r, %r)' % (bin_grains, dt))
    t = np.asarray(progress['time_s'], dtype=float)
    if t.size < 2:
        return []
    sim = np.diff(t)
    grains, contacts, sweeps = (np.asarray(progress[k], dtype=float)[1:] for k in ('grains', 'contacts', 'sweeps'))
    ok = sim > 0
    steps = np.round(sim / dt)
    b = np.floor(grains / bin_grains).astype(int)
    rows = []
    for k in sorted(set(b[ok])):
        m = ok & (b == k)
        if m.sum() < min_lines:
            continue
        n = steps[m]
        rows.append({'grains_from': int(k * bin_grains), 'grains_to': int((k + 1) * bin_grains),
                     'intervals': int(m.sum()), 'steps': int(n.sum()), 'sim_s': float(sim[m].sum()),
                     'contacts': float((n * contacts[m]).sum() / n.sum()),
                     'sweeps_per_step': float((n * sweeps[m]).sum() / n.sum()),
                     'contact_sweeps_per_sim_s': float((n * contacts[m] * sweeps[m]).sum() / sim[m].sum())})
    return rows


def compare_work(rows, other_rows):
    """:func:`work_by_grains` of two runs side by side, on the grain bins both report (same bin
    width): per bin the two runs' sweeps per step and the ratio of their contact-sweeps per
    simulated second, ``run / other``. Raises ValueError when the bins differ in width or none is
    shared."""
    width = {r['grains_to'] - r['grains_from'] for r in list(rows) + list(other_rows)}
    if len(width) > 1:
        raise ValueError('compare_work: the two runs were binned with different widths %s' % sorted(width))
    other = {r['grains_from']: r for r in other_rows}
    out = []
    for r in rows:
        o = other.get(r['grains_from'])
        if o is None:
            continue
        out.append({'grains_from': r['grains_from'], 'grains_to': r['grains_to'],
                    'sweeps_per_step': r['sweeps_per_step'], 'other_sweeps_per_step': o['sweeps_per_step'],
                    'contacts': r['contacts'], 'other_contacts': o['contacts'],
                    'work_ratio': r['contact_sweeps_per_sim_s'] / o['contact_sweeps_per_sim_s']})
    if not out:
        raise ValueError('compare_work: the two runs share no grain bin')
    return out

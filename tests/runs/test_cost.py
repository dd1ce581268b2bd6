"""What a run's wall time went into (yadecd.runs.cost) on constructed progress records with known
costs: two segments on hosts of different speed, the interval that straddles a resume left out,
sparse windows dropped, the segment log written and read back, and scripts/pile_cost.py's line
on where a run stands."""
import json
import os
import subprocess
import sys
import tempfile
import unittest

import numpy as np

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd.runs import cost as runcost


def progress(costs_ns, dt=1e-3, line_every=10, contacts=lambda t: 1000 + 100 * t, sweeps=lambda k: 300 + 50 * (k % 7)):
    """Progress lines every ``line_every`` steps; the wall time of each interval is steps ×
    contacts × sweeps × the cost [ns] of the segment (``costs_ns``: list of (t_start, cost)) in
    force at the interval's start. Sweeps vary from line to line as a real run's do."""
    t, w, rows = 0.0, 0.0, []
    for k in range(1, 401):
        t_new = round(k * line_every * dt, 9)
        cost = [c for s, c in costs_ns if s <= t + 0.5 * dt][-1]
        c, s = contacts(t_new), sweeps(k)
        w += line_every * c * s * cost * 1e-9
        rows.append((t_new, int(c / 3), c, s, 1e-3, w))
        t = t_new
    a = np.array(rows, dtype=float)
    return dict(zip(('time_s', 'grains', 'contacts', 'sweeps', 'residual', 'wall_s'), a.T))


class TestCostWindows(unittest.TestCase):

    def test_known_costs(self):
        """50 ns per contact-sweep until t = 2 s, 150 after (a slower host): every window gives its
        segment's cost exactly, and the wall time per simulated second is steps/s × contacts ×
        sweeps × cost."""
        p = progress([(0.0, 50.0), (2.0, 150.0)])
        rows = runcost.cost_windows(p, 1e-3, 1.0, [{'t_start_s': 0.0}, {'t_start_s': 2.0}])
        self.assertEqual([r['segment'] for r in rows], [0, 0, 1, 1])
        for r in rows:
            self.assertAlmostEqual(r['ns_per_contact_sweep'], 50.0 if r['segment'] == 0 else 150.0, delta=1e-9)
            self.assertEqual(r['steps'], round(r['sim_s'] / 1e-3))
        # without segment records the same windows, numbered -1, give the same costs
        bare = runcost.cost_windows(p, 1e-3, 1.0)
        self.assertEqual([r['segment'] for r in bare], [-1] * 4)
        self.assertEqual([round(r['ns_per_contact_sweep'], 6) for r in bare], [50.0, 50.0, 150.0, 150.0])
        # constant contacts and sweeps: wall per simulated second = 1000 steps × c × s × cost
        q = progress([(0.0, 80.0)], contacts=lambda t: 2000.0, sweeps=lambda k: 400)
        r = runcost.cost_windows(q, 1e-3, 2.0)[0]
        self.assertAlmostEqual(r['wall_per_sim_s'], 1000 * 2000 * 400 * 80e-9, delta=1e-9)

    def test_resume_interval_and_sparse_windows(self):
        """A segment that starts between two progress lines: the interval across it is left out
        (the window still reports its own lines); a window of fewer than min_lines lines is dropped."""
        p = progress([(0.0, 50.0), (1.005, 150.0)])
        rows = runcost.cost_windows(p, 1e-3, 1.0, [{'t_start_s': 0.0}, {'t_start_s': 1.005}])
        # the interval 1.00-1.01 straddles the start: left out, so segment 1's window starts at 1.01
        seg1 = [r for r in rows if r['segment'] == 1][0]
        self.assertAlmostEqual(seg1['t_from_s'], 1.01, delta=1e-9)
        self.assertAlmostEqual(seg1['ns_per_contact_sweep'], 150.0, delta=1e-9)
        self.assertEqual(sum(r['intervals'] for r in rows), 399 - 1)
        few = runcost.cost_windows({k: v[:4] for k, v in p.items()}, 1e-3, 1.0)
        self.assertEqual(few, [])
        self.assertEqual(runcost.cost_windows({k: v[:1] for k, v in p.items()}, 1e-3, 1.0), [])


class TestSegmentLog(unittest.TestCase):

    def test_append_and_read(self):
        with tempfile.TemporaryDirectory() as d:
            self.assertEqual(runcost.read_segments(os.path.join(d, 'segments.csv')), [])
            runcost.append_segment(d, 0.0, 0.0, 2)
            runcost.append_segment(d, 25.975, 8349.4, 1)
            runcost.append_segment(d, 20.0, 7000.0, 2)   # a resume from an older checkpoint after a crash
            segs = runcost.read_segments(os.path.join(d, 'segments.csv'))
            self.assertEqual([s['t_start_s'] for s in segs], [0.0, 20.0, 25.975])   # in order of start time
            self.assertEqual([s['threads'] for s in segs], ['2', '2', '1'])
            self.assertAlmostEqual(segs[2]['wall_before_s'], 8349.4)
            self.assertTrue(segs[0]['host'] and segs[0]['cpu'])


class TestRemainingWall(unittest.TestCase):
    """remaining_wall: the wall time a run still needs, on records with a known cost law."""
    A, BETA = 50.0, 1.5          # cost per simulated second c(t) = A t^BETA [s/s]

    def record(self, t_end=6.0, pause=None):
        """Progress lines every 0.05 s of simulated time to t_end, the wall time the integral of
        c; ``pause``: (t, seconds) added to the wall time from t on (a stopped or slowed segment)."""
        t = np.round(np.arange(1, int(round(t_end / 0.05)) + 1) * 0.05, 9)
        w = self.A * t ** (self.BETA + 1) / (self.BETA + 1)
        if pause:
            w = w + np.where(t >= pause[0], pause[1], 0.0)
        return {'time_s': t, 'wall_s': w}

    def exact(self, now, feed_end, end):
        """The rest of the feed at c(t), the relaxation at the feed's last rate."""
        a, b = self.A, self.BETA
        return a / (b + 1) * (feed_end ** (b + 1) - now ** (b + 1)) + a * feed_end ** b * (end - feed_end)

    def test_power_law_feed(self):
        est = runcost.remaining_wall(self.record(), end_s=9.0, feed_end_s=8.0)
        self.assertAlmostEqual(est / self.exact(6.0, 8.0, 9.0), 1.0, delta=5e-4)

    def test_one_window_with_a_pause_moves_it_little(self):
        # 2000 s of wall time in one interval of the second half (a run stopped with SIGSTOP, or
        # a host shared with another run): a least-squares fit of the rates would be 73 % off
        est = runcost.remaining_wall(self.record(pause=(4.6, 2000.0)), end_s=9.0, feed_end_s=8.0)
        self.assertAlmostEqual(est / self.exact(6.0, 8.0, 9.0), 1.0, delta=5e-3)

    def test_a_long_noisy_record_is_fitted_over_its_whole_second_half(self):
        """2400 intervals in the second half, each rate off the law by a log-normal factor
        (σ = 0.3, as step-to-step sweeps scatter), 20 seeds. Thinned evenly to 400 over the
        half, β is fitted over ln 2 of log t: Theil–Sen's slope error is then about
        1.05 σ / (sd(ln t) √400) ≈ 0.08, which, carried from the fit's centre (t ≈ 4.4 s) to the
        rest of the run (t ≈ 7 s), with the intercept's own error, makes the estimate's log error
        ≈ 0.04 r.m.s. (0.036 over these seeds). The latest 400 intervals alone span 1/12 of ln 2
        and miss by ≈ 0.18 r.m.s. over the same seeds, so a bound of 0.06 tells the two apart."""
        t = np.round(np.arange(1, 4801) * 0.00125, 9)            # to 6 s
        rate = self.A * (t - 0.000625) ** self.BETA              # at each interval's middle
        exact = self.exact(6.0, 8.0, 9.0)
        errs = []
        for seed in range(20):
            noise = np.exp(np.random.default_rng(seed).normal(0.0, 0.3, t.size))
            rec = {'time_s': t, 'wall_s': np.cumsum(0.00125 * rate * noise)}
            errs.append(np.log(runcost.remaining_wall(rec, end_s=9.0, feed_end_s=8.0) / exact))
        self.assertLess(np.sqrt(np.mean(np.square(errs))), 0.06)
        self.assertLess(abs(np.mean(errs)), 0.03)             # no bias: the median follows the law

    def test_relaxing_at_a_constant_rate(self):
        t = np.round(np.arange(1, 201) * 0.05, 9)           # to 10 s, past the feed's end at 8 s
        w = 300.0 * t
        est = runcost.remaining_wall({'time_s': t, 'wall_s': w}, end_s=11.0, feed_end_s=8.0)
        self.assertAlmostEqual(est, 300.0 * 1.0, delta=1e-6)

    def test_no_estimate_without_a_record_or_an_end(self):
        rec = self.record()
        self.assertIsNone(runcost.remaining_wall(rec, end_s=None, feed_end_s=None))
        self.assertIsNone(runcost.remaining_wall({'time_s': np.array([0.5]), 'wall_s': np.array([3.0])}, 9.0, 8.0))
        # a sparse record: fewer than 8 intervals in its second half
        sparse = {k: v[::8] for k, v in rec.items()}
        self.assertLess(np.sum(sparse['time_s'][:-1] >= 3.0), 8)
        self.assertIsNone(runcost.remaining_wall(sparse, 9.0, 8.0))
        self.assertEqual(runcost.remaining_wall(rec, end_s=6.0, feed_end_s=5.0), 0.0)

    def test_reads_only_the_second_half(self):
        """A record that starts late (a run resumed without its early lines) or whose first half
        ran at another pace (another host) gives the same estimate as the whole one."""
        rec = self.record()
        whole = runcost.remaining_wall(rec, 9.0, 8.0)
        late = {k: v[rec['time_s'] > 2.9] for k, v in rec.items()}
        self.assertEqual(runcost.remaining_wall(late, 9.0, 8.0), whole)
        slow_start = dict(rec, wall_s=rec['wall_s'] * np.where(rec['time_s'] < 3.0, 3.0, 1.0)
                          + np.where(rec['time_s'] >= 3.0, 2 * rec['wall_s'][rec['time_s'] < 3.0][-1], 0.0))
        self.assertAlmostEqual(runcost.remaining_wall(slow_start, 9.0, 8.0), whole, delta=1e-9 * whole)


def fed_record(dt, sweeps_pattern, steps_pattern, n_lines=200, rate=250.0):
    """A fed run's progress lines: intervals of ``steps_pattern`` steps in turn (uneven, as the
    wall-time clock of the progress lines makes them), grains = rate·t, contacts = 3·grains, and
    the sampled step's sweeps ``sweeps_pattern`` in turn."""
    rows, n = [], 0
    for k in range(n_lines):
        n += steps_pattern[k % len(steps_pattern)]
        t = n * dt
        g = int(rate * t + 1e-9)
        rows.append((t, g, 3 * g, sweeps_pattern[k % len(sweeps_pattern)], 1e-3, float(k)))
    return dict(zip(('time_s', 'grains', 'contacts', 'sweeps', 'residual', 'wall_s'), np.array(rows, dtype=float).T))


class TestWorkByGrains(unittest.TestCase):
    """work_by_grains / compare_work: the machine-free work per simulated second of two runs of
    one pile, on constructed records whose answer is known."""

    def test_step_weighted_sweeps_and_the_ratio(self):
        """Sweeps 100 and 300 sampled after 10 and 30 steps in turn: the steps' mean is 250 (the
        lines' plain mean would be 200). Against a run at 5× the time step with 500 sweeps a step
        on the same grains, the work per simulated second is 5·250/500 = 2.5× (the contacts are the
        same function of the grains). At 250 grains/s a pair of lines spans 2 grains, so every bin of
        50 holds as many lines of each kind."""
        a = fed_record(2e-4, (100, 300), (10, 30), n_lines=2000)
        b = fed_record(1e-3, (500,), (8,), n_lines=2000)
        ra, rb = runcost.work_by_grains(a, 2e-4, 50), runcost.work_by_grains(b, 1e-3, 50)
        for r in ra[1:]:
            self.assertEqual(r['sweeps_per_step'], 250.0)
        for r in rb:
            self.assertEqual(r['sweeps_per_step'], 500.0)
            # 1000 steps per simulated second, 500 sweeps, contacts of the bin's steps
            self.assertAlmostEqual(r['contact_sweeps_per_sim_s'], 1000 * 500 * r['contacts'], delta=1e-6 * r['contact_sweeps_per_sim_s'])
        cmp = runcost.compare_work(ra, rb)
        self.assertGreaterEqual(len(cmp), 5)
        for r in cmp[1:]:
            self.assertAlmostEqual(r['work_ratio'], 2.5 * r['contacts'] / r['other_contacts'], delta=1e-9)
            self.assertAlmostEqual(r['work_ratio'], 2.5, delta=0.01)

    def test_sparse_bins_repeated_lines_and_bad_input(self):
        """A bin with fewer than min_lines intervals is left out; a zero-length interval (a line
        repeated at a resume) counts for nothing; bins of different widths, no shared bin and a
        zero width are refused with the culprit named."""
        a = fed_record(1e-3, (200,), (8,), n_lines=60)        # grains 2 .. 120 by 2
        rows = runcost.work_by_grains(a, 1e-3, 50)
        self.assertEqual([r['grains_from'] for r in rows], [0, 50, 100])
        self.assertEqual(rows[-1]['intervals'], 11)           # grains 100..120
        self.assertEqual([r['grains_from'] for r in runcost.work_by_grains(a, 1e-3, 50, min_lines=12)], [0, 50])
        rep = {k: np.insert(v, 30, v[29]) for k, v in a.items()}   # line 29 written twice
        self.assertEqual(runcost.work_by_grains(rep, 1e-3, 50), rows)
        with self.assertRaisesRegex(ValueError, 'different widths'):
            runcost.compare_work(rows, runcost.work_by_grains(a, 1e-3, 40))
        far = fed_record(1e-3, (200,), (8,), n_lines=60, rate=2500.0)    # grains 20 .. 1200 by 20
        with self.assertRaisesRegex(ValueError, 'share no grain bin'):
            runcost.compare_work(rows, [r for r in runcost.work_by_grains(far, 1e-3, 50) if r['grains_from'] >= 150])
        with self.assertRaisesRegex(ValueError, 'bin_grains'):
            runcost.work_by_grains(a, 1e-3, 0)


class TestPileCostCommand(unittest.TestCase):
    """``pile_cost.py RUN``: the window table, then where an unfinished run stands and the wall
    time it still needs at its recent pace (the ensemble status's estimate); 'finished' once done."""

    def test_standing_line(self):
        script = os.path.join(SCRIPTS, 'pile_cost.py')
        python = '/usr/bin/python3' if os.path.exists('/usr/bin/python3') else sys.executable
        with tempfile.TemporaryDirectory() as d:
            params = {'n_grains': 1000, 'rate': 200.0, 'dt': 5e-4, 'relax': 1.0}
            with open(os.path.join(d, 'run.json'), 'w') as f:
                json.dump(params, f)
            with open(os.path.join(d, 'progress.csv'), 'w') as f:      # to 3 s at c(t) = 40 t s/s
                f.write('time_s,grains,contacts,sweeps,residual,wall_s\n')
                for x in [0.05 * k for k in range(1, 61)]:
                    f.write('%.2f,%d,%d,50,1e-3,%.3f\n' % (x, 200 * x, 600 * x, 20 * x * x))
            run = lambda: subprocess.run([python, script, d, '--window', '0.5', '--out', d],  # noqa: E731
                                         capture_output=True, text=True, timeout=120)
            r = run()
            self.assertEqual(r.returncode, 0, r.stderr)
            # the feed ends near 5 s, then 1 s of relaxation: 20 (5² − 3²) + 40·5·1 = 520 s more
            self.assertRegex(r.stdout, r'stands at t = 3\.000 s of 6\.\d+ s, 600 grains, 0\.05 h of wall time so far; '
                                       r'about 0\.1 h more at its recent pace')
            with open(os.path.join(d, 'run.json'), 'w') as f:
                json.dump(dict(params, wall_time_s=700.0, finished=True), f)
            open(os.path.join(d, 'snap_0006.000.npz'), 'w').close()
            r = run()
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertRegex(r.stdout, r'\nfinished\n')

    def test_against(self):
        """``--against OTHER``: the work table by grains, against.csv and against.png written; an
        other run without a progress record is refused by name."""
        script = os.path.join(SCRIPTS, 'pile_cost.py')
        python = '/usr/bin/python3' if os.path.exists('/usr/bin/python3') else sys.executable
        with tempfile.TemporaryDirectory() as d:
            runs = []
            for name, dt, sweeps, steps in (('a', 2e-4, (100, 300), (10, 30)), ('b', 1e-3, (500,), (8,))):
                rd = os.path.join(d, name)
                os.makedirs(rd)
                with open(os.path.join(rd, 'run.json'), 'w') as f:
                    json.dump({'n_grains': 1000, 'rate': 250.0, 'dt': dt, 'relax': 1.0}, f)
                rec = fed_record(dt, sweeps, steps, n_lines=1000)
                with open(os.path.join(rd, 'progress.csv'), 'w') as f:
                    f.write('time_s,grains,contacts,sweeps,residual,wall_s\n')
                    for row in zip(*(rec[k] for k in ('time_s', 'grains', 'contacts', 'sweeps', 'residual', 'wall_s'))):
                        f.write('%.6f,%d,%d,%d,%.3e,%.1f\n' % row)
                runs.append(rd)
            r = subprocess.run([python, script, runs[0], '--out', d, '--against', runs[1], '--bin', '50'],
                               capture_output=True, text=True, timeout=120)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertRegex(r.stdout, r'\n +50-100 +250 +500 +2\.50\n')
            self.assertTrue(os.path.exists(os.path.join(d, 'against.csv')))
            self.assertTrue(os.path.exists(os.path.join(d, 'against.png')))
            r = subprocess.run([python, script, runs[0], '--out', d, '--against', d],
                               capture_output=True, text=True, timeout=120)
            self.assertNotEqual(r.returncode, 0)
            self.assertIn('--against %s holds no progress.csv' % d, r.stderr)


if __name__ == '__main__':
    unittest.main()

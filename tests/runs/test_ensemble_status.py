"""``pile_ensemble.py status`` (yadecd.runs.ensemble.status_lines) on a constructed ensemble
directory: a finished run shows its wall time, a running one where it stands (simulated time of
its end, grains, wall time so far, from progress.csv and run.json), a failed one its error, one
not started nothing more; a progress line cut short (a full disk) is passed over, not an error."""
import json
import os
import tempfile
import unittest

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd.runs import ensemble


class TestStatus(unittest.TestCase):
    def test_lines(self):
        with tempfile.TemporaryDirectory() as root:
            e = ensemble.Ensemble(root)
            e.plan([1000], [1, 2, 3, 4], 1.0, ['--grain-shape', 'dimer'])
            runs = e.runs()
            names = sorted(runs)
            self.assertEqual(names, ['dimer_n1000_s%d' % s for s in (1, 2, 3, 4)])
            runs[names[0]].update(state='done', attempts=1, wall_s=512.4)
            runs[names[1]].update(state='submitted', attempts=2)
            runs[names[2]].update(state='failed', attempts=3, error='Traceback\nValueError: bad grain')
            e.save()
            for k, name in enumerate(names):
                os.makedirs(os.path.join(root, name))
            params = {'n_grains': 1000, 'rate': 200.0, 'dt': 5e-4, 'relax': 1.0}
            with open(os.path.join(root, names[0], 'run.json'), 'w') as f:
                json.dump(dict(params, wall_time_s=512.4), f)
            open(os.path.join(root, names[0], 'snap_0006.000.npz'), 'w').close()
            with open(os.path.join(root, names[1], 'run.json'), 'w') as f:
                json.dump(params, f)
            with open(os.path.join(root, names[1], 'progress.csv'), 'w') as f:
                f.write('time_s,grains,contacts,sweeps,residual,wall_s\n1.0,200,500,30,9e-4,40.0\n2.5,500,1400,60,9.9e-4,151.7\n')
            with open(os.path.join(root, names[3], 'progress.csv'), 'w') as f:
                f.write('time_s,grains,contacts,sweeps,residual,wall_s\n1.0,200,5')   # cut short by a full disk
            lines = ensemble.status_lines(root)
        self.assertEqual(len(lines), 4)
        self.assertRegex(lines[0], r'^dimer_n1000_s1 +done +attempts 1  512 s$')
        # the feed of 1000 grains at 200 per second ends at 5 s (feed_time), then 1 s of relaxation
        end = ensemble.feed_time(1000, 200.0, 5e-4) + 1.0
        self.assertAlmostEqual(end, 6.0, delta=0.01)
        self.assertRegex(lines[1], r'^dimer_n1000_s2 +submitted +attempts 2  t = 2\.50 of %.2f s, 500 grains, '
                                   r'152 s of wall time so far$' % end)
        self.assertRegex(lines[2], r'^dimer_n1000_s3 +failed +attempts 3  +error: ValueError: bad grain$')
        self.assertRegex(lines[3], r'^dimer_n1000_s4 +pending +attempts 0  $')

    def test_line_says_what_is_left(self):
        """A run with a long enough record: its line adds the wall time it still needs at its
        recent pace (yadecd.runs.cost.remaining_wall, tested on its own in test_cost)."""
        from yadecd.runs import cost as runcost
        with tempfile.TemporaryDirectory() as root:
            e = ensemble.Ensemble(root)
            e.plan([1000], [1], 1.0, [])
            name = sorted(e.runs())[0]
            e.runs()[name].update(state='submitted', attempts=1)
            e.save()
            d = os.path.join(root, name)
            os.makedirs(d)
            with open(os.path.join(d, 'run.json'), 'w') as f:
                json.dump({'n_grains': 1000, 'rate': 200.0, 'dt': 5e-4, 'relax': 1.0}, f)
            t = [0.05 * k for k in range(1, 61)]                     # to 3 s, c(t) = 40 t s/s
            with open(os.path.join(d, 'progress.csv'), 'w') as f:
                f.write('time_s,grains,contacts,sweeps,residual,wall_s\n')
                for x in t:
                    f.write('%.2f,%d,%d,50,1e-3,%.3f\n' % (x, 200 * x, 600 * x, 20 * x * x))
            left = ensemble.progress_of(d)['remaining_s']
            feed_end = ensemble.feed_time(1000, 200.0, 5e-4)
            exact = 20 * (feed_end ** 2 - 9.0) + 40 * feed_end * 1.0
            self.assertAlmostEqual(left / exact, 1.0, delta=1e-3)
            self.assertEqual(left, runcost.remaining_wall(runcost.read_progress(os.path.join(d, 'progress.csv')), feed_end + 1.0, feed_end))
            line = ensemble.status_lines(root)[0]
        self.assertRegex(line, r' 180 s of wall time so far, about %d min more at its recent pace$' % round(exact / 60))

    def test_progress_without_run_json(self):
        with tempfile.TemporaryDirectory() as d:
            self.assertIsNone(ensemble.progress_of(d))
            for text in ('', 'time_s,grains,contacts,sweeps,residual,wall_s\n'):   # created, header not yet or only it
                with open(os.path.join(d, 'progress.csv'), 'w') as f:
                    f.write(text)
                self.assertIsNone(ensemble.progress_of(d))
            with open(os.path.join(d, 'progress.csv'), 'w') as f:
                f.write('time_s,grains,contacts,sweeps,residual,wall_s\n0.75,150,300,20,1e-3,12.0\n')
            self.assertEqual(ensemble.progress_of(d), {'time_s': 0.75, 'end_s': None, 'grains': 150, 'wall_s': 12.0,
                                                    'remaining_s': None})
            with open(os.path.join(d, 'progress.csv'), 'a') as f:
                f.write('0.80,160,3')     # a last line cut short: the one before stands
            self.assertEqual(ensemble.progress_of(d)['time_s'], 0.75)


if __name__ == '__main__':
    unittest.main()

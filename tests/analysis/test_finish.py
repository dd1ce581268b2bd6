"""Finishing a long pile run (yadecd.analysis.finish, scripts/pile_finish.py) on a real 30-grain run:
the end of the feed and the relaxed pile re-solved tightly from their checkpoints, one step later
than each; their records named as the ensembles'; an interrupted finish going on without redoing
a re-solve; a run that cannot give an epoch yet refused with the reason."""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

from repo_package import REPO, SCRIPTS
import yadecd.pile as pile
from yadecd.runs.carry import FEED_END_DIR
from yadecd.analysis.finish import finish

TINY = dict(n_grains=30, relax=0.05, snap_every=1e9, seed=5)   # the feed ends at 0.15 s, the run at 0.2 s
QUIET = dict(log=lambda s: None)


class TestFinish(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix='cd-finish-')
        cls.run_dir = os.path.join(cls.tmp, 'run')
        cls.p = pile.run(cls.run_dir, **TINY, **QUIET)
        cls.t_feed = pile.feed_end_time(cls.p)
        cls.out = os.path.join(cls.tmp, 'finished')
        cls.lines = []
        cls.records = finish(cls.run_dir, cls.out, REPO, log=cls.lines.append)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_both_epochs_one_step_after_their_checkpoints(self):
        dt = self.p['dt']
        for epoch, t in (('feed', self.t_feed), ('relaxed', self.t_feed + TINY['relax'])):
            rec = self.records[epoch]
            self.assertAlmostEqual(rec['time_s'], t + dt, delta=1e-9)
            self.assertEqual(rec['snapshot'], 'snap_%08.3f.npz' % (t + dt))
            self.assertEqual((rec['run'], rec['epoch'], rec['n_grains'], rec['seed']), ('n30_s5', epoch, 30, 5))
            with open(os.path.join(self.out, 'records', 'n30_s5_%s.json' % epoch)) as f:
                self.assertEqual(json.load(f)['time_s'], rec['time_s'])
            with open(os.path.join(self.out, epoch, 'tolerance_effect.json')) as f:
                solves = json.load(f)['solves']
            self.assertTrue(solves['tight']['converged'])
            self.assertLessEqual(solves['tight']['residual'], 1e-6)
            self.assertEqual(solves['tight']['tolerance'], 1e-6)
            self.assertTrue(os.path.exists(os.path.join(self.out, epoch, 'figures', 'summary.json')))

    def test_again_keeps_the_resolves(self):
        lines = []
        again = finish(self.run_dir, self.out, REPO, figures=False, log=lines.append)
        self.assertEqual(sum('tight re-solve kept' in ln for ln in lines), 2)
        self.assertFalse(any('re-solving' in ln for ln in lines))
        for epoch in ('feed', 'relaxed'):
            self.assertEqual(again[epoch]['time_s'], self.records[epoch]['time_s'])
            self.assertEqual(again[epoch]['dip_D'], self.records[epoch]['dip_D'])

    def test_refusals(self):
        early = os.path.join(self.tmp, 'early')          # stopped before the end of its feed
        pile.run(early, stop_time=0.1, **TINY, **QUIET)
        with self.assertRaisesRegex(ValueError, 'no copy of itself at the end of the feed.*not finished'):
            finish(early, os.path.join(self.tmp, 'x'), REPO, **QUIET)
        late = os.path.join(self.tmp, 'late')            # past the end of its feed, not relaxed yet
        pile.run(late, stop_time=self.t_feed + 0.02, **TINY, **QUIET)
        self.assertTrue(os.path.isdir(os.path.join(late, FEED_END_DIR)))
        with self.assertRaisesRegex(ValueError, 'not finished: its relaxed pile does not exist yet'):
            finish(late, os.path.join(self.tmp, 'x'), REPO, epochs=('relaxed',), **QUIET)
        with self.assertRaisesRegex(ValueError, 'unknown epoch settled'):
            finish(late, os.path.join(self.tmp, 'x'), REPO, epochs=('settled',), **QUIET)
        with self.assertRaisesRegex(FileNotFoundError, 'no run.json'):
            finish(self.tmp, os.path.join(self.tmp, 'x'), REPO, **QUIET)
        # the feed alone, while the run relaxes: its state is the same as the finished run's
        recs = finish(late, os.path.join(self.tmp, 'late_out'), REPO, epochs=('feed',), figures=False, **QUIET)
        self.assertEqual(recs['feed']['time_s'], self.records['feed']['time_s'])
        self.assertEqual(recs['feed']['n_contacts'], self.records['feed']['n_contacts'])

    def test_command(self):
        dest = os.path.join(self.tmp, 'records_copy')
        out = subprocess.run(['/usr/bin/python3', os.path.join(SCRIPTS, 'pile_finish.py'), self.run_dir, '--out', self.out,
                              '--no-figures', '--records', dest], capture_output=True, text=True)
        self.assertEqual(out.returncode, 0, out.stderr)
        self.assertEqual(sorted(os.listdir(dest)), ['n30_s5_feed.json', 'n30_s5_relaxed.json'])
        bad = subprocess.run(['/usr/bin/python3', os.path.join(SCRIPTS, 'pile_finish.py'), self.tmp, '--out', self.out],
                             capture_output=True, text=True)
        self.assertEqual(bad.returncode, 2)
        self.assertIn('no run.json', bad.stderr)


if __name__ == '__main__':
    unittest.main(argv=[sys.argv[0]])

"""The docs places of the analyses' outputs (yadecd.analysis.publish; ``--docs`` of
scripts/pile_ensemble.py analyse and scripts/pile_growth.py): every table and figure the ensemble
analysis writes on constructed records has a place, each lands where docs/data/README.md lists
it, files without a place are left alone, and a path that is not a docs tree is refused before
any work, naming the path."""
import json
import os
import subprocess
import sys
import tempfile
import unittest

from repo_package import REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd.analysis import ensemble as pea
from yadecd.analysis import ensemble_report
from yadecd.analysis.publish import DOCS_PLACES, check_docs_root, docs_place, finished_places, publish, publish_finished

DOCS = os.path.join(REPO, 'docs')


def record(shape, n, seed, epoch, slope, p_disc, p_ring):
    """A per-run record with known values (the fields the statistics and figures read)."""
    run = ('' if shape == 'sphere' else shape + '_') + 'n%d_s%d' % (n, seed)
    return {'n_grains': n, 'seed': seed, 'epoch': epoch, 'run': run, 'grain_shape': shape,
            'slope_deg': slope, 'p_disc_Pa': p_disc, 'p_ring_Pa': p_ring, 'hydrostatic_Pa': p_ring,
            'recip_rel': [0.1, 0.2], 'recip_null': [0.5], 'recip_n_pairs': 2, 'law_angle_layer': [3.0],
            'law_angle_random': [9.0], 'law_r_over_R': [0.7], 'law_n_cuts': 1, 'packing_fraction': 0.5,
            'rings_r_over_d': [1.0, 3.0], 'rings_p_over_hydrostatic': [0.8, 1.0],
            'cache_version': pea.CACHE_VERSION}


def docs_tree(root):
    for d in ('data', 'figures'):
        os.makedirs(os.path.join(root, d))
    return root


class TestPublish(unittest.TestCase):
    def setUp(self):
        self._tmp = tempfile.TemporaryDirectory()
        self.tmp = self._tmp.name

    def tearDown(self):
        self._tmp.cleanup()

    def test_places_are_the_documented_ones(self):
        """Each pattern's place is a directory of this checkout's docs, and each named output
        listed in docs/data/README.md (or kept under docs/figures/) is found where the table puts it."""
        for pattern, place in DOCS_PLACES:
            self.assertTrue(os.path.isdir(os.path.join(DOCS, place)), (pattern, place))
        for name in ('answer_table.md', 'ensemble_summary.json', 'ensemble_table.md', 'size_trend.md', 'growth.md',
                     'shape_table.md', 'growth_dip.png', 'size_trend_dip.png', 'ensemble_dip.png',
                     'shapes_pressure_n1000.png'):
            self.assertTrue(os.path.isfile(os.path.join(DOCS, docs_place(name), name)), name)
        self.assertIsNone(docs_place('n1000_s1_relaxed.json'))
        self.assertIsNone(docs_place('growth.md.bak'))

    def test_every_output_of_the_analysis_has_a_place(self):
        """analyse_ensemble on constructed sphere and dimer records at two sizes: every file it
        writes at the top of its output has a docs place, and publish copies exactly those, byte
        for byte, leaving the per-run directory and a stray file behind."""
        root, stored, out = (os.path.join(self.tmp, x) for x in ('ens', 'stored', 'out'))
        os.makedirs(root)
        os.makedirs(stored)
        for shape, slope0 in (('sphere', 26.0), ('dimer', 33.0)):
            for n in (1000, 2000):
                for s in (1, 2, 3):
                    for epoch in ('feed', 'relaxed'):
                        r = record(shape, n, s, epoch, slope0 + 0.1 * s, 1.0 + 0.1 * s, 2.0)
                        with open(os.path.join(stored, '%s_%s.json' % (r['run'], epoch)), 'w') as f:
                            json.dump(r, f)
        ensemble_report.analyse_ensemble(root, out, n_boot=50, log=lambda m: None, records_from=[stored])
        with open(os.path.join(out, 'stray.txt'), 'w') as f:
            f.write('not an output')
        written = sorted(f for f in os.listdir(out) if os.path.isfile(os.path.join(out, f)) and f != 'stray.txt')
        self.assertIn('answer_table.md', written)
        self.assertIn('shapes_pressure_n2000.png', written)
        for name in written:
            self.assertIsNotNone(docs_place(name), name)
        docs = docs_tree(os.path.join(self.tmp, 'docs'))
        copied = publish(out, docs)
        self.assertEqual([os.path.basename(s) for s, _ in copied], written)
        for src, dest in copied:
            self.assertEqual(os.path.relpath(os.path.dirname(dest), docs), docs_place(os.path.basename(src)))
            with open(src, 'rb') as a, open(dest, 'rb') as b:
                self.assertEqual(a.read(), b.read())
        self.assertFalse(os.path.exists(os.path.join(docs, 'data', 'stray.txt')))

    def test_not_a_docs_tree(self):
        """A path without data/ and figures/ is refused, naming the path and what it lacks; nothing
        is created there."""
        wrong = os.path.join(self.tmp, 'doc')
        os.makedirs(os.path.join(wrong, 'data'))
        with self.assertRaisesRegex(ValueError, r'doc is not a docs directory \(no figures/\)'):
            check_docs_root(wrong)
        out = os.path.join(self.tmp, 'out')
        os.makedirs(out)
        with open(os.path.join(out, 'growth.md'), 'w') as f:
            f.write('x')
        with self.assertRaises(ValueError):
            publish(out, wrong)
        self.assertEqual(os.listdir(wrong), ['data'])
        self.assertEqual(os.listdir(os.path.join(wrong, 'data')), [])
        with self.assertRaisesRegex(ValueError, 'missing is not a directory'):
            publish(os.path.join(self.tmp, 'missing'), docs_tree(os.path.join(self.tmp, 'docs')))

    def test_finished_run(self):
        """A finished long run's outputs (the layout yadecd.analysis.finish writes) go to
        figures/<run>_<epoch>/, replacing a stale directory whole, and data/tolerance_effect_<run>_<epoch>.json;
        an epoch without figures copies its record only."""
        out = os.path.join(self.tmp, 'finish')
        for epoch, files in (('relaxed', ('fig5_ground_pressure.png', 'paper_table.md')), ('feed', ())):
            os.makedirs(os.path.join(out, epoch, 'figures') if files else os.path.join(out, epoch))
            for name in files:
                with open(os.path.join(out, epoch, 'figures', name), 'w') as f:
                    f.write(name)
            with open(os.path.join(out, epoch, 'tolerance_effect.json'), 'w') as f:
                json.dump({'epoch': epoch}, f)
        docs = docs_tree(os.path.join(self.tmp, 'docs'))
        stale = os.path.join(docs, 'figures', 'n14000_s2_relaxed')
        os.makedirs(stale)
        with open(os.path.join(stale, 'fig9_old.png'), 'w') as f:
            f.write('old')
        written = publish_finished(out, 'n14000_s2', ['relaxed', 'feed'], docs)
        self.assertEqual(finished_places('n14000_s2', 'feed'),
                         ('figures/n14000_s2_feed', 'data/tolerance_effect_n14000_s2_feed.json'))
        self.assertEqual([os.path.relpath(w, docs) for w in written],
                         ['figures/n14000_s2_relaxed', 'data/tolerance_effect_n14000_s2_relaxed.json',
                          'data/tolerance_effect_n14000_s2_feed.json'])
        self.assertEqual(sorted(os.listdir(stale)), ['fig5_ground_pressure.png', 'paper_table.md'])
        with open(os.path.join(docs, 'data', 'tolerance_effect_n14000_s2_feed.json')) as f:
            self.assertEqual(json.load(f), {'epoch': 'feed'})
        self.assertFalse(os.path.exists(os.path.join(docs, 'figures', 'n14000_s2_feed')))
        with self.assertRaises(ValueError):
            publish_finished(out, 'n14000_s2', ['feed'], os.path.join(self.tmp, 'nodocs'))

    def test_command_lines_refuse_a_wrong_docs_tree(self):
        """The three commands exit 2 on a wrong --docs before any analysis (no output directory made)."""
        out = os.path.join(self.tmp, 'out')
        wrong = os.path.join(self.tmp, 'nodocs')
        os.makedirs(os.path.join(self.tmp, 'run'))
        with open(os.path.join(self.tmp, 'run', 'run.json'), 'w') as f:
            f.write('{}')
        for argv in ([os.path.join(SCRIPTS, 'pile_growth.py'), os.path.join(self.tmp, 'run'), '--out', out,
                      '--docs', wrong],
                     [os.path.join(SCRIPTS, 'pile_ensemble.py'), 'analyse', self.tmp, '--figures', out,
                      '--docs', wrong],
                     [os.path.join(SCRIPTS, 'pile_finish.py'), os.path.join(self.tmp, 'run'), '--out', out,
                      '--docs', wrong]):
            r = subprocess.run([sys.executable] + argv, capture_output=True, text=True, timeout=120)
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertIn('nodocs is not a docs directory', r.stderr)
            self.assertFalse(os.path.exists(out))


if __name__ == '__main__':
    unittest.main()

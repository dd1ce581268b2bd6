"""One definition of every solver option: the engine's attributes.

- ``schedule`` names the sweep order; ``sweepOrder``, its deprecated integer code, still works in
  scripts and in saved scenes, and the two stay in step whichever is set (and through O.save /
  O.load, which keep only the code);
- :func:`yadecd.solver_options` reads the defaults from the class, and every settable attribute
  the class declares is either a solver option or named here as something else;
- the pile protocol states only its departures from the engine, maps renamed keys of old
  ``run.json`` files (``sweep_order`` 1/4/5 -> ``schedule``), and its parameter check names the
  culprit, the solver's ranges checked by the engine itself.
"""
import json
import os
import re
import tempfile
import unittest

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd.pile import protocol

try:
    from yade import O
    from yade.wrapper import ContactDynamicsIntegrator, NewtonIntegrator
    import yadecd
    from yadecd import pile, scenes
    HAVE_YADE = True
except ImportError:
    HAVE_YADE = False

CODES = {1: 'height', 4: 'colours', 5: 'slabs'}


class TestRenamedPileKeys(unittest.TestCase):
    """yadecd.pile.protocol.upgrade on constructed parameter dicts (pure Python)."""

    def test_sweep_order_maps_to_schedule(self):
        for code, name in CODES.items():
            self.assertEqual(protocol.upgrade({'sweep_order': code, 'seed': 3}), {'schedule': name, 'seed': 3})
        self.assertEqual(protocol.upgrade({'schedule': 'height'}), {'schedule': 'height'})
        self.assertEqual(protocol.upgrade({'sweep_order': 5, 'schedule': 'slabs'}), {'schedule': 'slabs'})

    def test_retired_and_contradictory_values_name_the_key(self):
        for bad in (0, 2, 3, 7):
            with self.assertRaisesRegex(ValueError, 'sweep_order=%d' % bad):
                protocol.upgrade({'sweep_order': bad})
        with self.assertRaisesRegex(ValueError, 'sweep_order=1 and schedule=.slabs. disagree'):
            protocol.upgrade({'sweep_order': 1, 'schedule': 'slabs'})

    def test_old_run_json_reads_with_current_names(self):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, 'run.json')
            with open(path, 'w') as f:
                json.dump({'n_grains': 100, 'sweep_order': 4, 'tolerance': 1e-3}, f)
            self.assertEqual(protocol.read_run_json(path), {'n_grains': 100, 'schedule': 'colours', 'tolerance': 1e-3})
        with open(os.path.join(DATA, 'checkpoint_release_6e7a405', 'run.json')) as f:
            old = json.load(f)
        new = protocol.read_run_json(os.path.join(DATA, 'checkpoint_release_6e7a405', 'run.json'))
        self.assertNotIn('sweep_order', new)
        if 'sweep_order' in old:
            self.assertEqual(new['schedule'], CODES[old['sweep_order']])

    def test_defaults_hold_only_the_departures(self):
        # the protocol's own parameters and where it departs from the engine; no other solver option
        solver_keys = set(protocol.SOLVER_OPTIONS)
        self.assertEqual(set(protocol.DEFAULTS) & solver_keys, set(protocol.SOLVER_DEPARTURES))
        self.assertEqual(set(protocol.DEFAULTS), set(protocol.PROTOCOL) | set(protocol.SOLVER_DEPARTURES))


@unittest.skipUnless(HAVE_YADE, 'needs YADE')
class TestSchedule(unittest.TestCase):

    def test_names_and_codes_stay_in_step(self):
        cd = ContactDynamicsIntegrator()
        self.assertEqual((cd.schedule, cd.sweepOrder), ('height', 1))
        for code, name in CODES.items():
            cd.schedule = name
            self.assertEqual(cd.sweepOrder, code)
            c2 = ContactDynamicsIntegrator(schedule=name)
            self.assertEqual((c2.schedule, c2.sweepOrder), (name, code))
        for code, name in CODES.items():
            cd.sweepOrder = code                  # a script of an earlier release
            self.assertEqual(cd.schedule, name)
            self.assertEqual(ContactDynamicsIntegrator(sweepOrder=code).schedule, name)

    def test_bad_names_and_codes_are_refused_by_name(self):
        for bad in ('Height', 'colors', '', 'slab'):
            with self.assertRaisesRegex(ValueError, "schedule='%s'.*'height', 'colours' or 'slabs'" % bad):
                ContactDynamicsIntegrator(schedule=bad)
        for bad in (0, 2, 3):
            with self.assertRaisesRegex(ValueError, 'sweepOrder=%d: a retired order' % bad):
                ContactDynamicsIntegrator(sweepOrder=bad)
        with self.assertRaisesRegex(ValueError, 'sweepOrder=6'):
            ContactDynamicsIntegrator(sweepOrder=6)
        with self.assertRaisesRegex(ValueError, 'disagree'):
            ContactDynamicsIntegrator(schedule='slabs', sweepOrder=4)

    def test_saved_scene_keeps_its_schedule(self):
        # O.save keeps the code only (schedule is not saved): the name comes back from it
        with tempfile.TemporaryDirectory() as d:
            for name in CODES.values():
                scenes.column(3, schedule=name)
                path = os.path.join(d, 'scene_%s.yade.gz' % name)
                O.save(path)
                scenes.column(3)                  # another scene in between, default schedule
                O.load(path)
                self.assertEqual(yadecd.integrator().schedule, name)

    def test_unsaved_options_are_those_the_archive_drops(self):
        # a resume from a checkpoint's archive sets protocol.UNSAVED_OPTIONS again from run.json:
        # they must be exactly the pile's solver options that O.save / O.load do not keep
        changed = dict(tolerance=2e-4, max_iter=1234, relaxation=0.9, momentum=False, correction_momentum=True,
                       schedule='colours', slabs=3, slabs_across=2, slabs_own_bodies=True,
                       parallel_min_contacts=7)
        self.assertEqual(set(changed), set(protocol.SOLVER_OPTIONS), 'a new pile solver option: give it a changed value here')
        with tempfile.TemporaryDirectory() as d:
            scenes.column(3, **protocol.engine_options(changed))
            path = os.path.join(d, 'scene.yade.gz')
            O.save(path)
            scenes.column(3)
            O.load(path)
            cd = yadecd.integrator()
            dropped = {key for key, attr in protocol.SOLVER_OPTIONS.items() if getattr(cd, attr) != changed[key]}
        self.assertEqual(dropped, set(protocol.UNSAVED_OPTIONS))

    def test_old_checkpoint_archive_loads_with_a_named_schedule(self):
        # tests/data's first-release checkpoint holds YADE's archive of a pile run (sweepOrder 5
        # in its run.json): the engine it loads has the matching schedule name
        base = os.path.join(DATA, 'checkpoint_release_6e7a405')
        scene = [os.path.join(r, f) for r, _, fs in os.walk(base) for f in fs if f.endswith('.yade.gz')]
        self.assertTrue(scene, 'no archive in %s' % base)
        O.load(scene[0])           # the class layout is unchanged: the archive must load (it resumes bit for bit)
        cd = yadecd.integrator()
        self.assertEqual(cd.schedule, CODES[cd.sweepOrder])
        old = protocol.read_run_json(os.path.join(base, 'run.json'))
        self.assertEqual(cd.schedule, old.get('schedule', 'height'))


@unittest.skipUnless(HAVE_YADE, 'needs YADE')
class TestOneDefinition(unittest.TestCase):

    #: settable attributes the class declares that are not solver options, and why
    NOT_OPTIONS = {'problemFile': 'an action (write the next step), cleared after use',
                   'nUnconverged': 'a counter the user may reset',
                   'sweepOrder': "the deprecated code of 'schedule'"}

    @staticmethod
    def documented_defaults():
        """``{name: default}`` of the option table of docs/method.md (its second column), the
        defaults as the documentation states them."""
        def value(text):
            text = text.strip().strip('`')
            if text in ('True', 'False'):
                return text == 'True'
            if text.startswith("'"):
                return text.strip("'")
            try:
                return int(text)
            except ValueError:
                return float(text)
        out, inside = {}, False
        with open(os.path.join(REPO, 'docs', 'method.md')) as f:
            for line in f:
                if line.startswith('| attribute | default |'):
                    inside = True
                elif inside and not line.startswith('|'):
                    break
                m = re.match(r'\|\s*`(\w+)`\s*\|\s*([^|]+?)\s*\|', line) if inside else None
                if m and m.group(1) in yadecd.SOLVER_OPTIONS:
                    out[m.group(1)] = value(m.group(2))
        return out

    def test_solver_options_are_the_documented_defaults(self):
        """yadecd.solver_options() lists every solver option, in SOLVER_OPTIONS' order, with the
        default docs/method.md's option table states for it (the table and the class are written
        separately: a default changed in one and not the other fails here)."""
        opts = yadecd.solver_options()
        self.assertEqual(tuple(opts), yadecd.SOLVER_OPTIONS)
        documented = self.documented_defaults()
        self.assertEqual(sorted(documented), sorted(yadecd.SOLVER_OPTIONS))
        for name, value in opts.items():
            self.assertEqual(value, documented[name], name)
            self.assertEqual(type(value) is bool, type(documented[name]) is bool, name)

    #: solver options that are the engine's alone (contact detection and logging, not the solve)
    ENGINE_ONLY = {'alertRatio', 'alertSpeedFactor', 'warnUnconverged'}

    @staticmethod
    def core_params_defaults():
        """``{name: default}`` of the fields of ``struct Params`` in pkg/cd/core/Problem.hpp that
        are initialised with a number or a bool (the core tests and ``cd_core_bench`` solve with
        these when a problem file does not set them)."""
        with open(os.path.join(REPO, 'pkg', 'cd', 'core', 'Problem.hpp')) as f:
            text = f.read()
        m = re.search(r'struct Params \{(.*?)\n\t\};', text, re.S)
        assert m, 'struct Params not found in pkg/cd/core/Problem.hpp'
        out = {}
        for name, literal in re.findall(r'^\s*(?:Real|int|long|bool)\s+(\w+)\s*=\s*([^;]+);', m.group(1), re.M):
            literal = literal.strip()
            out[name] = literal == 'true' if literal in ('true', 'false') else (
                float(literal) if re.search(r'[.eE]', literal) else int(literal))
        return out

    def test_core_params_defaults_are_the_engine_s(self):
        """The solver core's own defaults (cd::Params, used by the core tests and the core
        benchmark) are the engine's attribute defaults: the two are written separately, and a
        default changed in one would make the benchmark solve another problem than a script."""
        core = self.core_params_defaults()
        self.assertGreater(len(core), 15)     # the parse found the struct's fields
        engine = yadecd.solver_options()
        codes = {name: code for code, name in CODES.items()}   # Params::schedule is sweepOrder's code
        for name, value in engine.items():
            if name in self.ENGINE_ONLY:
                self.assertNotIn(name, core)
                continue
            self.assertIn(name, core, 'cd::Params has no default for the engine option %s' % name)
            expected = codes[value] if name == 'schedule' else value
            self.assertEqual(core[name], expected, name)
            self.assertEqual(type(core[name]) is bool, type(expected) is bool, name)

    def test_every_settable_attribute_is_accounted_for(self):
        inherited = set(NewtonIntegrator().dict())
        declared = set(ContactDynamicsIntegrator().dict()) - inherited
        settable = set()
        cd = ContactDynamicsIntegrator()
        for name in declared:
            try:
                setattr(cd, name, getattr(cd, name))
            except AttributeError:
                continue                          # read-only results
            settable.add(name)
        self.assertEqual(settable - set(yadecd.SOLVER_OPTIONS) - set(self.NOT_OPTIONS), set())
        self.assertEqual(set(yadecd.SOLVER_OPTIONS) - declared, set())

    def test_pile_defaults_are_the_engine_s_but_for_the_departures(self):
        p = pile.defaults()
        engine = yadecd.solver_options()
        for key, attr in protocol.SOLVER_OPTIONS.items():
            expected = protocol.SOLVER_DEPARTURES.get(key, engine[attr])
            self.assertEqual(p[key], expected, key)
        self.assertEqual(protocol.engine_options({'max_iter': 7, 'schedule': 'slabs', 'seed': 1}),
                         {'maxIter': 7, 'schedule': 'slabs'})

    def test_pile_check_names_the_culprit(self):
        base = pile.defaults()
        for key, value, words in (('schedule', 'diagonal', "schedule='diagonal'"), ('max_iter', 0, 'maxIter'),
                                  ('relaxation', 2.5, 'relaxation'), ('parallel_min_contacts', -1, 'parallelMinContacts'),
                                  ('tolerance', -1e-3, 'tolerance'), ('momentum', 1, 'momentum must be a bool')):
            with self.assertRaises(ValueError) as cm:
                protocol.check_params(dict(base, **{key: value}))
            self.assertIn(key, str(cm.exception))
            self.assertIn(words, str(cm.exception))
        protocol.check_params(base)


if __name__ == '__main__':
    unittest.main()

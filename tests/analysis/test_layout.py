"""The package's layout rules, checked on the source:

- what must import without YADE does (``yadecd.analysis`` entire, ``yadecd.pile.protocol``,
  ``yadecd.io``, the run-management modules but ``runs.runstate``, the pure testing helpers, the
  list of YADE examples run under CD), in a
  fresh interpreter where ``import yade`` fails;
- no module uses another module's private name (``mod._name`` or ``from mod import _name``
  across modules of yadecd, its scripts or its tests);
- no module of the package is over 700 lines.
"""
import ast
import glob
import os
import subprocess
import unittest

from repo_package import PY, REPO  # noqa: F401  (first: this checkout's yadecd)

PACKAGE = os.path.join(PY, 'yadecd')

#: modules that must import without YADE (dotted, below yadecd)
WITHOUT_YADE = ['analysis', 'analysis.snapshots', 'analysis.surface', 'analysis.stats', 'analysis.forces',
                'analysis.ground', 'analysis.fabric', 'analysis.figures', 'analysis.report', 'analysis.ensemble',
                'analysis.protocols', 'analysis.rheology', 'analysis.trends', 'analysis.growth', 'analysis.shapes', 'analysis.ensemble_report', 'analysis.finish', 'pile.protocol', 'io', 'runs', 'runs.checkpoint', 'runs.carry', 'runs.cost',
                'runs.ensemble', 'testing', 'testing.synthetic', 'testing.faults', 'testing.variant', 'export',
                'compare', 'compare.examples']

PROBE = r'''
import importlib, sys
sys.path.insert(0, PY_DIR)
class NoYade:
    def find_spec(self, name, path=None, target=None):
        if name == 'yade' or name.startswith('yade.'):
            raise ImportError('YADE is not available in this test (it must not be needed)')
sys.meta_path.insert(0, NoYade())
failed = []
for name in MODULES:
    try:
        importlib.import_module('yadecd.' + name)
    except Exception as e:
        failed.append('{}: {}: {}'.format(name, type(e).__name__, e))
print('\n'.join(failed) or 'ALL IMPORTED')
'''


def probe(modules):
    """The probe's source for these modules."""
    return PROBE.replace('PY_DIR', repr(PY)).replace('MODULES', repr(modules))


def package_modules():
    """(dotted name, path) of every module of yadecd."""
    out = []
    for path in sorted(glob.glob(os.path.join(PACKAGE, '**', '*.py'), recursive=True)):
        rel = os.path.relpath(path, PY)[:-3].replace(os.sep, '.')
        out.append((rel[:-9] if rel.endswith('.__init__') else rel, path))
    return out


def private_uses(source, module_names):
    """``(line, text)`` of the uses of a private name of another module in ``source``: an
    attribute ``alias._x`` where ``alias`` is bound by an import of one of ``module_names``, or
    ``from M import _x`` with M one of them. Dunder names are not private."""
    tree = ast.parse(source)
    aliases, found = set(), []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name in module_names:
                    aliases.add(a.asname or a.name)
        elif isinstance(node, ast.ImportFrom):
            base = ('.' * node.level) + (node.module or '')
            for a in node.names:
                full = (node.module + '.' + a.name) if node.module else a.name
                if full in module_names or node.level and a.name in {m.rsplit('.', 1)[-1] for m in module_names}:
                    aliases.add(a.asname or a.name)
                elif (base in module_names or node.level) and a.name.startswith('_') and not a.name.startswith('__'):
                    found.append((node.lineno, 'from %s import %s' % (base, a.name)))
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases \
                and node.attr.startswith('_') and not node.attr.startswith('__'):
            found.append((node.lineno, '%s.%s' % (node.value.id, node.attr)))
    return found


class TestWithoutYade(unittest.TestCase):

    def test_imports_without_yade(self):
        proc = subprocess.run(['/usr/bin/python3', '-c', probe(WITHOUT_YADE)], capture_output=True, text=True,
                              timeout=300, cwd=REPO)
        self.assertEqual(proc.stdout.strip(), 'ALL IMPORTED', proc.stdout + proc.stderr)

    def test_probe_catches_a_yade_import(self):
        # the probe itself must fail on a module that imports YADE
        proc = subprocess.run(['/usr/bin/python3', '-c', probe(['pile.build'])], capture_output=True,
                              text=True, timeout=300, cwd=REPO)
        self.assertIn('pile.build: ImportError', proc.stdout)


class TestPrivateNames(unittest.TestCase):

    def test_checker_on_constructed_source(self):
        mods = {'yadecd.analysis.figures', 'yadecd.analysis'}
        src = ('from yadecd.analysis import figures as pf\nimport yadecd.analysis as pa\n'
               'pf._figure(1)\npa.flank_slope(s)\npa.__doc__\nfrom yadecd.analysis.figures import _save\n')
        self.assertEqual(sorted(t for _, t in private_uses(src, mods)),
                         ['from yadecd.analysis.figures import _save', 'pf._figure'])

    def test_no_private_name_crosses_a_module(self):
        names = {'yadecd.' + m if m else 'yadecd' for m, _ in package_modules()}
        names = {n.replace('yadecd.yadecd', 'yadecd') for n in names}
        files = [p for _, p in package_modules()] + glob.glob(os.path.join(REPO, 'scripts', '**', '*.py'), recursive=True) \
            + glob.glob(os.path.join(REPO, 'tests', '**', '*.py'), recursive=True)
        bad = []
        for path in files:
            if os.path.abspath(path) == os.path.abspath(__file__):
                continue
            with open(path) as f:
                for line, text in private_uses(f.read(), names):
                    bad.append('%s:%d: %s' % (os.path.relpath(path, REPO), line, text))
        self.assertEqual(bad, [])


class TestSizes(unittest.TestCase):

    def test_no_module_over_700_lines(self):
        long = []
        for name, path in package_modules():
            with open(path) as f:
                n = sum(1 for _ in f)
            if n > 700:
                long.append('%s: %d lines' % (name, n))
        self.assertEqual(long, [])


if __name__ == '__main__':
    unittest.main()

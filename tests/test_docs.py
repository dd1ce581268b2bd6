"""The documentation cites what exists: checked on the text of README.md, runs/README.md and
docs/*.md (not docs/data/), against the checkout's files, without YADE and without importing
any module of the package.

(a) every repository path cited (``py/``, ``scripts/``, ``tests/``, ``pkg/``, ``docs/``, ``runs/``...)
    exists, and every relative Markdown link leads to a file and, with ``#anchor``, to a heading;
(b) every dotted name ``yadecd.a.b...`` (and every ``from yadecd... import x``) resolves: modules
    and packages under py/yadecd, a final attribute defined in its module (read with ``ast``:
    definitions, imports re-exported by ``__init__``, ``from .x import *``, the lazy table
    ``_WHERE`` of yadecd.pile);
(c) every attribute of a plugin class cited (``ContactDynamicsIntegrator.name``,
    ``:yref:`…<ContactDynamicsIntegrator.name>```, ``name=value`` inside ``engines(...)`` and
    ``ContactDynamicsIntegrator(...)``, the rows of method.md's option table, ``CDPhys.name``...)
    is declared in the class's YADE_CLASS_BASE_DOC_* macro in pkg/cd, or is one of the
    attributes of its YADE base listed in :data:`YADE_BASE_ATTRIBUTES`;
(d) every C++ ``Type::member`` (and ``cd::name``) cited names a type of pkg/cd with that member
    in its definition (comments and string literals ignored), or a YADE type of
    :data:`YADE_TYPES` with a member listed there;
(e) no retired module name of the flat layout (``pile_analysis``, ``benchio``...) is cited;
(f) every test cited by name (``TestClass``, ``TestClass.test_x``, ``test_x``,
    ``tests/a/test_b.py::TestClass``) is defined in tests/;
(g) an attribute whose docstring begins "Deprecated" (``sweepOrder``) is cited only in a
    paragraph, list item or table row that says it is deprecated (or retired);
(h) every ``--option`` given to a script (``scripts/x.py``, ``x.py``, ``cd_core_bench``) on a
    command line or in inline code is one the script knows;
(i) the number of test methods docs/results.md states is the number in tests/;
(j) docs/data/README.md lists every record of docs/data/, and what it cites exists.

Where a check fails on the documentation, the documentation is what is wrong. The checker
functions are tested on constructed strings first (:class:`CheckerTest`)."""
from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)

import ast
import functools
import glob
import os
import re
import unittest

PY = os.path.join(REPO, 'py')
PKG_CD = os.path.join(REPO, 'pkg', 'cd')

#: the documentation checked (docs/data/ holds records, not prose)
DOCS = ['README.md', os.path.join('runs', 'README.md')] + sorted(
    os.path.relpath(p, REPO) for p in glob.glob(os.path.join(REPO, 'docs', '*.md')))

#: attributes of the plugin classes' YADE bases that the docs may cite (YADE's source is not in
#: the checkout, so they are listed here, each on purpose)
YADE_BASE_ATTRIBUTES = {
    'NewtonIntegrator': {'gravity', 'damping', 'maxVelocitySq', 'mask', 'exactAsphericalRot', 'kinSplit',
                         'dampGravity', 'label', 'dead'},
    'FrictPhys': {'tangensOfFrictionAngle', 'normalForce', 'shearForce', 'kn', 'ks'},
}

#: YADE's own C++ types that the docs cite with a member (``Type::member``), and those members
YADE_TYPES = {
    'State': {'pos', 'ori', 'vel', 'angVel', 'blockedDOFs'},
    'ScGeom': {'penetrationDepth', 'normal', 'contactPoint'},
    'NewtonIntegrator': YADE_BASE_ATTRIBUTES['NewtonIntegrator'],
    'FrictPhys': YADE_BASE_ATTRIBUTES['FrictPhys'],
    'Clump': {'moveMembers', 'addForceTorqueFromMembers', 'members'},   # YADE's core/Clump.hpp
}

#: module names of the flat layout, retired by the package's reorganisation (their new places:
#: yadecd.analysis, yadecd.analysis.figures/report, yadecd.analysis.ensemble, yadecd.io,
#: yadecd.runs.cost, yadecd.compare.sweep)
RETIRED_MODULES = ('pile_analysis', 'pile_figures', 'pile_ensemble_analysis', 'benchio', 'runcost',
                   'compare_sweep')

PATH_PREFIXES = ('py', 'scripts', 'tests', 'pkg', 'docs', 'runs')


def doc_texts():
    """``(relative path, text)`` of every checked document."""
    out = []
    for rel in DOCS:
        with open(os.path.join(REPO, rel), encoding='utf-8') as f:
            out.append((rel, f.read()))
    return out


def line_of(text, pos):
    return text.count('\n', 0, pos) + 1


# ---------------------------------------------------------------------------------------------
# (a) paths and links

PATH_RE = re.compile(r'(?<![\w./~$-])((?:%s)/[^\s`\'"()\[\],;|#]*)' % '|'.join(PATH_PREFIXES))


def cited_paths(text):
    """``(line, path)`` of the repository paths cited in a text (placeholders excluded)."""
    out = []
    for m in PATH_RE.finditer(text):
        path = m.group(1).split('::')[0].rstrip('.:!?')  # tests/x.py::TestY: the names are checked by (f)
        if any(c in path for c in '<>*{}$'):
            continue
        out.append((line_of(text, m.start()), path))
    return out


def missing_paths(text, root=REPO):
    """The cited paths that do not exist under ``root``: ``(line, path)``."""
    return [(ln, p) for ln, p in cited_paths(text) if not os.path.exists(os.path.join(root, p))]


LINK_RE = re.compile(r'\]\(([^)\s]+)\)')


def slug(heading):
    """GitHub's anchor of a heading: lower case, punctuation dropped (letters, digits, spaces,
    hyphens and underscores kept), spaces to hyphens."""
    text = re.sub(r'[`*]', '', heading.strip().lower())
    text = ''.join(c for c in text if c.isalnum() or c in ' -_')
    return text.replace(' ', '-')


def anchors(text):
    """The anchors of a Markdown text's headings (outside code blocks), with GitHub's -1, -2... for
    repeated ones."""
    seen, out, fenced = {}, set(), False
    for line in text.splitlines():
        if line.startswith('```'):
            fenced = not fenced
            continue
        m = None if fenced else re.match(r'#{1,6}\s+(.*)', line)
        if m:
            s = slug(m.group(1))
            out.add(s if s not in seen else '%s-%d' % (s, seen[s]))
            seen[s] = seen.get(s, 0) + 1
    return out


def broken_links(text, doc_dir):
    """Relative Markdown links of a text (in directory ``doc_dir``) that lead nowhere:
    ``(line, link, why)``."""
    out = []
    for m in LINK_RE.finditer(text):
        link = m.group(1)
        if re.match(r'[a-z]+:', link):
            continue  # http:, https:, mailto:
        target, _, anchor = link.partition('#')
        path = os.path.normpath(os.path.join(doc_dir, target)) if target else None
        if path and not os.path.exists(path):
            out.append((line_of(text, m.start()), link, 'no such file'))
            continue
        if anchor:
            if path:
                if not path.endswith('.md'):
                    continue
                with open(path, encoding='utf-8') as f:
                    heads = anchors(f.read())
            else:
                heads = anchors(text)
            if anchor not in heads:
                out.append((line_of(text, m.start()), link, 'no heading with this anchor'))
    return out


# ---------------------------------------------------------------------------------------------
# (b) dotted names of the package

DOTTED_RE = re.compile(r'(?<![\w/.])yadecd(?:\.[A-Za-z_]\w*)+')
FROM_RE = re.compile(r'\bfrom\s+(yadecd(?:\.\w+)*)\s+import\s+(\([^)]*\)|[\w ,]+)')


def module_file(dotted, root=PY):
    """The file of a module or package (``yadecd.analysis`` → .../__init__.py), or None."""
    base = os.path.join(root, *dotted.split('.'))
    for candidate in (os.path.join(base, '__init__.py'), base + '.py'):
        if os.path.isfile(candidate):
            return candidate
    return None


def _absolute(module, level, package):
    """The absolute name of a relative import in ``package``."""
    if not level:
        return module
    parts = package.split('.')
    base = parts[:len(parts) - (level - 1)]
    return '.'.join(base + ([module] if module else []))


@functools.lru_cache(maxsize=None)
def definitions(dotted, root=PY):
    """What a module defines at its top level: ``{name: how}`` with how ``('local', node)``,
    ``('from', module, name)`` or ``('module', module)``; plus ``'*'``: the modules it imports with
    ``from m import *``."""
    path = module_file(dotted, root)
    with open(path, encoding='utf-8') as f:
        tree = ast.parse(f.read(), path)
    package = dotted if path.endswith('__init__.py') else dotted.rpartition('.')[0]
    out, stars = {}, []

    def names_of(target):
        if isinstance(target, ast.Name):
            yield target.id
        elif isinstance(target, (ast.Tuple, ast.List)):
            for t in target.elts:
                yield from names_of(t)

    def visit(body):
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                out[node.name] = ('local', node)
            elif isinstance(node, ast.Assign):
                for t in node.targets:
                    for n in names_of(t):
                        out[n] = ('local', node)
                if any(isinstance(t, ast.Name) and t.id == '_WHERE' for t in node.targets) \
                        and isinstance(node.value, ast.Dict):
                    for k, v in zip(node.value.keys, node.value.values):
                        for e in getattr(v, 'elts', []):
                            if isinstance(k, ast.Constant) and isinstance(e, ast.Constant):
                                out.setdefault(e.value, ('from', package + '.' + k.value, e.value))
            elif isinstance(node, ast.AnnAssign):
                for n in names_of(node.target):
                    out[n] = ('local', node)
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.asname:
                        out[a.asname] = ('module', a.name)
                    else:
                        out[a.name.split('.')[0]] = ('module', a.name.split('.')[0])
            elif isinstance(node, ast.ImportFrom):
                source = _absolute(node.module, node.level, package)
                for a in node.names:
                    if a.name == '*':
                        stars.append(source)
                    else:
                        out[a.asname or a.name] = ('from', source, a.name)
            elif isinstance(node, (ast.If, ast.Try, ast.With)):
                visit(node.body)
                for h in getattr(node, 'handlers', []):
                    visit(h.body)
                visit(getattr(node, 'orelse', []))
                visit(getattr(node, 'finalbody', []))

    visit(tree.body)
    out['*'] = tuple(stars)
    return out


def class_members(node):
    """Names a class defines: methods, class attributes, ``self.x = ...`` in its methods."""
    out = set()
    for n in node.body:
        if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(n.name)
        elif isinstance(n, ast.Assign):
            out.update(t.id for t in n.targets if isinstance(t, ast.Name))
        elif isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name):
            out.add(n.target.id)
    for n in ast.walk(node):
        if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name) and n.value.id == 'self' \
                and isinstance(n.ctx, ast.Store):
            out.add(n.attr)
    return out


def _resolve_attr(module, rest, root, depth=0):
    """None when ``module.rest[0].rest[1]...`` is defined, else why not."""
    if not rest:
        return None
    if not module.startswith('yadecd') or depth > 10:
        return None  # outside the package (numpy...): not checked
    if module_file(module + '.' + rest[0], root):
        return _resolve_attr(module + '.' + rest[0], rest[1:], root, depth + 1)
    defs = definitions(module, root)
    how = defs.get(rest[0])
    if how is None:
        for star in defs['*']:
            if _resolve_attr(star, rest[:1], root, depth + 1) is None:
                return _resolve_attr(star, rest, root, depth + 1)
        return '%s defines no %r' % (module, rest[0])
    if how[0] == 'module':
        return _resolve_attr(how[1], rest[1:], root, depth + 1)
    if how[0] == 'from':
        return _resolve_attr(how[1], [how[2]] + rest[1:], root, depth + 1)
    node = how[1]
    if len(rest) > 1 and isinstance(node, ast.ClassDef):
        local_bases = [b.id for b in node.bases if isinstance(b, ast.Name)]
        if len(local_bases) == len(node.bases) and rest[1] not in class_members(node):
            for b in local_bases:  # a base class of the same module (or imported into it)
                if b in defs and _resolve_attr(module, [b, rest[1]], root, depth + 1) is None:
                    return None
            if not any(b not in defs for b in local_bases):
                return '%s.%s has no member %r' % (module, rest[0], rest[1])
    return None


def resolve(dotted, root=PY):
    """None when a dotted name of the package (``yadecd.a.b``) exists, else why not."""
    parts = dotted.split('.')
    if parts[0] != 'yadecd' or module_file('yadecd', root) is None:
        return 'not a name of the yadecd package'
    return _resolve_attr('yadecd', parts[1:], root)


def cited_dotted(text):
    """``(line, dotted name)`` of the package's names cited in a text: dotted names, and the
    names of ``from yadecd... import a, b``."""
    out = [(line_of(text, m.start()), m.group(0)) for m in DOTTED_RE.finditer(text)]
    for m in FROM_RE.finditer(text):
        for name in re.split(r'[\s,()]+', m.group(2)):
            name = name.strip()
            if name and name != 'as' and re.match(r'[A-Za-z_]\w*$', name):
                out.append((line_of(text, m.start()), m.group(1) + '.' + name))
                if ' as ' in m.group(2):
                    break  # `import x as y`: y is no name of the package
    return out


def unresolved_names(text, root=PY):
    """``(line, name, why)`` of the cited dotted names that do not resolve."""
    out = []
    for ln, name in cited_dotted(text):
        why = resolve(name, root)
        if why:
            out.append((ln, name, why))
    return out


def retired_modules(text):
    """``(line, name)`` of citations of the flat layout's retired modules (script names such as
    ``pile_figures.py`` excepted)."""
    pat = re.compile(r'(?<![\w/])(%s)(?!\.py)\b' % '|'.join(RETIRED_MODULES))
    return [(line_of(text, m.start()), m.group(1)) for m in pat.finditer(text)]


# ---------------------------------------------------------------------------------------------
# (c) attributes of the plugin's classes, (d) C++ members

def _strip_cpp(source, keep_strings=False):
    """C++ source without comments (and string literals unless ``keep_strings``)."""
    out, i, n = [], 0, len(source)
    while i < n:
        c = source[i]
        if source.startswith('//', i):
            j = source.find('\n', i)
            i = n if j < 0 else j
        elif source.startswith('/*', i):
            j = source.find('*/', i + 2)
            i = n if j < 0 else j + 2
        elif c == '"' or c == "'":
            j = i + 1
            while j < n and source[j] != c:
                j += 2 if source[j] == '\\' else 1
            out.append(source[i:j + 1] if keep_strings else c + c)
            i = j + 1
        else:
            out.append(c)
            i += 1
    return ''.join(out)


def cpp_sources(root=PKG_CD):
    out = {}
    for path in sorted(glob.glob(os.path.join(root, '**', '*.[hc]pp'), recursive=True)):
        with open(path, encoding='utf-8') as f:
            out[path] = f.read()
    return out


@functools.lru_cache(maxsize=None)
def yade_classes(root=PKG_CD):
    """``{class: (base, attributes)}`` of the classes declared with a YADE_CLASS_BASE_DOC_* macro
    in pkg/cd: the ``((type, name, default, flags, "doc"))`` tuples and the ``.def("name"`` methods."""
    out = {}
    for path, source in cpp_sources(root).items():
        code = _strip_cpp(source, keep_strings=True)
        starts = [m for m in re.finditer(r'YADE_CLASS_BASE_DOC\w*\(\s*(\w+)\s*,\s*(\w+)', code)]
        for i, m in enumerate(starts):
            end = starts[i + 1].start() if i + 1 < len(starts) else len(code)
            raw = code[m.end():end]
            stop = re.search(r'REGISTER_SERIALIZABLE', raw)
            raw = raw[:stop.start()] if stop else raw
            chunk = re.sub(r'"(?:[^"\\]|\\.)*"', '""', raw)  # docstrings may quote ((...)) too
            tuple_name = r'\(\(\s*[\w:<>, ]+?\s*,\s*(\w+)\s*,'
            attrs = set(re.findall(tuple_name, chunk))
            for define in re.finditer(r'#define\s+(\w+)\s+(.*)', code):  # attributes added through a macro
                if re.search(r'\b%s\b' % define.group(1), chunk):
                    attrs.update(re.findall(tuple_name, define.group(2)))
            attrs.update(re.findall(r'\.def\(\s*"(\w+)"', raw))  # methods exposed to Python
            out[m.group(1)] = (m.group(2), attrs)
    return out


def class_attribute_missing(cls, name, root=PKG_CD):
    """None when ``cls.name`` is an attribute of a plugin class (or of its listed YADE base),
    else why not."""
    classes = yade_classes(root)
    seen = cls
    while cls in classes:
        base, attrs = classes[cls]
        if name in attrs:
            return None
        cls = base
    if name in YADE_BASE_ATTRIBUTES.get(cls, ()):
        return None
    return '%s declares no attribute %r (nor does its base %s in YADE_BASE_ATTRIBUTES)' % (seen, name, cls)


def _call_keywords(text, start):
    """The keyword names at the top level of the call whose '(' is at ``start``."""
    depth, i, names, quote = 0, start, [], None
    token = re.compile(r'([A-Za-z_]\w*)\s*=(?!=)')
    while i < len(text):
        c = text[i]
        if quote:
            if c == '\\':
                i += 1
            elif c == quote:
                quote = None
        elif c in '\'"':
            quote = c
        elif c in '([{':
            depth += 1
        elif c in ')]}':
            depth -= 1
            if depth == 0:
                break
        elif depth == 1:
            m = token.match(text, i)
            if m and (i == start + 1 or not (text[i - 1].isalnum() or text[i - 1] == '_')):
                names.append(m.group(1))
                i = m.end()
                continue
        i += 1
    return names


@functools.lru_cache(maxsize=None)
def engines_parameters(root=PY):
    """The parameters of yadecd.engines() (read from its signature)."""
    how = definitions('yadecd', root).get('engines')
    args = how[1].args
    return {a.arg for a in args.args + args.kwonlyargs}


def cited_attributes(text, root=PKG_CD):
    """``(line, class, attribute)`` of the plugin classes' attributes cited in a text."""
    classes = sorted(yade_classes(root), key=len, reverse=True)
    alt = '|'.join(map(re.escape, classes))
    out = []
    for m in re.finditer(r'(?<![\w:])(%s)\.([A-Za-z_]\w*)' % alt, text):  # also :yref:`text<Class.attr>`
        if m.group(2) not in ('hpp', 'cpp', 'py', 'md'):
            out.append((line_of(text, m.start()), m.group(1), m.group(2)))
    for m in re.finditer(r'(?<![\w.])(engines|ContactDynamicsIntegrator)\(', text):
        cls = 'ContactDynamicsIntegrator'
        for name in _call_keywords(text, m.end() - 1):
            if m.group(1) == 'engines' and name in engines_parameters():
                continue
            out.append((line_of(text, m.start()), cls, name))
    return out


def option_table(text):
    """``(line, name)`` of the first column of the table under a heading that says it lists the
    attributes of ``ContactDynamicsIntegrator`` (method.md's options)."""
    out, inside = [], False
    for i, line in enumerate(text.splitlines(), 1):
        if line.startswith('#'):
            inside = 'attributes of `ContactDynamicsIntegrator`' in line
            continue
        if inside:
            m = re.match(r'\|\s*`(\w+)`\s*\|', line)
            if m:
                out.append((i, m.group(1)))
    return out


def missing_attributes(text, root=PKG_CD):
    """``(line, 'Class.attr', why)`` of the cited attributes the classes do not declare."""
    cited = cited_attributes(text, root) + [(ln, 'ContactDynamicsIntegrator', n) for ln, n in option_table(text)]
    out = []
    for ln, cls, name in cited:
        why = class_attribute_missing(cls, name, root)
        if why:
            out.append((ln, '%s.%s' % (cls, name), why))
    return out


@functools.lru_cache(maxsize=None)
def cpp_types(root=PKG_CD):
    """``{type: [(base or None, body without comments and strings)]}`` of the structs, classes and
    enums defined in pkg/cd; ``'cd::'``: the core's code (for namespace-level names)."""
    out, core = {}, []
    for path, source in cpp_sources(root).items():
        code = _strip_cpp(source)
        if os.sep + 'core' + os.sep in path:
            core.append(code)
        for m in re.finditer(r'\b(?:struct|class|enum\s+class|enum)\s+(\w+)\s*(?::\s*(?:public\s+)?([\w:]+)[^{;]*)?\{',
                             code):
            depth, i = 0, m.end() - 1
            while i < len(code):
                depth += {'{': 1, '}': -1}.get(code[i], 0)
                if depth == 0:
                    break
                i += 1
            base = m.group(2).split('::')[-1] if m.group(2) else None
            out.setdefault(m.group(1), []).append((base, code[m.end():i]))
    out['cd::'] = [(None, '\n'.join(core))]
    return out


MEMBER_RE = re.compile(r'(?<![\w.])(?:cd::)?([A-Z]\w*)::(~?[A-Za-z_]\w*(?:/[A-Za-z_]\w*)*)')
NAMESPACE_RE = re.compile(r'(?<![\w:])cd::([A-Za-z_]\w*)(?!\w*::)')


def _declarations(body):
    """A type's body without what stands between parentheses (parameter lists, initialisers,
    macro arguments), so that a name left in it is one the type declares."""
    previous = None
    while previous != body:
        previous, body = body, re.sub(r'\([^()]*\)', '()', body)
    return body


def member_missing(cls, member, root=PKG_CD):
    """None when C++ ``cls::member`` exists (declared in the type's body in pkg/cd, or as an
    attribute of its YADE_CLASS macro, following bases; or listed in YADE_TYPES)."""
    types, classes = cpp_types(root), yade_classes(root)
    seen, todo = set(), [cls]
    while todo:
        t = todo.pop()
        if t in seen:
            continue
        seen.add(t)
        if member in YADE_TYPES.get(t, ()) or member in classes.get(t, (None, ()))[1]:
            return None
        for base, body in types.get(t, []):
            if re.search(r'\b%s\b' % re.escape(member), _declarations(body)):
                return None
            if base:
                todo.append(base)
    if cls not in types and cls not in YADE_TYPES:
        return 'no type %s in pkg/cd (nor in YADE_TYPES)' % cls
    return '%s has no member %r' % (cls, member)


def missing_members(text, root=PKG_CD):
    """``(line, 'Type::member', why)`` of the C++ members cited in a text that do not exist."""
    out = []
    for m in MEMBER_RE.finditer(text):
        for member in m.group(2).split('/'):
            why = member_missing(m.group(1), member, root)
            if why:
                out.append((line_of(text, m.start()), '%s::%s' % (m.group(1), member), why))
    code = cpp_types(root)['cd::'][0][1]
    for m in NAMESPACE_RE.finditer(text):
        name = m.group(1)
        if not re.search(r'\b%s\b' % re.escape(name), code):
            out.append((line_of(text, m.start()), 'cd::' + name, 'not in pkg/cd/core'))
    return out


# ---------------------------------------------------------------------------------------------
# (f) tests cited by name, (g) deprecated attributes cited as such

@functools.lru_cache(maxsize=None)
def tests_index(root=os.path.join(REPO, 'tests')):
    """What the test files define: ``{'modules': {test module names}, 'names': {class and function
    names}, 'methods': {(class, method)}, 'files': {relative path: set of names}}``."""
    out = {'modules': set(), 'names': set(), 'methods': set(), 'files': {}}
    for path in sorted(glob.glob(os.path.join(root, '**', '*.py'), recursive=True)):
        with open(path, encoding='utf-8') as f:
            tree = ast.parse(f.read(), path)
        names = set()
        for node in ast.walk(tree):
            if isinstance(node, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                names.add(node.name)
            if isinstance(node, ast.ClassDef):
                out['methods'].update((node.name, n.name) for n in node.body if isinstance(n, ast.FunctionDef))
        out['modules'].add(os.path.basename(path)[:-3])
        out['names'].update(names)
        out['files'][os.path.relpath(path, REPO)] = names
    return out


TEST_CLASS_RE = re.compile(r'(?<![\w/.:])(Test[A-Z]\w*)(?:\.(test_\w+))?')
TEST_FUNC_RE = re.compile(r'(?<![\w/.:])(test_\w+)(?![\w.])')
TEST_FILE_RE = re.compile(r'(?<![\w/.])(tests/[\w/]+\.py)((?:::\w+)+)')


def missing_tests(text, root=os.path.join(REPO, 'tests')):
    """``(line, name, why)`` of the tests cited by name (``TestClass``, ``TestClass.test_x``,
    ``test_x``, ``tests/a/test_b.py::TestClass``) that no test file defines."""
    idx, out = tests_index(root), []
    for m in TEST_CLASS_RE.finditer(text):
        cls, meth = m.group(1), m.group(2)
        if cls not in idx['names']:
            out.append((line_of(text, m.start()), cls, 'no test class of this name in tests/'))
        elif meth and (cls, meth) not in idx['methods']:
            out.append((line_of(text, m.start()), cls + '.' + meth, 'no such test method'))
    for m in TEST_FUNC_RE.finditer(text):
        name = m.group(1)
        if name not in idx['names'] and name not in idx['modules']:
            out.append((line_of(text, m.start()), name, 'no test of this name in tests/'))
    for m in TEST_FILE_RE.finditer(text):
        names = idx['files'].get(m.group(1))
        for name in m.group(2).split('::')[1:]:
            if names is not None and name not in names:
                out.append((line_of(text, m.start()), m.group(1) + '::' + name, 'not defined in that file'))
    return out


@functools.lru_cache(maxsize=None)
def deprecated_attributes(root=PKG_CD):
    """``{(class, attribute)}`` whose docstring begins with "Deprecated"."""
    out = set()
    for path, source in cpp_sources(root).items():
        code = _strip_cpp(source, keep_strings=True)
        for m in re.finditer(r'YADE_CLASS_BASE_DOC\w*\(\s*(\w+)', code):
            cls = m.group(1)
            end = code.find('REGISTER_SERIALIZABLE', m.end())
            chunk = code[m.end():end if end > 0 else len(code)]
            for t in re.finditer(r'\(\(([^"]*?)"((?:[^"\\]|\\.)*)"\s*\)\)', chunk):
                fields = [f.strip() for f in t.group(1).split(',')]
                if len(fields) >= 2 and t.group(2).startswith('Deprecated'):
                    out.add((cls, fields[1]))
    return out


def blocks(text):
    """``(first line, text)`` of a Markdown text's paragraphs, table rows and list items."""
    out, current, start = [], [], 1
    for i, line in enumerate(text.splitlines() + [''], 1):
        starts_new = not line.strip() or line.lstrip().startswith(('|', '- ', '* ')) or re.match(r'\s*\d+\. ', line)
        if starts_new and current:
            out.append((start, '\n'.join(current)))
            current = []
        if line.strip():
            if not current:
                start = i
            current.append(line)
            if line.lstrip().startswith('|'):
                out.append((start, line))
                current = []
    return out


def undeclared_deprecations(text, root=PKG_CD):
    """``(line, 'Class.attr', why)`` of the paragraphs (rows, items) citing a deprecated attribute
    without saying it is deprecated (or retired)."""
    out = []
    for cls, name in sorted(deprecated_attributes(root)):
        pat = re.compile(r'(`%s[`=]|\b%s\.%s\b)' % (re.escape(name), re.escape(cls), re.escape(name)))
        for ln, block in blocks(text):
            if pat.search(block) and not re.search(r'deprecat|retired', block, re.I):
                out.append((ln, '%s.%s' % (cls, name), 'cited without saying it is deprecated'))
    return out


# ---------------------------------------------------------------------------------------------
# (h) command-line options of the scripts

@functools.lru_cache(maxsize=None)
def pile_flags(root=PY):
    """The flags ``scripts/pile.py`` makes from the pile's parameters (``--`` + name with hyphens):
    the protocol's (``PROTOCOL``) and the solver options' (``SOLVER_OPTIONS``), read from
    yadecd/pile/protocol.py without importing it."""
    with open(module_file('yadecd.pile.protocol', root), encoding='utf-8') as f:
        tree = ast.parse(f.read())
    keys = set()
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id in ('PROTOCOL', 'SOLVER_OPTIONS')
                                                for t in node.targets):
            v = node.value
            if isinstance(v, ast.Dict):
                keys.update(k.value for k in v.keys if isinstance(k, ast.Constant))
            elif isinstance(v, ast.Call):  # dict(a=..., b=...)
                keys.update(k.arg for k in v.keywords if k.arg)
    return {'--' + k.replace('_', '-') for k in keys}


@functools.lru_cache(maxsize=None)
def script_flags(path):
    """The ``--flags`` a script or the core benchmark knows: its string literals that look like
    flags (argparse's, or C++ comparisons), plus the pile's parameter flags for scripts that build
    their options from ``pile.defaults()``."""
    with open(path, encoding='utf-8') as f:
        source = f.read()
    flags = set(re.findall(r'["\'](--[a-z][a-z0-9-]*)["\']', source))
    if 'pile.defaults()' in source:
        flags |= pile_flags()
    return flags


SCRIPT_RE = re.compile(r'(?<![\w/.-])((?:scripts/)?(?:bench/)?[A-Za-z_]\w*\.py|(?:build/)?cd_core_bench)(?![\w/])')


def script_path(name, root=REPO):
    """The file of a script cited as ``scripts/x.py``, ``x.py`` or ``cd_core_bench`` (None if none)."""
    if name.endswith('cd_core_bench'):
        return os.path.join(root, 'pkg', 'cd', 'bench', 'cd_core_bench.cpp')
    if name.startswith('scripts/'):
        path = os.path.join(root, name)
        return path if os.path.isfile(path) else None
    for d in ('scripts', os.path.join('scripts', 'bench')):
        path = os.path.join(root, d, os.path.basename(name))
        if os.path.isfile(path):
            return path
    return None


def unknown_options(text, root=REPO):
    """``(line, 'script --flag', why)`` of the options given to a script on a command line or in
    inline code that the script does not know (``--no-x`` counts as ``--x``; what follows a bare
    ``--`` is passed on to another program and not checked)."""
    out, first = [], 1
    logical = []  # (first line, text) of the lines, a backslash continuation joined to the next
    for raw in re.split(r'(?<!\\)\n', text):
        logical.append((first, raw.replace('\\\n', ' ')))
        first += raw.count('\n') + 1
    for ln, line in logical:
        hits = list(SCRIPT_RE.finditer(line))
        for i, m in enumerate(hits):
            path = script_path(m.group(1), root)
            if path is None:
                continue
            end = hits[i + 1].start() if i + 1 < len(hits) else len(line)
            segment = re.split(r'[`#|;]', line[m.end():end])[0]
            segment = re.split(r'(?<!\S)--(?!\S)', segment)[0]  # a bare -- ends the script's own options (the rest is passed on)
            known = script_flags(path)
            for flag in re.findall(r'(?<![\w-])(--[a-z][a-z0-9-]*)', segment):
                if flag not in known and '--' + flag[5:] not in known:
                    out.append((ln, '%s %s' % (m.group(1), flag), 'not an option of %s' % os.path.relpath(path, root)))
    return out


# ---------------------------------------------------------------------------------------------
# (i) the test count results.md states

def count_test_methods(root=os.path.join(REPO, 'tests')):
    """Lines ``    def test_`` in the test files: what ``grep -rh "^    def test_" tests/
    --include=*.py | wc -l`` counts."""
    n = 0
    for path in glob.glob(os.path.join(root, '**', '*.py'), recursive=True):
        with open(path, encoding='utf-8') as f:
            n += sum(1 for line in f if line.startswith('    def test_'))
    return n


def stated_test_count(text):
    """``(line, count)`` of the test count a text states ("N test methods"), or None."""
    m = re.search(r'(\d[\d ]*) test methods', text)
    return (line_of(text, m.start()), int(m.group(1).replace(' ', ''))) if m else None


# ---------------------------------------------------------------------------------------------
# (j) the index of the measurement records

def unindexed_records(data_dir=os.path.join(REPO, 'docs', 'data')):
    """Files and directories of docs/data/ that its README.md does not list (by name, by name
    without its extension, or by a backticked pattern such as ``tolerance_effect_*.json``)."""
    import fnmatch
    with open(os.path.join(data_dir, 'README.md'), encoding='utf-8') as f:
        index = f.read()
    patterns = [p for p in re.findall(r'`([^`\s]+)`', index) if '*' in p]
    out = []
    for name in sorted(os.listdir(data_dir)):
        if name == 'README.md':
            continue
        stem = os.path.splitext(name)[0]
        listed = ('`%s' % name in index or '`%s.' % stem in index
                  or any(fnmatch.fnmatch(name, p) for p in patterns))
        if not listed:
            out.append(name)
    return out


# ---------------------------------------------------------------------------------------------

def report(found, what):
    return '%d %s:\n' % (len(found), what) + '\n'.join('  ' + ': '.join(str(x) for x in f) for f in found)


class CheckerTest(unittest.TestCase):
    """The checks report wrong citations (constructed texts)."""

    def test_paths(self):
        text = 'see `scripts/pile.py` and scripts/no_such_script.py, `tests/runs/test_io.py`, ' \
               'runs/<run>/ckpt, tests/core/*.cpp, docs/data/.\n'
        self.assertEqual(missing_paths(text), [(1, 'scripts/no_such_script.py')])
        self.assertEqual(missing_paths('the old tests/test_benchio.py'), [(1, 'tests/test_benchio.py')])

    def test_links(self):
        docs = os.path.join(REPO, 'docs')
        self.assertEqual(broken_links('[p](pile.md) [m](method.md#the-solver-core-and-its-data-flow)', docs), [])
        self.assertEqual([b[1] for b in broken_links('[x](nowhere.md) [y](method.md#no-such-heading)', docs)],
                         ['nowhere.md', 'method.md#no-such-heading'])
        self.assertEqual(slug('The full pile (14 000 grains)'), 'the-full-pile-14-000-grains')

    def test_dotted_names(self):
        good = ['yadecd.analysis.flank_slope', 'yadecd.analysis.surface.flank_slope', 'yadecd.pile.run',
                'yadecd.pile.protocol.DEFAULTS', 'yadecd.pile.PileRun', 'yadecd.io.write_csv',
                'yadecd.compare.run', 'yadecd.export.fclib', 'yadecd.engines', 'yadecd.analysis.stats.sweeps_to',
                'yadecd.analysis.SNAP_NAME', 'yadecd.analysis.BandDensity']
        for name in good:
            self.assertIsNone(resolve(name), name)
        for name in ['yadecd.analysis.no_such_thing', 'yadecd.pile_analysis', 'yadecd.pile.no_such',
                     'yadecd.analysis._line_angles', 'yadecd.benchio.write_csv', 'yadecd.pile.PileRun.no_such_method']:
            self.assertIsNotNone(resolve(name), name)
        text = 'Use yadecd.analysis.no_such_thing.\n```\nfrom yadecd.analysis import flank_slope, nothing_here\n```'
        self.assertEqual([(ln, n) for ln, n, _ in unresolved_names(text)],
                         [(1, 'yadecd.analysis.no_such_thing'), (3, 'yadecd.analysis.nothing_here')])
        self.assertEqual(retired_modules('`pile_analysis.force_change`, scripts/pile_figures.py'),
                         [(1, 'pile_analysis')])

    def test_attributes(self):
        self.assertIsNone(class_attribute_missing('ContactDynamicsIntegrator', 'tolerance'))
        self.assertIsNone(class_attribute_missing('ContactDynamicsIntegrator', 'gravity'))  # NewtonIntegrator's
        self.assertIsNone(class_attribute_missing('CDPhys', 'tangensOfFrictionAngle'))      # FrictPhys'
        text = ('`ContactDynamicsIntegrator.noSuchOption` and :yref:`x<ContactDynamicsIntegrator.alsoMissing>`\n'
                '    O.engines = engines(gravity=(0, 0, -9.81), extra=[PyRunner(iterPeriod=10)], bogusKnob=3)\n'
                '`CDPhys.overlapAllowance`, `CDPhys.noSuchField`\n'
                '## Options (all attributes of `ContactDynamicsIntegrator`)\n'
                '| `tolerance` | 1e-6 |\n| `madeUp` | 1 |\n')
        self.assertEqual([(ln, n) for ln, n, _ in missing_attributes(text)],
                         [(1, 'ContactDynamicsIntegrator.noSuchOption'), (1, 'ContactDynamicsIntegrator.alsoMissing'),
                          (3, 'CDPhys.noSuchField'), (2, 'ContactDynamicsIntegrator.bogusKnob'),
                          (6, 'ContactDynamicsIntegrator.madeUp')])

    def test_members(self):
        text = ('`ContactSet::state`, `ContactState::r`, `BodyRecord::vi/wi`, `cd::Params::h`, `State::pos`, '
                '`cd::projectOnCone`, `Schedule::run`, `Solver::localVelocity(k)`\n'
                '`ContactSet::r[k]`, `ContactSet::mu[k]`, `BodyRecord::vi/nope`, `cd::noSuchFunction`,\n'
                '`NoSuchType::x`, `ContactDynamicsIntegrator::action()`, `ContactDynamicsIntegrator::tolerance`,\n'
                '`CDPhys::normalForce`\n')
        self.assertEqual([(ln, n) for ln, n, _ in missing_members(text)],
                         [(2, 'ContactSet::r'), (2, 'ContactSet::mu'), (2, 'BodyRecord::nope'), (3, 'NoSuchType::x'),
                          (2, 'cd::noSuchFunction')])


    def test_tests_cited(self):
        text = ('`TestResume.test_branch`, `TestKills`, `test_frictionless_gap_contact_converges`, `test_docs`\n'
                '`tests/engine/test_physics.py::TestCoulombIsotropy`\n'
                '`TestNoSuchThing`, `TestResume.test_no_such`, `test_never_written`,\n'
                '`tests/engine/test_physics.py::TestNoSuch`\n')
        self.assertEqual([(ln, n) for ln, n, _ in missing_tests(text)],
                         [(3, 'TestNoSuchThing'), (3, 'TestResume.test_no_such'), (3, 'test_never_written'),
                          (4, 'tests/engine/test_physics.py::TestNoSuch')])

    def test_deprecations(self):
        self.assertIn(('ContactDynamicsIntegrator', 'sweepOrder'), deprecated_attributes())
        text = ('Set `sweepOrder=5` for slabs.\n\nThe deprecated `sweepOrder` still works.\n\n'
                '| `sweepOrder` | 1 | the schedule |\n| `sweepOrder` | 1 | deprecated code |\n')
        self.assertEqual([ln for ln, _, _ in undeclared_deprecations(text)], [1, 5])

    def test_options(self):
        text = ('    scripts/yade -n -x scripts/pile.py --out x --n-grains 300 --schedule slabs --no-momentum \\\n'
                '        --sweep-order 5\n'
                'run `pile_figures.py RUN --epoch 10` or `cd_core_bench --tolerance 1e-3 --bogus 1`,\n'
                '`pile.py --resume`\n'
                '`pile_ensemble.py run ROOT --sizes 5000 --bogus-two -- --dt 1e-3 --tolerance 3e-3`\n')
        self.assertEqual([(ln, n) for ln, n, _ in unknown_options(text)],
                         [(1, 'scripts/pile.py --sweep-order'), (3, 'cd_core_bench --bogus'), (5, 'pile_ensemble.py --bogus-two')])

    def test_records_index(self):
        import tempfile
        with tempfile.TemporaryDirectory() as d:
            for name in ('README.md', 'a.csv', 'a.md', 'b_1.json', 'c.txt'):
                with open(os.path.join(d, name), 'w') as f:
                    f.write('| `a.csv`, `.md` | ... |\n| `b_*.json` | ... |\n' if name == 'README.md' else '')
            os.mkdir(os.path.join(d, 'runs_dir'))
            self.assertEqual(unindexed_records(d), ['c.txt', 'runs_dir'])

class DocsTest(unittest.TestCase):
    """The documentation's citations exist."""

    def check(self, finder, what):
        found = []
        for rel, text in doc_texts():
            found += [(rel,) + f for f in finder(rel, text)]
        self.assertEqual(found, [], report(found, what))

    def test_paths_exist(self):
        self.check(lambda rel, text: missing_paths(text), 'cited paths that do not exist')

    def test_links_lead_somewhere(self):
        self.check(lambda rel, text: broken_links(text, os.path.dirname(os.path.join(REPO, rel))),
                   'relative links that lead nowhere')

    def test_dotted_names_resolve(self):
        self.check(lambda rel, text: unresolved_names(text), 'yadecd names that do not resolve')

    def test_no_retired_module(self):
        self.check(lambda rel, text: retired_modules(text), 'citations of retired modules')

    def test_engine_attributes_declared(self):
        self.check(lambda rel, text: missing_attributes(text),
                   'plugin class attributes cited but not declared (pkg/cd/*.hpp YADE_CLASS macros)')

    def test_cpp_members_exist(self):
        self.check(lambda rel, text: missing_members(text), 'C++ Type::member citations that do not exist')


    def test_tests_cited_exist(self):
        self.check(lambda rel, text: missing_tests(text), 'tests cited by name that do not exist')

    def test_deprecated_attributes_marked(self):
        self.check(lambda rel, text: undeclared_deprecations(text), 'deprecated attributes cited as current')

    def test_script_options_exist(self):
        self.check(lambda rel, text: unknown_options(text), 'script options that the script does not take')

    def test_stated_test_count(self):
        """docs/results.md states the number of test methods there are (update it with the tests)."""
        with open(os.path.join(REPO, 'docs', 'results.md'), encoding='utf-8') as f:
            stated = stated_test_count(f.read())
        self.assertIsNotNone(stated, 'docs/results.md states no "N test methods"')
        self.assertEqual(stated[1], count_test_methods(),
                         'docs/results.md:%d says %d test methods; tests/ has %d' % (stated[0], stated[1],
                                                                                    count_test_methods()))

    def test_records_indexed(self):
        """docs/data/README.md lists every record of docs/data/, and what it cites exists."""
        self.assertEqual(unindexed_records(), [], 'records missing from docs/data/README.md')
        with open(os.path.join(REPO, 'docs', 'data', 'README.md'), encoding='utf-8') as f:
            index = f.read()
        self.assertEqual(missing_paths(index), [], 'paths of docs/data/README.md that do not exist')
        self.assertEqual(unresolved_names(index), [], 'names of docs/data/README.md that do not resolve')
        self.assertEqual(unknown_options(index), [], 'options of docs/data/README.md that the scripts do not take')

if __name__ == '__main__':
    unittest.main()

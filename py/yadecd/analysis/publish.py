"""Where the analyses' outputs live in ``docs/``: one table, used by every ``--docs`` option.

The ensemble analysis (``pile_ensemble.py analyse``) and the growth curves (``pile_growth.py``)
write their tables and figures into one output directory; a finished long run
(``pile_finish.py``, :mod:`.finish`) writes per epoch a figures directory and the tolerance
record of its tight re-solve (:func:`publish_finished`). The documentation keeps them in two
places: tables and JSON under ``docs/data/`` (listed in ``docs/data/README.md``), figures under
``docs/figures/``. :data:`DOCS_PLACES` says which file goes where, so that refreshing the docs
after new runs is one option of the command that made the outputs, not a list of copies done by
hand. Files that match no entry (per-run summaries, caches) stay where they were written.
"""
import fnmatch
import os
import shutil

#: (file-name pattern, directory under the docs root), first match wins.
DOCS_PLACES = (
    ('answer_table.md', 'data'),
    ('ensemble_table.md', 'data'),
    ('ensemble_summary.json', 'data'),
    ('size_trend.md', 'data'),
    ('growth.md', 'data'),
    ('shape_table.md', 'data/shapes'),
    ('ensemble_*.png', 'figures/ensemble'),
    ('size_trend_*.png', 'figures/ensemble'),
    ('growth_dip.png', 'figures/ensemble'),
    ('shapes_*.png', 'figures/shapes'),
)


def docs_place(name):
    """The directory under the docs root where an output named ``name`` is kept, or None."""
    for pattern, place in DOCS_PLACES:
        if fnmatch.fnmatchcase(name, pattern):
            return place
    return None


def check_docs_root(docs_root):
    """Raise ValueError naming ``docs_root`` unless it is a documentation tree (holding ``data/``
    and ``figures/``); commands call it before their work, so a typo fails at once."""
    missing = [d for d in ('data', 'figures') if not os.path.isdir(os.path.join(docs_root, d))]
    if missing:
        raise ValueError('%s is not a docs directory (no %s)' % (docs_root, ' or '.join(d + '/' for d in missing)))


def publish(out_dir, docs_root, log=None):
    """Copy every file of ``out_dir`` (not its subdirectories) that has a place in
    :data:`DOCS_PLACES` to that place under ``docs_root``; return the list of (source,
    destination) pairs, in name order.

    ``docs_root`` must be a documentation tree (holding ``data/`` and ``figures/``): a wrong path
    raises ValueError naming it before anything is copied (:func:`check_docs_root`)."""
    check_docs_root(docs_root)
    if not os.path.isdir(out_dir):
        raise ValueError('%s is not a directory of analysis outputs' % out_dir)
    copied = []
    for name in sorted(os.listdir(out_dir)):
        src = os.path.join(out_dir, name)
        place = docs_place(name)
        if place is None or not os.path.isfile(src):
            continue
        dest_dir = os.path.join(docs_root, place)
        os.makedirs(dest_dir, exist_ok=True)
        dest = os.path.join(dest_dir, name)
        shutil.copyfile(src, dest)
        copied.append((src, dest))
        if log:
            log('docs: %s -> %s' % (name, os.path.relpath(dest, docs_root)))
    return copied


def finished_places(name, epoch):
    """Where a finished long run's epoch goes under the docs root: (figures directory, tolerance
    record), e.g. ``figures/n14000_s2_relaxed`` and ``data/tolerance_effect_n14000_s2_relaxed.json``."""
    return (os.path.join('figures', '%s_%s' % (name, epoch)),
            os.path.join('data', 'tolerance_effect_%s_%s.json' % (name, epoch)))


def publish_finished(out_dir, name, epochs, docs_root, log=None):
    """Copy what :func:`.finish.finish` wrote in ``out_dir`` for run ``name`` and each of
    ``epochs`` to its place under ``docs_root`` (:func:`finished_places`): the epoch's figures
    directory, replaced whole (no figure of an earlier finish stays beside the new ones), and its
    ``tolerance_effect.json``. An epoch without figures copies its record only. Returns the
    destinations written."""
    check_docs_root(docs_root)
    written = []
    for epoch in epochs:
        fig_dest, tol_dest = (os.path.join(docs_root, p) for p in finished_places(name, epoch))
        figures = os.path.join(out_dir, epoch, 'figures')
        here = []
        if os.path.isdir(figures):
            if os.path.isdir(fig_dest):
                shutil.rmtree(fig_dest)
            shutil.copytree(figures, fig_dest)
            here.append(fig_dest)
        tol = os.path.join(out_dir, epoch, 'tolerance_effect.json')
        if os.path.isfile(tol):
            shutil.copyfile(tol, tol_dest)
            here.append(tol_dest)
        for w in here if log else ():
            log('docs: %s' % os.path.relpath(w, docs_root))
        written += here
    return written

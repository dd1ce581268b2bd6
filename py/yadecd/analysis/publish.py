"""Where the analyses' outputs live in ``docs/``: one table, used by every ``--docs`` option.

The ensemble analysis (``pile_ensemble.py analyse``) and the growth curves (``pile_growth.py``)
write their tables and figures into one output directory. The documentation keeps them in two
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

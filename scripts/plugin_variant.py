"""A second YADE prefix that runs another build of the plugin, beside the installed one.

    /usr/bin/python3 scripts/plugin_variant.py BUILD_DIR PREFIX [--throwaway-attribute] [--repo-py]

Compiles the plugin from this repository into BUILD_DIR (with ``--throwaway-attribute``: one more
serialized attribute in ContactDynamicsIntegrator, the layout change of tests/runs/test_runstate.py),
then makes PREFIX a YADE prefix of symbolic links to the installed YADE in which the plugin is the
new build (and, with ``--repo-py``, the ``yadecd`` package is this repository's ``py/yadecd``).
Run it with ``YADECD_VARIANT_PREFIX=PREFIX scripts/yade ...`` (scripts/yade then sets YADE_PREFIX, from
which YADE reads its libraries).
The installed YADE and plugin are never touched.
"""
import argparse
import os
import sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(sys.argv[0])), '..', 'py'))  # this checkout's yadecd (README: which yadecd)

from yadecd.testing.variant import REPO, build, make_prefix  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(prog='plugin_variant.py', description=__doc__.split('\n')[0])
    ap.add_argument('build_dir')
    ap.add_argument('prefix')
    ap.add_argument('--throwaway-attribute', action='store_true')
    ap.add_argument('--repo-py', action='store_true', help="use this repository's py/yadecd")
    ap.add_argument('--jobs', type=int, default=None)
    a = ap.parse_args(argv)
    plugin = build(a.build_dir, a.throwaway_attribute, a.jobs)
    make_prefix(a.prefix, plugin, os.path.join(REPO, 'py', 'yadecd') if a.repo_py else None)
    print('plugin_variant: %s runs %s (YADECD_VARIANT_PREFIX=%s scripts/yade ...)' % (a.prefix, plugin, a.prefix))
    return 0


if __name__ == '__main__':
    sys.exit(main())

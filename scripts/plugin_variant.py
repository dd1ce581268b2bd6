"""A second YADE prefix that runs another build of the plugin, beside the installed one.

    /usr/bin/python3 scripts/plugin_variant.py BUILD_DIR PREFIX [--throwaway-attribute] [--repo-py]

Compiles the plugin from this repository into BUILD_DIR (with ``--throwaway-attribute``: one more
serialized attribute in ContactDynamicsIntegrator, the layout change of tests/test_runstate.py),
then makes PREFIX a YADE prefix of symbolic links to the installed YADE in which the plugin is the
new build (and, with ``--repo-py``, the ``yadecd`` package is this repository's ``py/yadecd``).
Run it with ``YADECD_VARIANT_PREFIX=PREFIX scripts/yade ...`` (scripts/yade then sets YADE_PREFIX, from
which YADE reads its libraries).
The installed YADE and plugin are never touched.
"""
import argparse
import os
import shutil
import subprocess
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PLUGIN = 'libpkg_contactdynamics.so'


def yade_env():
    """YADE_PREFIX, YADE_VERSION and YADE_LIBDIR of the cached YADE (scripts/yade-env.sh)."""
    out = subprocess.run(['bash', '-c', 'source "%s/scripts/yade-env.sh"; echo "$YADE_PREFIX"; echo "$YADE_VERSION"; '
                          'echo "$YADE_LIBDIR"' % REPO], capture_output=True, text=True, check=True).stdout.split('\n')
    return out[0], out[1], out[2]


def build(build_dir, throwaway=False, jobs=None):
    """Configure and compile the plugin into ``build_dir``; returns the library's path."""
    prefix, _, _ = yade_env()
    cmake = ['cmake', '-S', REPO, '-B', build_dir, '-G', 'Ninja', '-DYADE_PREFIX=' + prefix,
             '-DCMAKE_BUILD_TYPE=Release', '-DYADECD_THROWAWAY_ATTRIBUTE=' + ('ON' if throwaway else 'OFF')]
    subprocess.run(cmake, check=True, stdout=subprocess.DEVNULL)
    subprocess.run(['cmake', '--build', build_dir, '-j%d' % (jobs or os.cpu_count() or 1)], check=True,
                   stdout=subprocess.DEVNULL)
    return os.path.join(build_dir, PLUGIN)


def make_prefix(prefix_out, plugin, yadecd_dir=None):
    """Make ``prefix_out`` a YADE prefix of links to the installed one, with ``plugin`` as the
    Contact Dynamics plugin (and ``yadecd_dir`` as the yadecd package when given)."""
    prefix, version, libdir = yade_env()
    rel = os.path.relpath(libdir, prefix)
    new_lib = os.path.join(prefix_out, rel)
    shutil.rmtree(prefix_out, ignore_errors=True)
    os.makedirs(os.path.join(new_lib, 'plugins'))
    os.makedirs(os.path.join(new_lib, 'py'))
    for name in os.listdir(libdir):
        if name not in ('plugins', 'py'):
            os.symlink(os.path.join(libdir, name), os.path.join(new_lib, name))
    for name in os.listdir(os.path.join(libdir, 'plugins')):
        if name != PLUGIN:
            os.symlink(os.path.join(libdir, 'plugins', name), os.path.join(new_lib, 'plugins', name))
    shutil.copy2(plugin, os.path.join(new_lib, 'plugins', PLUGIN))   # a copy: a rebuild cannot pull it away
    for name in os.listdir(os.path.join(libdir, 'py')):
        src = os.path.join(libdir, 'py', name)
        if name == 'yadecd' and yadecd_dir:
            src = os.path.abspath(yadecd_dir)
        os.symlink(src, os.path.join(new_lib, 'py', name))
    for name in os.listdir(prefix):
        if name not in ('lib',):
            os.symlink(os.path.join(prefix, name), os.path.join(prefix_out, name))
    return prefix_out


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

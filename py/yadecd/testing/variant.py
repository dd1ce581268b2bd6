"""Another build of the plugin run beside the installed one, through a second YADE prefix.

:func:`build` compiles the plugin from this checkout (optionally with one more serialized
attribute, the layout change of the resume tests); :func:`make_prefix` makes a YADE prefix of
symbolic links to the installed YADE in which the plugin (and optionally the yadecd package) is
another. Run it with ``YADECD_VARIANT_PREFIX=PREFIX scripts/yade ...``. The installed YADE and
plugin are never touched. Needs a checkout (it compiles the plugin's sources); no YADE import.
"""
import os
import shutil
import subprocess

#: the checkout this package is part of
REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..'))
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

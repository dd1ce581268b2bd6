#!/usr/bin/env bash
# One-command set-up of the Contact Dynamics plugin for YADE.
#
#   bash scripts/setup.sh            # install everything, then run the demo (small pile)
#   bash scripts/setup.sh --no-demo  # install only
#
# Steps: (1) Debian packages, (2) YADE 2025.2.0 built from the upstream tarball served by the
# Debian mirror (cached outside the repository, rebuilt only when its version or options change),
# (3) this plugin and its Python helpers installed into YADE's library directory, (4) the demo.
#
# Variables (all optional):
#   YADE_CD_HOME    cache root for the YADE build and install   (default: $HOME/.cache/yade-cd)
#   YADE_SOURCE     an existing YADE 2025.2.0 source tarball (.tar.bz2/.tar.gz/.tar.xz) or an
#                   unpacked source tree, used instead of downloading
#   YADE_JOBS       parallel build jobs                          (default: nproc)
set -euo pipefail
# YADE must be configured, built and run with Debian's interpreter, never a pyenv shim.
# Drop every pyenv entry from PATH: YADE's CMake probes python3.X names and would find its shims.
PATH=$(printf '%s' "/usr/sbin:/usr/bin:/sbin:/bin:$PATH" | tr ':' '\n' | grep -v pyenv | paste -sd:)
export PATH; unset PYENV_VERSION PYTHONPATH PYTHONHOME
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$REPO/scripts/yade-env.sh"

DEMO=1; YADE_ONLY=0
for a in "$@"; do case "$a" in --no-demo) DEMO=0 ;; --yade-only) YADE_ONLY=1 ;; *) echo "unknown option $a" >&2; exit 2 ;; esac; done
T0=$(date +%s)
say() { printf '[setup %4ds] %s\n' $(( $(date +%s) - T0 )) "$*"; }

# ---------------------------------------------------------------- 1. system packages
PKGS="cmake g++ ninja-build libboost-all-dev libeigen3-dev python3-dev python3-numpy python3-mpmath
libbz2-dev zlib1g-dev python3-minieigen python3-pygraphviz python3-xlib python3-sphinx python3-tk
python3-ipython python3-matplotlib python3-future python3-pil python3-siconos python3-scipy python3-h5py python3-mpi4py python3-distributed bzip2 curl ca-certificates"
missing=$(for p in $PKGS; do dpkg-query -W -f='${Status}\n' "$p" 2>/dev/null | grep -q 'install ok installed' || echo "$p"; done)
if [ -n "$missing" ]; then
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO=sudo
  say "installing Debian packages: $(echo $missing | tr '\n' ' ')"
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q $missing
else
  say "Debian packages: all present"
fi

# ---------------------------------------------------------------- 2. YADE (cached)
if [ -f "$YADE_PREFIX/.complete" ]; then
  say "YADE $YADE_VERSION: cached at $YADE_PREFIX"
else
  say "YADE $YADE_VERSION is not built yet: first build takes about 10-20 min on 2 cores (unity build, measured 10 to 19 min by host)."
  SRC_ROOT="$YADE_CD_HOME/src"; mkdir -p "$SRC_ROOT"
  if [ -n "${YADE_SOURCE:-}" ] && [ -d "$YADE_SOURCE" ]; then
    SRC="$YADE_SOURCE"
  else
    TARBALL="${YADE_SOURCE:-$SRC_ROOT/yade_${YADE_VERSION}.orig.tar.bz2}"
    if [ ! -f "$TARBALL" ]; then
      # The mirror is read from apt's configuration; no host name lives in this repository.
      MIRROR=$(grep -hE '^\s*URIs:' /etc/apt/sources.list.d/*.sources 2>/dev/null | awk '{print $2}' | grep -v security | head -1)
      [ -n "$MIRROR" ] || MIRROR=$(grep -hE '^\s*deb\s' /etc/apt/sources.list 2>/dev/null | awk '{print $2}' | grep -v security | head -1)
      [ -n "$MIRROR" ] || { echo "no Debian mirror found in the apt configuration; set YADE_SOURCE" >&2; exit 1; }
      say "downloading yade_${YADE_VERSION}.orig.tar.bz2 from the apt mirror"
      curl -fsSL --retry 3 -o "$TARBALL.part" "${MIRROR%/}/pool/main/y/yade/yade_${YADE_VERSION}.orig.tar.bz2"
      mv "$TARBALL.part" "$TARBALL"
    fi
    if [ -z "${YADE_SOURCE:-}" ]; then
      echo "$YADE_SHA256  $TARBALL" | sha256sum -c --quiet - || { echo "SHA-256 mismatch for $TARBALL" >&2; rm -f "$TARBALL"; exit 1; }
      say "SHA-256 verified"
    fi
    rm -rf "$SRC_ROOT/trunk-$YADE_VERSION"
    tar -xf "$TARBALL" -C "$SRC_ROOT"
    SRC="$SRC_ROOT/trunk-$YADE_VERSION"
  fi
  BUILD="$YADE_CD_HOME/build-$YADE_KEY"; rm -rf "$BUILD"; mkdir -p "$BUILD"
  say "configuring YADE ($YADE_OPTIONS)"
  # shellcheck disable=SC2086
  (cd "$BUILD" && cmake -G Ninja "$SRC" $YADE_OPTIONS -DCMAKE_INSTALL_PREFIX="$YADE_PREFIX" \
      -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_EXPORT_COMPILE_COMMANDS=ON > "$BUILD/configure.log" 2>&1) \
    || { tail -30 "$BUILD/configure.log"; exit 1; }
  say "building YADE with ${YADE_JOBS:-$(nproc)} jobs (log: $BUILD/build.log; ninja prints [done/total])"
  if ! (cd "$BUILD" && ninja -j"${YADE_JOBS:-$(nproc)}" install 2>&1 | tee "$BUILD/build.log" \
        | grep --line-buffered -E '^\[[0-9]+/[0-9]+\]' | while read -r step _; do say "   YADE build step $step"; done) \
     || [ ! -x "$YADE_BIN" ]; then
    tail -40 "$BUILD/build.log"; echo "YADE build failed (log: $BUILD/build.log)" >&2; exit 1
  fi
  # keep what the plugin build needs: headers (source tree) and generated compile flags
  ln -sfn "$SRC" "$YADE_PREFIX/source"
  cp "$BUILD/compile_commands.json" "$YADE_PREFIX/compile_commands.json"
  touch "$YADE_PREFIX/.complete"
  say "YADE installed at $YADE_PREFIX"
fi

[ "$YADE_ONLY" = 1 ] && exit 0
# ---------------------------------------------------------------- 3. plugin + Python helpers
say "building the Contact Dynamics plugin"
cmake -S "$REPO" -B "$REPO/build" -G Ninja -DYADE_PREFIX="$YADE_PREFIX" -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build "$REPO/build" -j"${YADE_JOBS:-$(nproc)}"
# the plugin is renamed into place, never rewritten (CMakeLists.txt): a YADE running from this
# prefix (a pile of a long run) keeps the library it mapped
cmake --install "$REPO/build" > /dev/null
say "plugin installed into $YADE_LIBDIR"

# ---------------------------------------------------------------- 4. demo
if [ "$DEMO" = 1 ]; then
  say "running the demo: a small Contact Dynamics pile and its figures (scripts/demo.py)"
  (cd "$REPO" && "$YADE_BIN" -n -x scripts/demo.py)
fi
say "done in $(( $(date +%s) - T0 )) s. Run YADE scripts with: scripts/yade script.py  (= $YADE_BIN)"

# Sourced by the set-up and test scripts: where the cached YADE lives, and under which key.
# The key changes whenever the YADE version or its build options change, forcing a rebuild.
YADE_VERSION=2025.2.0
YADE_SHA256=42702372251bf5e8f07a364bdf30533a1318947e4db90435b1f89293dc029156
YADE_OPTIONS="-DCMAKE_BUILD_TYPE=Release -DDISABLE_ALL=ON -DENABLE_OPENMP=ON -DENABLE_LOGGER=ON \
-DENABLE_MULTI_REAL_HP=OFF -DENABLE_COMPLEX_MP=OFF -DENABLE_USEFUL_ERRORS=OFF -DDISABLE_SAVE_TEMPS=ON \
-DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=16 \
-DDISABLE_PKGS=fem,lbm,levelSet,openfoam,pfv,polyhedra,potential"
YADE_CD_HOME="${YADE_CD_HOME:-$HOME/.cache/yade-cd}"
YADE_KEY="$YADE_VERSION-$(printf '%s' "$YADE_OPTIONS" | sha256sum | cut -c1-10)"
YADE_PREFIX="$YADE_CD_HOME/yade-$YADE_KEY"
YADE_BIN="$YADE_PREFIX/bin/yade-$YADE_VERSION"
YADE_LIBDIR="$YADE_PREFIX/lib/x86_64-linux-gnu/yade-$YADE_VERSION"

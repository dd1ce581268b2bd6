#!/usr/bin/env bash
# Run the whole test suite inside YADE (unittest); prints unittest's summary and exits non-zero
# on failure. Needs scripts/setup.sh to have run once (it builds and installs the plugin).
#   bash tests/run.sh            # all tests
#   bash tests/run.sh -k Incline # only tests whose name contains "Incline"
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$REPO/scripts/yade-env.sh"
if [ ! -x "$YADE_BIN" ] || ! ls "$YADE_LIBDIR"/plugins/libpkg_contactdynamics.so >/dev/null 2>&1; then
  echo "YADE or the plugin is not installed: run 'bash scripts/setup.sh' first." >&2; exit 2
fi
cd "$REPO"
exec env PATH="/usr/bin:/bin:$PATH" "$YADE_BIN" -n -x "$REPO/tests/run_tests.py" "$@"

#!/usr/bin/env bash
# Regenerate every CD-versus-MD chart and table of docs/compare.md in one command:
#   bash scripts/compare_all.sh            # scenes a–f (2363 runs, ~7 min) and the pile, scene g (~6 min)
#   bash scripts/compare_all.sh --quick    # a smoke run of both into out/ (seconds to a minute)
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO"
if [ "${1:-}" = "--quick" ]; then
  scripts/yade -n -x scripts/compare_cd_md.py --quick
  scripts/yade -n -x scripts/compare_pile.py --grains 20 --relax 0.05 --cases cd,md_1e6 --out out/compare_pile_quick
else
  scripts/yade -n -x scripts/compare_cd_md.py
  scripts/yade -n -x scripts/compare_pile.py --out out/compare_pile --docs
fi

#!/usr/bin/env bash
# The fix with its own stereo depth against truth depth on the three held-out sets of world
# seeds (2-4, the issue's set; 10-12 and 13-15, run once each on 2026-12-07), 100 test-zone
# stops per seed and sun: the six runs of scripts/fix-results.sh (resumable: finished reports
# are kept), their pages, and the pooled page with the stops paired stereo against truth.
# Usage: bash scripts/fix-results-pooled.sh   ($ORBFIX_BIN: a built orbfix)
#   about 3 x 25 minutes per depth on 2 cores when nothing is cached yet.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -z "${ORBFIX_BIN:-}" ]; then
  cargo build --release -p orbfix-host
  ORBFIX_BIN="${CARGO_TARGET_DIR:-target}/release/orbfix"
fi
export ORBFIX_BIN
bash scripts/fix-results.sh 100 "2 3 4" truth
ORBFIX_AGAINST=out/fix-results-range bash scripts/fix-results.sh 100 "2 3 4" stereo
ORBFIX_RESULTS_DIR=out/fix-results-range-10-12 ORBFIX_RESULTS_MD=docs/fix-results-range-10-12.md \
  bash scripts/fix-results.sh 100 "10 11 12" truth
ORBFIX_RESULTS_DIR=out/fix-results-stereo-10-12 ORBFIX_RESULTS_MD=docs/fix-results-stereo-10-12.md \
  ORBFIX_AGAINST=out/fix-results-range-10-12 bash scripts/fix-results.sh 100 "10 11 12" stereo
ORBFIX_RESULTS_DIR=out/fix-results-range-13-15 ORBFIX_RESULTS_MD=docs/fix-results-range-13-15.md \
  bash scripts/fix-results.sh 100 "13 14 15" truth
ORBFIX_RESULTS_DIR=out/fix-results-stereo-13-15 ORBFIX_RESULTS_MD=docs/fix-results-stereo-13-15.md \
  ORBFIX_AGAINST=out/fix-results-range-13-15 bash scripts/fix-results.sh 100 "13 14 15" stereo
"$ORBFIX_BIN" fix-report --dir out/fix-results-stereo --dir out/fix-results-stereo-10-12 \
  --dir out/fix-results-stereo-13-15 \
  --against out/fix-results-range --against out/fix-results-range-10-12 \
  --against out/fix-results-range-13-15 \
  --out docs/fix-results-stereo-pooled.md \
  --title "The one fix with its own stereo depth: the three held-out sets pooled (world seeds 2-4, 10-12 and 13-15)" \
  --command "bash scripts/fix-results-pooled.sh"

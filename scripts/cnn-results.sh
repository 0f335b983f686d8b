#!/usr/bin/env bash
# Regenerates docs/matcher-results.md: `orbfix eval` of the classical matchers, the bare CNN
# (`cnn`: the core's fix with only the CNN's sub-cell peak, shipped int8 weights) and the whole
# fix (`fix`) on the test zone, same sun and cross sun, range reprojection; then the tables. Usage: bash scripts/cnn-results.sh [QUERIES] [SEED]
# (defaults 60, 1). About 8 minutes per condition for 60 queries on 2 cores (release).
# Resumable: a condition whose report exists is not run again (delete out/cnn-results to redo);
# $ORBFIX_BIN: a built orbfix instead of building one.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
Q="${1:-60}"
SEED="${2:-1}"
OUT=out/cnn-results
mkdir -p "$OUT"
BIN="${ORBFIX_BIN:-}"
if [ -z "$BIN" ]; then
  cargo build --release -p orbfix-host
  BIN=target/release/orbfix
  [ -n "${CARGO_TARGET_DIR:-}" ] && BIN="$CARGO_TARGET_DIR/release/orbfix"
fi
MATCHERS="ncc,ncc-hp2,cnn,fix"
for cond in same-sun cross-sun; do
  [ -s "$OUT/eval_range_${cond}.json" ] && continue
  "$BIN" eval --seed "$SEED" --queries "$Q" --matcher "$MATCHERS" --condition "$cond" \
    --reprojection range --json "$OUT/eval_range_${cond}.json" --figures "$OUT/fig_${cond}" --examples 2
done
"$BIN" results --dir "$OUT" --out docs/matcher-results.md \
  --title "CNN matcher results: test zone, range reprojection" \
  --notes docs/matcher-results_notes.md --command "bash scripts/cnn-results.sh $Q $SEED"

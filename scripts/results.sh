#!/usr/bin/env bash
# Regenerates docs/results.md: `orbfix eval` for every matcher x condition x reprojection,
# then the table (lut, range, and range with stereo depth noise). Usage: bash scripts/results.sh [QUERIES] [SEED]   (defaults 30, 1)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
Q="${1:-30}"
SEED="${2:-1}"
OUT=out/results
mkdir -p "$OUT"
cargo build --release -p orbfix-host
BIN=target/release/orbfix
[ -n "${CARGO_TARGET_DIR:-}" ] && BIN="$CARGO_TARGET_DIR/release/orbfix"
MATCHERS="ncc,ncc-hp2,ncc-dist,l1,l2"
for rep in lut range; do
  for cond in same-sun cross-sun; do
    "$BIN" eval --seed "$SEED" --queries "$Q" --matcher "$MATCHERS" --condition "$cond" \
      --reprojection "$rep" --json "$OUT/eval_${rep}_${cond}.json" --figures "$OUT/fig_${rep}" --examples 2
  done
done
# The range path with a stereo depth-noise model (sigma = 0.001 z^2 m), same sun only.
"$BIN" eval --seed "$SEED" --queries "$Q" --matcher "$MATCHERS" --condition same-sun \
  --reprojection range --depth-noise-k 0.001 --json "$OUT/eval_range-noise_same-sun.json" \
  --figures "$OUT/fig_range-noise" --examples 2
"$BIN" results --dir "$OUT" --out docs/results.md --command "bash scripts/results.sh $Q $SEED"

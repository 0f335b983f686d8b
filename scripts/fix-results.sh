#!/usr/bin/env bash
# Accuracy of the one fix (`orbfix::fix::run`, default FixConfig) and of the bare CNN on world
# seeds never used in development: STOPS stops per seed and condition in the test zone, range
# reprojection (truth depth), same sun and cross sun; then docs/fix-results.md.
# Usage: bash scripts/fix-results.sh [STOPS] [SEEDS] [REPROJECTION]   ($ORBFIX_BIN: a built orbfix)
#   defaults: 100 "2 3 4" range   (about 25 minutes per 300 stops on 2 cores, release)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
STOPS="${1:-100}"
SEEDS="${2:-2 3 4}"
REP="${3:-range}"
OUT=out/fix-results-$REP
mkdir -p "$OUT"
BIN="${ORBFIX_BIN:-}"
if [ -z "$BIN" ]; then
  cargo build --release -p orbfix-host
  BIN=target/release/orbfix
  [ -n "${CARGO_TARGET_DIR:-}" ] && BIN="$CARGO_TARGET_DIR/release/orbfix"
fi
for seed in $SEEDS; do
  for cond in same-sun cross-sun; do
    f="$OUT/eval_${REP}_seed${seed}_${cond}.json"
    # Resumable: a finished (seed, condition) is not run again.
    [ -s "$f" ] && continue
    "$BIN" eval --seed "$seed" --queries "$STOPS" --matcher fix,cnn --condition "$cond" \
      --reprojection "$REP" --json "$f" --quiet
  done
done
"$BIN" fix-report --dir "$OUT" --out "docs/fix-results-$REP.md" \
  --title "The one fix: accuracy on unseen world seeds ($REP reprojection)" \
  --command "bash scripts/fix-results.sh $STOPS \"$SEEDS\" $REP"

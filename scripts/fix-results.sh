#!/usr/bin/env bash
# Accuracy of the one fix (`orbfix::fix::run`, default FixConfig) and of the bare CNN on world
# seeds never used in development: STOPS stops per seed and condition in the test zone, same
# sun and cross sun, with the depth source DEPTH; then docs/fix-results-NAME.md.
# Usage: bash scripts/fix-results.sh [STOPS] [SEEDS] [DEPTH]   ($ORBFIX_BIN: a built orbfix)
#   DEPTH (or $ORBFIX_DEPTH): stereo (the rover's own stereo pairs, matched by the core inside
#   the fix), truth (the renderer's exact depth; also spelled range) or none (flat ground;
#   also spelled lut). Results in out/fix-results-NAME, NAME = stereo, range (truth) or lut.
#   defaults: 100 "2 3 4" truth   (about 25 minutes per 300 stops on 2 cores with truth depth;
#   stereo renders the right views too and takes longer)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
STOPS="${1:-100}"
SEEDS="${2:-2 3 4}"
DEPTH="${3:-${ORBFIX_DEPTH:-truth}}"
case "$DEPTH" in
  stereo) REP=stereo ;;
  truth|range) DEPTH=truth; REP=range ;;
  none|lut) DEPTH=none; REP=lut ;;
  *) echo "fix-results.sh: depth must be stereo, truth or none (got '$DEPTH')" >&2; exit 2 ;;
esac
# $ORBFIX_RESULTS_DIR / $ORBFIX_RESULTS_MD: other folder and page (e.g. for a shorter run).
# $ORBFIX_AGAINST: folders of reports of the same stops (e.g. truth depth's, for a stereo run)
#   that the page pairs stop by stop with these (differences with 95 % intervals).
OUT="${ORBFIX_RESULTS_DIR:-out/fix-results-$REP}"
MD="${ORBFIX_RESULTS_MD:-docs/fix-results-$REP.md}"
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
      --depth "$DEPTH" --json "$f" --quiet
  done
done
# The page quotes the command with the environment that shaped it.
CMD="bash scripts/fix-results.sh $STOPS \"$SEEDS\" $DEPTH"
for v in ORBFIX_AGAINST ORBFIX_RESULTS_MD ORBFIX_RESULTS_DIR; do
  [ -n "${!v:-}" ] && CMD="$v=\"${!v}\" $CMD"
done
AGAINST=()
for d in ${ORBFIX_AGAINST:-}; do AGAINST+=(--against "$d"); done
"$BIN" fix-report --dir "$OUT" "${AGAINST[@]}" --out "$MD" \
  --title "The one fix: accuracy on unseen world seeds ($DEPTH depth)" \
  --command "$CMD"

#!/usr/bin/env bash
# The stereo benchmark of docs/stereo.md: the core's matcher against OpenCV StereoSGBM and
# StereoBM on the same world-rendered pairs, scored against the renderer's true disparity.
# Prints the overall table and the same pixels by true depth band (coverage, good, error, bias).
# OpenCV lives in a venv under .cache/ (opencv-python-headless from PyPI), never in the core.
#   bash scripts/stereo-bench.sh [--locations N] [--seed S] [other `orbfix bench stereo` options]
#   bash scripts/stereo-bench.sh --seeds "2 3 4 10 11 12 13 14 15" [--locations N] [options]
# With --seeds (first), one set per world seed: a line per set (its core / SGBM bad-pixel
# ratio), then the tables over all the seeds' pairs pooled.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
OUT=.cache/stereo-bench
VENV=.cache/venv-stereo
SEEDS=""
if [ "${1:-}" = "--seeds" ]; then
  [ $# -ge 2 ] || { echo "--seeds wants a list of world seeds, e.g. --seeds \"2 3 4\"" >&2; exit 2; }
  SEEDS="$2"
  shift 2
fi
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV"
  "$VENV/bin/pip" install --quiet opencv-python-headless numpy
fi
if [ -z "$SEEDS" ]; then
  cargo run --release -q -p orbfix-host -- bench stereo --out "$OUT" "$@"
  "$VENV/bin/python" scripts/stereo_bench.py --set "$OUT" --json "$OUT/table.json" --by-depth
  exit 0
fi
cargo build --release -q -p orbfix-host
SETS=()
for s in $SEEDS; do
  target/release/orbfix bench stereo --seed "$s" --out "$OUT/seed-$s" "$@" > /dev/null
  SETS+=("$OUT/seed-$s")
done
"$VENV/bin/python" scripts/stereo_bench.py --set "${SETS[@]}" --json "$OUT/table.json" --by-depth

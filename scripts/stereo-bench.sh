#!/usr/bin/env bash
# The stereo benchmark of docs/stereo.md: the core's matcher against OpenCV StereoSGBM and
# StereoBM on the same world-rendered pairs, scored against the renderer's true disparity.
# Prints the overall table and the same pixels by true depth band (coverage, good, error, bias).
# OpenCV lives in a venv under .cache/ (opencv-python-headless from PyPI), never in the core.
#   bash scripts/stereo-bench.sh [--locations N] [--seed S] [other `orbfix bench stereo` options]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
OUT=.cache/stereo-bench
VENV=.cache/venv-stereo
if [ ! -x "$VENV/bin/python" ]; then
  python3 -m venv "$VENV"
  "$VENV/bin/pip" install --quiet opencv-python-headless numpy
fi
cargo run --release -q -p orbfix-host -- bench stereo --out "$OUT" "$@"
"$VENV/bin/python" scripts/stereo_bench.py --set "$OUT" --json "$OUT/table.json" --by-depth

#!/usr/bin/env bash
# The shipped int8 network in TensorFlow Lite Micro's reference interpreter vs the core,
# byte for byte (docs/interop.md). Exports weights/matcher-v2.ofw with
# `orbfix export-tflite`, runs real top-down inputs (rover top-downs and satellite crops of
# a generated dataset, `orbfix prepare-inputs`) and random int8 inputs through TFLM
# (PyPI tflite-micro, pinned, in .cache/py-venv) and through `orbfix embed`, and prints
# "N passed, M failed"; exits non-zero on any differing byte.
# Usage: bash scripts/tflm-check.sh   (env: TFLM_LOCATIONS real locations, default 110;
#        TFLM_RANDOM random inputs, default 300)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
source scripts/py-venv.sh
LOCATIONS=${TFLM_LOCATIONS:-110}
RANDOM_N=${TFLM_RANDOM:-300}
W=.cache/tflm-check
mkdir -p "$W"
cargo build -q --release -p orbfix-host
B=${CARGO_TARGET_DIR:-$(pwd)/target}/release/orbfix
"$B" export-tflite --out "$W/matcher.tflite"
rm -rf "$W/smoke"
"$B" generate --preset smoke --seed 13 --count "$LOCATIONS" --out "$W/smoke" --quiet
"$B" prepare-inputs --dataset "$W/smoke" --out "$W/real.npy"
"$PY" scripts/tflm_check.py inputs --real "$W/real.npy" --random "$RANDOM_N" --seed 1 --out "$W/inputs.npy"
"$B" embed --input "$W/inputs.npy" --out "$W/orbfix.npy"
"$PY" scripts/tflm_check.py compare --model "$W/matcher.tflite" --inputs "$W/inputs.npy" --orbfix "$W/orbfix.npy"

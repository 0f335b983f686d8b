#!/usr/bin/env bash
# The Python dataset example (scripts/load_dataset.py, docs/dataset.md) on a fresh smoke
# dataset with range images: loads it into NumPy arrays and checks shapes, values and
# errors (scripts/test_load_dataset.py). Pinned numpy + Pillow in .cache/py-venv.
# Usage: bash scripts/python-check.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
source scripts/py-venv.sh
W=.cache/python-check
cargo build -q --release -p orbfix-host
B=${CARGO_TARGET_DIR:-$(pwd)/target}/release/orbfix
rm -rf "$W/smoke"
mkdir -p "$W"
"$B" generate --preset smoke --seed 1 --range --out "$W/smoke" --quiet
"$PY" scripts/load_dataset.py "$W/smoke"
"$PY" scripts/test_load_dataset.py "$W/smoke"

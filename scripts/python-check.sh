#!/usr/bin/env bash
# The Python dataset example (scripts/load_dataset.py, docs/dataset.md) on a fresh smoke
# dataset with range images: loads it into NumPy arrays and checks shapes, values and
# errors (scripts/test_load_dataset.py); then the same on a dataset generated from a DEM site
# (`--dem --ortho`, a region exported with `orbfix export-geotiff`). Pinned numpy + Pillow in
# .cache/py-venv.
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
# The same loader on a dataset of a DEM site (`orbfix generate --dem --ortho`): a 400 m region
# of world seed 2 exported as GeoTIFFs, locations 60 m inside its edges.
rm -rf "$W/dem"
mkdir -p "$W/dem"
"$B" export-geotiff --seed 2 --x 3000 --y 2000 --size-m 400 --m-per-px 0.5 \
  --out-dem "$W/dem/dem.tif" --out-ortho "$W/dem/ortho.tif" > /dev/null
"$B" generate --preset smoke --seed 1 --range --dem "$W/dem/dem.tif" --ortho "$W/dem/ortho.tif" \
  --dem-margin 60 --out "$W/dem/ds" --quiet
"$PY" scripts/load_dataset.py "$W/dem/ds"
"$PY" scripts/test_load_dataset.py "$W/dem/ds"

#!/usr/bin/env bash
# The one fix on a real-format site: a synthetic Mars site (not orbfix's procedural world)
# written by GDAL (scripts/dem_site.py: DEM 0.5 m + orthoimage 0.25 m, IAU_2015:49910), then
# `orbfix eval --dem --ortho --matcher fix` (the map product from the orthoimage, rover
# views rendered over the DEM with the orthoimage as albedo), same sun and cross sun; then
# docs/dem-site-results.md (`orbfix fix-report`).
# Usage: bash scripts/dem-site-results.sh [STOPS_PER_CHUNK] [QUERY_SEEDS]   ($ORBFIX_BIN: a built orbfix)
#   defaults: 25 "2 3 4 5" (100 stops per condition; about 7 s of CPU per stop, release).
# Resumable: each (query seed, condition) chunk is one report, not run again once written.
# Needs python3-gdal (Debian; scripts/gdal-check.sh installs it).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
STOPS="${1:-25}"
SEEDS="${2:-2 3 4 5}"
OUT=out/dem-site
mkdir -p "$OUT/reports"
BIN="${ORBFIX_BIN:-}"
if [ -z "$BIN" ]; then
  cargo build --release -p orbfix-host
  BIN=target/release/orbfix
  [ -n "${CARGO_TARGET_DIR:-}" ] && BIN="$CARGO_TARGET_DIR/release/orbfix"
fi
if [ ! -s "$OUT/ortho.tif" ]; then
  /usr/bin/python3 scripts/dem_site.py --seed 7 --out-dem "$OUT/dem.tif" --out-ortho "$OUT/ortho.tif"
fi
for cond in same-sun cross-sun; do
  for seed in $SEEDS; do
    f="$OUT/reports/eval_dem_seed${seed}_${cond}.json"
    [ -s "$f" ] && continue
    "$BIN" eval --dem "$OUT/dem.tif" --ortho "$OUT/ortho.tif" --seed "$seed" --queries "$STOPS" \
      --matcher fix --condition "$cond" --reprojection range --json "$f" --quiet
  done
done
"$BIN" fix-report --dir "$OUT/reports" --out docs/dem-site-results.md \
  --title "The one fix on a GDAL-written DEM + orthoimage site (synthetic Mars site, IAU_2015:49910)" \
  --command "bash scripts/dem-site-results.sh $STOPS \"$SEEDS\""

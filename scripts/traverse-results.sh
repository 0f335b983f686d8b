#!/usr/bin/env bash
# The measured traverses of docs/traverse.md: world seeds 2, 3, 4, same sun and cross sun,
# 28 stops (about 1.1 km) each, with the per-stop heading comparison at sigma 2 deg; then
# the heading-step measurement (seed 2, steps 1 and 0.5 deg against the default 2) and a drive with heading sigma
# 2 deg (the search inside the loop, seed 3); then the heading tables of docs/traverse.md
# (scripts/heading_table.py, also written to $O/heading-tables.md). Resumable: rerun to continue.
# Usage: bash scripts/traverse-results.sh [BINARY]   (default: the release build)
set -euo pipefail
cd "$(dirname "$0")/.."
B=${1:-target/release/orbfix}
[ -x "$B" ] || cargo build --release -p orbfix-host
O=out/traverse-results
mkdir -p $O
for cond in same-sun cross-sun; do
  for seed in 2 3 4; do
    d=$O/$cond-s$seed
    nice -n 10 "$B" traverse --seed $seed --stops 28 --condition $cond \
      --compare-heading-sigma-deg 2 --json $d/traverse.json --figures $d --quiet | tee $d.log
  done
done
for step in 1 0.5; do
  d=$O/step$step-s2
  nice -n 10 "$B" traverse --seed 2 --stops 28 --heading-step-deg $step \
    --compare-heading-sigma-deg 2 --json $d/traverse.json --figures $d --quiet | tee $d.log
done
d=$O/sigma2-s3
nice -n 10 "$B" traverse --seed 3 --stops 28 --heading-sigma-deg 2 \
  --json $d/traverse.json --figures $d --quiet | tee $d.log
python3 scripts/heading_table.py $O | tee $O/heading-tables.md

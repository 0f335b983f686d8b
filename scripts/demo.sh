#!/usr/bin/env bash
# The README's main command: localize a few rover stops of the built-in world (no files
# needed), print a table and write pictures to out/demo.
# Usage: bash scripts/demo.sh [--stops N] [--seed S] [--matcher M] [--out DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
cargo run --release -p orbfix-host -- demo "$@"

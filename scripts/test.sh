#!/usr/bin/env bash
# Runs every test of orbfix: formatting, lints, the core's and host tools' tests.
# Usage: bash scripts/test.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh

step() { printf '\n== %s ==\n' "$*"; }

step "format"
cargo fmt --all -- --check
step "clippy"
cargo clippy --workspace --all-targets -- -D warnings
step "tests (core and host tools)"
cargo test --workspace

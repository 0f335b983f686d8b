#!/usr/bin/env bash
# Runs every test of orbfix: formatting, lints, the core's and host tools' tests.
# Usage: bash scripts/test.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh

step() { printf '\n== %s ==\n' "$*"; }

step "toolchain (rust-toolchain.toml; docs/toolchain.md)"
pin=$(sed -n 's/^channel = "\(.*\)"$/\1/p' rust-toolchain.toml)
if ! rustc -V | grep -q "^rustc $pin "; then
  echo "rustc is '$(rustc -V)', but rust-toolchain.toml pins $pin: install it with 'rustup toolchain install $pin' (or, where rustup cannot download and stable is $pin, 'rustup toolchain link $pin \"\$(rustc +stable --print sysroot)\"')" >&2
  exit 1
fi
echo "rustc $pin, as pinned"

step "format"
cargo fmt --all -- --check
step "clippy"
cargo clippy --workspace --all-targets -- -D warnings
step "tests (core and host tools)"
cargo test --workspace
# What ships is the release build: the same suite with optimizations (and without overflow
# checks, as the firmware). Its release host binary is the one the stack-probe check reads
# and the flight step runs.
step "tests, release profile"
cargo test --workspace --release
step "stack probes: no large frames in the core, no probe loops in the host binary (docs/toolchain.md)"
cargo build --release -p orbfix-host
python3 scripts/stack-probe-check.py

step "Python interop: TensorFlow Lite Micro bit-exactness, dataset loader (docs/interop.md)"
if [ "${ORBFIX_SKIP_TFLM:-0}" = 1 ]; then
  echo "skipped (ORBFIX_SKIP_TFLM=1)"
else
  # Pinned tflite-micro, numpy and Pillow from PyPI into .cache/py-venv (python3-venv needed).
  bash scripts/tflm-check.sh
  bash scripts/python-check.sh
fi

step "GeoTIFF against GDAL itself: files GDAL writes read right, files orbfix writes georeferenced right (docs/interop.md)"
if [ "${ORBFIX_SKIP_GDAL:-0}" = 1 ]; then
  echo "skipped (ORBFIX_SKIP_GDAL=1)"
else
  # Installs gdal-bin and python3-gdal (Debian) when missing.
  bash scripts/gdal-check.sh
fi

step "flight target: Cortex-M7 (thumbv7em-none-eabihf) build, no-panic link, QEMU run, bit-exact"
if [ "${ORBFIX_SKIP_FLIGHT:-0}" = 1 ]; then
  echo "skipped (ORBFIX_SKIP_FLIGHT=1)"
else
  # Installs QEMU and a thumbv7em Rust toolchain into .cache/ when missing (see docs/flight-target.md).
  FLIGHT_ENV=$(bash scripts/flight-toolchain.sh | tail -n 1)
  FLIGHT_TARGET_DIR=${CARGO_TARGET_DIR:-$(pwd)/target}
  cargo fmt --manifest-path firmware/Cargo.toml -- --check
  if grep -rnE '^\s*(extern crate (std|alloc)|use (std|alloc)::)' src/; then
    echo "the flight core must not use std or alloc (lines above)" >&2
    exit 1
  fi
  (
    source "$FLIGHT_ENV"
    echo "core for $ORBFIX_FLIGHT_TARGET (${ORBFIX_FLIGHT_ROUTE} route), no std, no alloc:"
    cargo check -q -p orbfix --target "$ORBFIX_FLIGHT_TARGET" $ORBFIX_FLIGHT_CARGO_FLAGS
  )
  # Whole fix on the target, budget and bit-exact comparison with the host (fails if not).
  # (The firmware build compiles the core for the target in full, with LTO.) No
  # --allow-panic: the firmware must link with the no-panic handler, i.e. no panic path may
  # remain in anything the fix runs; otherwise `orbfix budget` lists the call sites and fails.
  CARGO_TARGET_DIR=$FLIGHT_TARGET_DIR cargo run --release -q -p orbfix-host -- budget \
    --toolchain-env "$FLIGHT_ENV" --json "$FLIGHT_TARGET_DIR/flight-budget.json" \
    --md "$FLIGHT_TARGET_DIR/timing-budget.md"
  grep -q '"bit_exact": true' "$FLIGHT_TARGET_DIR/flight-budget.json"
  grep -q '"panic_free": true' "$FLIGHT_TARGET_DIR/flight-budget.json" ||
    { echo "the flight firmware is not panic free (call sites above)" >&2; exit 1; }
  # The no-panic link check itself: the firmware without the fix must link, and must stop
  # linking when one panic path is added.
  fw_build() {
    (source "$FLIGHT_ENV" && cd firmware &&
      CARGO_TARGET_DIR=$FLIGHT_TARGET_DIR ORBFIX_VECTORS_DIR="$FLIGHT_TARGET_DIR/flight-vectors" \
        cargo build -q --release --features "$1" $ORBFIX_FLIGHT_CARGO_FLAGS)
  }
  fw_build no-fix
  if fw_build no-fix,panic-probe >"$FLIGHT_TARGET_DIR/panic-probe.log" 2>&1; then
    echo "the panic-probe firmware linked: the no-panic check is not working" >&2
    exit 1
  fi
  grep -q orbfix_firmware_error_a_panic_path_remains "$FLIGHT_TARGET_DIR/panic-probe.log" ||
    { cat "$FLIGHT_TARGET_DIR/panic-probe.log" >&2; echo "panic-probe failed for another reason (log above)" >&2; exit 1; }
  echo "flight target: ok (panic-probe correctly refused to link)"
fi

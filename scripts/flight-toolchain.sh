#!/usr/bin/env bash
# Installs what building and running orbfix's flight firmware needs, into a cache folder:
#   - a Rust compiler that can build `core` for thumbv7em-none-eabihf (Cortex-M7, hard float),
#   - QEMU's `qemu-system-arm` (machine mps2-an500) to run it.
#
# Usage: bash scripts/flight-toolchain.sh [--check]
#   Writes <cache>/env.sh and prints its path as the last line of stdout; `source` that file
#   before `cargo build` in firmware/ (it sets RUSTC, RUSTC_BOOTSTRAP, LD_LIBRARY_PATH and the
#   linker). Messages go to stderr. --check only reports what is installed, changing nothing.
#
# Cache folder: $ORBFIX_FLIGHT_CACHE, default <repo>/.cache/flight-toolchain (git-ignored).
# Nothing outside the cache folder is changed, except that QEMU is installed with apt-get
# when it is missing and we run as root.
#
# Route 1 (preferred, e.g. a laptop with network): `rustup target add thumbv7em-none-eabihf`.
# Route 2 (fallback, machines where rustup cannot download): Debian's rustc-web packages,
#   fetched with `apt-get download` and unpacked with `dpkg -x` into the cache (no install);
#   `core` is then built from source with `-Zbuild-std=core`, linked by rustup's rust-lld.
set -euo pipefail
cd "$(dirname "$0")/.."
REPO=$(pwd)
TARGET=thumbv7em-none-eabihf
CACHE=${ORBFIX_FLIGHT_CACHE:-$REPO/.cache/flight-toolchain}
CHECK_ONLY=0
[ "${1:-}" = "--check" ] && CHECK_ONLY=1

say() { printf 'flight-toolchain: %s\n' "$*" >&2; }
die() {
  printf 'flight-toolchain: ERROR: %s\n' "$*" >&2
  exit 1
}

source scripts/env.sh
mkdir -p "$CACHE"
APT_UPDATED=0
apt_update_once() {
  if [ "$APT_UPDATED" = 0 ] && [ "$(id -u)" = 0 ]; then
    say "refreshing the package lists (apt-get update)"
    apt-get update -qq >&2 || say "apt-get update failed; using the package lists already here"
    APT_UPDATED=1
  fi
}

# ---------------------------------------------------------------- QEMU
if command -v qemu-system-arm >/dev/null 2>&1; then
  say "QEMU: $(qemu-system-arm --version | head -1)"
elif [ "$CHECK_ONLY" = 1 ]; then
  say "QEMU: qemu-system-arm is not installed"
elif [ "$(id -u)" = 0 ]; then
  say "QEMU: installing qemu-system-arm with apt-get (about 1 minute)"
  if ! DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    qemu-system-arm >&2; then
    apt_update_once
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
      qemu-system-arm >&2 || die "could not install qemu-system-arm with apt-get; install it by hand and run this again"
  fi
else
  die "qemu-system-arm is missing and this is not root: run 'sudo apt-get install qemu-system-arm' and run this again (or skip the flight step of scripts/test.sh with ORBFIX_SKIP_FLIGHT=1)"
fi

# ---------------------------------------------------------------- host rust-lld
RUSTUP_SYSROOT=$(rustc --print sysroot)
HOST_TRIPLE=$(rustc -vV | sed -n 's/^host: //p')
RUST_LLD="$RUSTUP_SYSROOT/lib/rustlib/$HOST_TRIPLE/bin/rust-lld"
[ -x "$RUST_LLD" ] || RUST_LLD=$(command -v rust-lld || true)
[ -n "$RUST_LLD" ] && [ -x "$RUST_LLD" ] || die "no rust-lld found (looked in $RUSTUP_SYSROOT/lib/rustlib/$HOST_TRIPLE/bin); install a rustup toolchain"

write_env() { # $1 = route
  local tmp="$CACHE/env.sh.tmp"
  {
    echo "# Written by scripts/flight-toolchain.sh ($1 route). Source before building firmware/."
    echo "export ORBFIX_FLIGHT_ROUTE=$1"
    echo "export ORBFIX_FLIGHT_TARGET=$TARGET"
    echo "export CARGO_TARGET_THUMBV7EM_NONE_EABIHF_LINKER='$RUST_LLD'"
    if [ "$1" = debian ]; then
      echo "export RUSTC='$DEB_RUSTC'"
      echo "export RUSTC_BOOTSTRAP=1"
      echo "export LD_LIBRARY_PATH='$DEB_LIBS'\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
      echo "export ORBFIX_FLIGHT_CARGO_FLAGS='-Zbuild-std=core'"
    else
      echo "export ORBFIX_FLIGHT_CARGO_FLAGS="
    fi
  } >"$tmp"
  mv "$tmp" "$CACHE/env.sh"
  say "ready ($1 route); source $CACHE/env.sh"
  echo "$CACHE/env.sh"
}

# ---------------------------------------------------------------- route 1: rustup
SKIP_RUSTUP=${ORBFIX_FLIGHT_SKIP_RUSTUP:-0} # 1: test the Debian route even where rustup works
if [ "$SKIP_RUSTUP" != 1 ] && rustup target list --installed 2>/dev/null | grep -qx "$TARGET"; then
  say "Rust: $TARGET standard library installed through rustup"
  [ "$CHECK_ONLY" = 1 ] || write_env rustup
  exit 0
fi
if [ "$CHECK_ONLY" = 0 ] && [ "$SKIP_RUSTUP" != 1 ]; then
  say "Rust: trying 'rustup target add $TARGET'"
  if timeout 120 rustup target add "$TARGET" >&2 2>&1; then
    write_env rustup
    exit 0
  fi
  say "rustup could not add $TARGET (no download here?); falling back to Debian's rustc-web"
fi

# ---------------------------------------------------------------- route 2: Debian rustc-web
DEB_ROOT="$CACHE/debian"
DEB_LIBS="$DEB_ROOT/usr/lib/$(dpkg-architecture -qDEB_HOST_MULTIARCH 2>/dev/null || echo x86_64-linux-gnu)"
find_llvm_libdir() {
  local d
  for d in "$DEB_ROOT"/usr/lib/llvm-*/lib; do
    [ -d "$d" ] && echo "$d" && return 0
  done
  return 1
}
DEB_RUSTC="$DEB_ROOT/usr/bin/rustc"
if [ -f "$DEB_ROOT/.complete" ] && [ -x "$DEB_RUSTC" ]; then
  LLVM_LIBDIR=$(find_llvm_libdir || true)
  DEB_LIBS="$DEB_LIBS${LLVM_LIBDIR:+:$LLVM_LIBDIR}"
  say "Rust: Debian rustc-web already unpacked in $DEB_ROOT"
  [ "$CHECK_ONLY" = 1 ] || write_env debian
  exit 0
fi
[ "$CHECK_ONLY" = 1 ] && {
  say "Rust: no $TARGET toolchain yet (run without --check to install)"
  exit 1
}
command -v apt-get >/dev/null 2>&1 || die "no apt-get here: install the $TARGET target with 'rustup target add $TARGET' (needs network) and run this again"

# Newest rustc-web the package lists know; refresh them once if it is older than we need.
MIN_MINOR=${ORBFIX_FLIGHT_MIN_RUSTC_MINOR:-90}
candidate() { apt-cache policy rustc-web 2>/dev/null | sed -n 's/^ *Candidate: *//p'; }
minor_of() { echo "$1" | sed -n 's/^\([0-9]*:\)\?1\.\([0-9]*\)\..*/\2/p'; }
CAND=$(candidate)
if [ -z "$CAND" ] || [ "$CAND" = "(none)" ] || [ "$(minor_of "$CAND")" -lt "$MIN_MINOR" ] 2>/dev/null; then
  apt_update_once
  CAND=$(candidate)
fi
[ -n "$CAND" ] && [ "$CAND" != "(none)" ] || die "apt knows no rustc-web package; check /etc/apt/sources.list (Debian bookworm + bookworm-security)"
say "Rust: using Debian rustc-web $CAND"
# The exact library and LLVM packages this rustc-web was built against.
DEPS=$(apt-cache depends "rustc-web=$CAND" 2>/dev/null | sed -n 's/^ *Depends: *\(libstd-rust-web-[0-9.]*\|libllvm[0-9]*\)$/\1/p' | sort -u)
[ -n "$DEPS" ] || DEPS="libstd-rust-web-1.96 libllvm22"
PKGS="rustc-web=$CAND rust-web-src=$CAND libstd-rust-web-dev=$CAND $DEPS"
DL="$CACHE/debs.partial"
rm -rf "$DL" && mkdir -p "$DL"
say "downloading $PKGS (about 150 MB)"
(cd "$DL" && apt-get download $PKGS >&2) || {
  apt_update_once
  (cd "$DL" && apt-get download $PKGS >&2) || die "apt-get download failed for: $PKGS"
}
STAGE="$CACHE/debian.partial"
rm -rf "$STAGE" && mkdir -p "$STAGE"
for deb in "$DL"/*.deb; do
  say "unpacking $(basename "$deb")"
  dpkg -x "$deb" "$STAGE"
done
rm -rf "$DEB_ROOT" && mv "$STAGE" "$DEB_ROOT" && rm -rf "$DL"
LLVM_LIBDIR=$(find_llvm_libdir || true)
DEB_LIBS="$DEB_LIBS${LLVM_LIBDIR:+:$LLVM_LIBDIR}"
LD_LIBRARY_PATH="$DEB_LIBS" "$DEB_RUSTC" --version >&2 || die "the unpacked rustc does not run; delete $CACHE and try again"
LD_LIBRARY_PATH="$DEB_LIBS" "$DEB_RUSTC" --print target-list | grep -qx "$TARGET" || die "this rustc does not know $TARGET"
SRC=$(LD_LIBRARY_PATH="$DEB_LIBS" "$DEB_RUSTC" --print sysroot)/lib/rustlib/src/rust/library/core
[ -d "$SRC" ] || die "rust-web-src did not provide $SRC"
touch "$DEB_ROOT/.complete"
write_env debian

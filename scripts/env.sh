# Sourced by the scripts: checks the Rust toolchain and installs what the project needs.
if ! command -v cargo >/dev/null 2>&1; then
  if [ -x "$HOME/.cargo/bin/cargo" ]; then
    export PATH="$HOME/.cargo/bin:$PATH"
  else
    echo "orbfix: no Rust toolchain found. Install one (https://rustup.rs, or 'apt-get install cargo' for Debian's) and run this again." >&2
    exit 1
  fi
fi

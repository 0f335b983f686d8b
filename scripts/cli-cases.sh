#!/usr/bin/env bash
# Runs each hostile CLI case of issue 12 with the release binary and prints the Markdown
# table "case | command | exit | what it prints" (docs/reliability.md).
# Usage: bash scripts/cli-cases.sh [OUT_DIR]   (default out/cli-cases; needs a release build)
set -uo pipefail
cd "$(dirname "$0")/.."
B=$(pwd)/target/release/orbfix
[ -x "$B" ] || { echo "build first: cargo build --release -p orbfix-host" >&2; exit 1; }
D=${1:-out/cli-cases}
mkdir -p "$D"
cd "$D"
# Inputs: a 120 m map and a 50 m "top-down image" (a map crop) of world 1, damaged copies.
"$B" map --x 3000 --y 2000 --size-m 120 --out map.png >/dev/null
"$B" map --x 3000 --y 2000 --size-m 50 --out top.png >/dev/null
sed 's/"m_per_px": *[0-9.]*/"m_per_px": -0.25/' map.json > neg-res.json
sed 's/"origin_x_m": *[0-9.e+-]*/"origin_x_m": 1e38/' map.json > far-origin.json
echo '{"origin_x_m": 1' > cut.json
head -c 2000 map.png > cut.png
W=../../weights/matcher-v2.ofw
head -c 1000 "$W" > trunc.ofw
python3 -c "import sys; b=bytearray(open(sys.argv[1],'rb').read()); b[5000]^=0x10; open('corrupt.ofw','wb').write(b)" "$W"
python3 -c "import sys; b=bytearray(open(sys.argv[1],'rb').read()); b[8]^=0x01; open('layers.ofw','wb').write(b)" "$W"
L="localize --map map.png --map-meta map.json --top top.png --out loc"

row() { # case, command (run in bash), [check]
  local out rc
  out=$(timeout 300 bash -c "$2" 2>&1); rc=$?
  out=$(printf '%s' "$out" | grep -v '^\s*$' | tail -n 2 | tr '\n' ' ' | sed 's/|/\\|/g; s/ *$//')
  [ ${#out} -gt 400 ] && out="${out:0:400}..."
  printf '| %s | `%s` | %s | %s |\n' "$1" "${2//$B/orbfix}" "$rc" "$out"
}
echo "| case | command | exit | what it prints now |"
echo "|---|---|---:|---|"
# The device case writes to a private copy of /dev/full (a regression replaces only it).
rm -f full; mknod full c 1 7 2>/dev/null || echo "(not root: the device case runs on a non-device)" >&2
row "output onto a device (\`/dev/full\`, as root)" "$B map --x 3000 --y 2000 --size-m 50 --out full; s=\$?; echo \"(full is still: \$(ls -l full | cut -c1))\"; exit \$s"
row "output onto a directory" "mkdir -p adir; $B map --x 3000 --y 2000 --size-m 50 --out adir"
row "stdout closed early (\`| head\`)" "$B help generate | head -n 1; echo \"exit statuses: \${PIPESTATUS[*]}\""
row "stdout closed early, long output" "$B bench world | head -n 1; echo \"exit statuses: \${PIPESTATUS[*]}\""
row "map resolution -0.25 m/px (was \"BadResolution\")" "$B localize --map map.png --map-meta neg-res.json --top top.png --out loc"
row "map origin 1e38 m (was \"BadOrigin\", a 39-digit fix)" "$B localize --map map.png --map-meta far-origin.json --top top.png --out loc"
row "truncated map georeference" "$B localize --map map.png --map-meta cut.json --top top.png --out loc"
row "truncated map image" "$B localize --map cut.png --map-meta map.json --top top.png --out loc"
row "negative prior (\`--prior-x -5\`)" "$B $L --prior-x -5 --prior-y -5"
row "NaN prior" "$B $L --prior-x nan"
row "fix matcher on a top-down image" "$B $L --matcher fix"
row "\`--noise -5\` (render)" "$B render location --noise -5 --out rl"
row "\`--noise -5\` (bench stereo)" "$B bench stereo --noise -5"
row "NaN heading" "$B render location --heading nan --out rl"
row "NaN sun elevation" "$B map --x 3000 --y 2000 --sun-elevation nan --out m2.png"
row "NaN field of view" "$B render location --hfov nan --out rl"
row "\`generate --size 1x1\`" "$B generate --preset smoke --size 1x1 --out ds1"
row "frames too small to reproject (was \"FrameTooSmall\")" "$B render location --size 1x1 --out rl2"
row "bad fix setting (was \"BadConfig\")" "$B bench-localize --coarse-factor 0 --reps 1"
for c in "demo --stops 1" "eval --seed 2 --queries 1 --json e.json" "embed --input x.npy --out y.npy" "export-tflite --out m.tflite" "budget --json b.json"; do
  row "corrupt weights (CRC), \`${c%% *}\`" "$B $c --weights corrupt.ofw"
done
row "truncated weights" "$B demo --stops 1 --weights trunc.ofw"
row "weights with a flipped layer-count byte" "$B export-tflite --out m.tflite --weights layers.ofw"
row "missing weights" "$B eval --seed 2 --queries 1 --json e.json --weights nothere.ofw"

#!/usr/bin/env bash
# tests/cost_map/run.sh LOCUS SOURCE_DIR: `locus render --cost-map` with the
# real binary (issue #27 item 5; CTest `cost_map_cli`; docs/cost-map.md):
#   1 the issue's command, `locus render scenes/paper/d_spheres_2lights.json
#     -o d.png --cost-map d_cost.png` (no --workers: it renders in process
#     and says so), writes both, each 512x512; so does --workers 0;
#   2 frames: --frames 1-2 with -o f_####.png --cost-map c_####.png writes
#     c_0001.png and c_0002.png at the image's size; a cost map name
#     without #### for two frames is refused;
#   3 bad --cost-map paths are refused before rendering, naming the flag:
#     an unknown format, -o's own file, a directory that cannot be made.
# Prints one line per check and "N passed, M failed".
set -uo pipefail
[ $# -eq 2 ] || { echo "usage: $0 LOCUS SOURCE_DIR" >&2; exit 2; }
locus=$(cd "$(dirname "$1")" && pwd)/$(basename "$1") src=$(cd "$2" && pwd) || exit 2
py=/usr/bin/python3
tmp=$(mktemp -d)
trap 'if [ -n "${KEEP:-}" ]; then echo "kept $tmp"; else rm -rf "$tmp"; fi' EXIT
passed=0 failed=0
ok() { echo "ok: $1"; passed=$((passed + 1)); }
bad() { echo "FAILED: $1"; failed=$((failed + 1)); }
check() { # check DESCRIPTION CMD...
  local what=$1
  shift
  if "$@"; then ok "$what"; else bad "$what"; fi
}
# size_is FILE WxH: the image's size.
size_is() {
  [ -s "$1" ] && [ "$("$py" -c 'import sys; from PIL import Image; w, h = Image.open(sys.argv[1]).size; print(f"{w}x{h}")' "$1")" = "$2" ]
}
# refused DESCRIPTION WORDS ARGS...: the render exits non-zero at once, its
# message names --cost-map and contains WORDS.
refused() {
  local what=$1 words=$2
  shift 2
  local out
  out=$("$locus" render "$@" --workers 0 2>&1)
  local rc=$?
  if [ $rc -ne 0 ] && grep -q -- "--cost-map" <<<"$out" && grep -qi -- "$words" <<<"$out"; then
    ok "$what"
  else
    bad "$what (exit $rc: $out)"
  fi
}

d=$src/scenes/paper/d_spheres_2lights.json

# 1 The issue's command, in a directory of its own.
mkdir -p "$tmp/one"
log=$(cd "$tmp/one" && "$locus" render "$d" -o d.png --cost-map d_cost.png 2>&1)
rc=$?
check "the issue's command exits 0" [ $rc -eq 0 ]
check "d.png is 512x512" size_is "$tmp/one/d.png" 512x512
check "d_cost.png is 512x512" size_is "$tmp/one/d_cost.png" 512x512
check "without --workers it says it renders in process" grep -q "rendering in process" <<<"$log"
"$locus" render "$d" -o "$tmp/w0/d.png" --cost-map "$tmp/w0/maps/d_cost.png" --workers 0 \
  --size 128x96 2>/dev/null
check "--workers 0 --size 128x96: both written at 128x96 (directories made)" \
  size_is "$tmp/w0/maps/d_cost.png" 128x96
check "... and the image" size_is "$tmp/w0/d.png" 128x96
# The map is not the image, and it shows the outline's cyan.
check "the cost map has the ray-traced spans' outline" "$py" - "$tmp/one/d_cost.png" <<'EOF'
import sys
import numpy as np
from PIL import Image
a = np.asarray(Image.open(sys.argv[1]).convert("RGB")).astype(int)
cyan = (a[..., 0] == 0) & (a[..., 1] == 255) & (a[..., 2] == 255)
sys.exit(0 if cyan[:-60].sum() > 500 else 1)
EOF

# 2 Frames.
anim=$src/scenes/anim/spinning_mirror.json
"$locus" render "$anim" --frames 1-2 --size 64x48 -o "$tmp/anim/f_####.png" \
  --cost-map "$tmp/anim/c_####.png" --workers 0 2>/dev/null
check "two frames: c_0001.png is 64x48" size_is "$tmp/anim/c_0001.png" 64x48
check "two frames: c_0002.png is 64x48" size_is "$tmp/anim/c_0002.png" 64x48
refused "two frames, a cost map name without ####" "frame number" "$anim" --frames 1-2 \
  --size 64x48 -o "$tmp/anim2/f_####.png" --cost-map "$tmp/anim2/c.png"

# 3 Bad paths, refused before anything is rendered.
refused "an unknown format" "unsupported image format" "$d" -o "$tmp/bad/d.png" \
  --cost-map "$tmp/bad/d_cost.bmp"
refused "-o's own file" "the same file as -o" "$d" -o "$tmp/bad/d.png" \
  --cost-map "$tmp/bad/./d.png"
refused "a directory that cannot be made" "cannot write into" "$d" -o "$tmp/bad/d.png" \
  --cost-map /proc/locus-no-such-dir/d_cost.png
check "nothing rendered for the refused commands" [ ! -e "$tmp/bad/d.png" ]

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]

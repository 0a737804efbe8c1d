#!/usr/bin/env bash
# tests/cost_map/run.sh LOCUS SOURCE_DIR: `locus render --cost-map` with the
# real binary (issue #27 item 5; CTest `cost_map_cli`; docs/cost-map.md):
#   1 the issue's command, `locus render scenes/paper/d_spheres_2lights.json
#     -o d.png --cost-map d_cost.png` (no --workers: on the embedded local
#     farm, whose workers count and whose coordinator writes the map),
#     writes both, each 512x512; so does --workers 0; a farm of one band
#     writes the same map as --workers 0, value for value; one of six bands
#     the same outline;
#   2 frames: --frames 1-2 with -o f_####.png --cost-map c_####.png writes
#     c_0001.png and c_0002.png at the image's size; a cost map name
#     without #### for two frames is refused;
#   3 bad --cost-map paths are refused before rendering, naming the flag:
#     an unknown format, -o's own file, a directory that cannot be made;
#     on the farm too;
#   4 `locus submit --cost-map` to a running coordinator, then `locus fetch`:
#     the frames and their cost maps in the directory; `locus status`
#     shows the pattern.
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
check "without --workers it renders on the local farm" grep -q "workers) in" <<<"$log"
"$locus" render "$d" -o "$tmp/w0/d.png" --cost-map "$tmp/w0/maps/d_cost.png" --workers 0 \
  --size 128x96 2>/dev/null
check "--workers 0 --size 128x96: both written at 128x96 (directories made)" \
  size_is "$tmp/w0/maps/d_cost.png" 128x96
check "... and the image" size_is "$tmp/w0/d.png" 128x96
# The farm's map is the single process's: one band, the same counts.
"$locus" render "$d" -o "$tmp/cmp/p.png" --cost-map "$tmp/cmp/p_cost.png" --workers 0 \
  --size 160x120 2>/dev/null
"$locus" render "$d" -o "$tmp/cmp/f1.png" --cost-map "$tmp/cmp/f1_cost.png" --workers 2 \
  --bands 1 --size 160x120 2>/dev/null
"$locus" render "$d" -o "$tmp/cmp/f6.png" --cost-map "$tmp/cmp/f6_cost.png" --workers 2 \
  --bands 6 --size 160x120 2>/dev/null
check "a farm of one band writes --workers 0's map exactly" "$py" - "$tmp/cmp/f1_cost.png" \
  "$tmp/cmp/p_cost.png" <<'EOF'
import sys
import numpy as np
from PIL import Image
a, b = (np.asarray(Image.open(p).convert("RGB")).astype(int) for p in sys.argv[1:3])
sys.exit(0 if a.shape == b.shape and np.abs(a - b).max() == 0 else 1)
EOF
# Six bands: each band restarts multi-scanning's chunks and shadow groups,
# so pixels at band tops may cost a little more (docs/cost-map.md); the
# outline (cyan) is the same pixels.
check "a farm of six bands: the same outline" "$py" - "$tmp/cmp/f6_cost.png" \
  "$tmp/cmp/p_cost.png" <<'EOF'
import sys
import numpy as np
from PIL import Image
a, b = (np.asarray(Image.open(p).convert("RGB")).astype(int) for p in sys.argv[1:3])
cyan = lambda m: (m[..., 0] == 0) & (m[..., 1] == 255) & (m[..., 2] == 255)
sys.exit(0 if a.shape == b.shape and cyan(a).sum() > 100 and (cyan(a) == cyan(b)).all() else 1)
EOF

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
out=$("$locus" render "$d" -o "$tmp/bad/d.png" --cost-map "$tmp/bad/d_cost.bmp" --workers 1 2>&1)
rc=$?
check "on the farm too, an unknown format is refused (exit $rc)" \
  eval '[ $rc -ne 0 ] && grep -q -- "--cost-map" <<<"$out" && [ ! -e "$tmp/bad/d.png" ]'

# 4 A running coordinator (loopback, plaintext): submit with a cost map,
# then fetch frames and maps.
bin=$(dirname "$locus")
"$bin/locus-coordinator" --listen 127.0.0.1:0 --data "$tmp/farm" --insecure \
  >"$tmp/coord.out" 2>"$tmp/coord.log" &
cpid=$!
. "$src/tests/farm_lib.sh"  # listening_port
port=$(listening_port "$tmp/coord.out")
farm=127.0.0.1:$port
"$bin/locus-worker" --coordinator "$farm" 2>"$tmp/worker.log" &
wpid=$!
trap 'kill $cpid $wpid 2>/dev/null; if [ -n "${KEEP:-}" ]; then echo "kept $tmp"; else rm -rf "$tmp"; fi' EXIT
check "the coordinator started (port $port)" [ -n "$port" ]
job=$("$locus" submit "$anim" --farm "$farm" --frames 1-2 --size 64x48 -o "s_####.png" \
  --cost-map "sc_####.png" 2>"$tmp/submit.log")
check "submit --cost-map gives a job ($job)" [ -n "$job" ]
"$locus" watch "$job" --farm "$farm" >/dev/null 2>&1
fetched=$("$locus" fetch "$job" "$tmp/fetched" --farm "$farm" 2>&1)
check "fetch says it brought the cost maps ($fetched)" grep -q "with 2 cost maps" <<<"$fetched"
check "fetch: sc_0001.png is 64x48" size_is "$tmp/fetched/sc_0001.png" 64x48
check "fetch: sc_0002.png is 64x48" size_is "$tmp/fetched/sc_0002.png" 64x48
check "fetch: the frames too" size_is "$tmp/fetched/s_0002.png" 64x48
check "status shows the cost map" grep -q "cost map sc_####.png" \
  <<<"$("$locus" status "$job" --farm "$farm" 2>&1)"

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]

#!/usr/bin/env bash
# tests/image_files/run.sh BIN_DIR SOURCE_DIR (CTest image_plugin): the
# image plugin (common/base/image_plugin.h) with the real `locus`:
#   1 the binaries link no OpenImageIO; a PNG or an EXR render loads
#     neither the plugin nor OpenImageIO (LD_DEBUG=files lists what the
#     loader opens); a TIFF render loads the plugin from BIN_DIR/../lib/locus;
#   2 a copy of `locus` with no plugin beside it still renders PNGs and
#     EXRs, the same pixels; a TIFF fails at once with a message that
#     names the file it wanted and where it looked;
#   3 a plugin of another build (a library without the entry point) is
#     refused by name, not called.
# Prints one line per check and "N passed, M failed".
set -uo pipefail
[ $# -eq 2 ] || { echo "usage: $0 BIN_DIR SOURCE_DIR" >&2; exit 2; }
bin=$(cd "$1" && pwd) src=$(cd "$2" && pwd) || exit 2
. "$src/tests/farm_lib.sh"  # same_pixels, prints
tmp=$(mktemp -d)
trap 'if [ -n "${KEEP:-}" ]; then echo "kept $tmp"; else rm -rf "$tmp"; fi' EXIT
passed=0 failed=0
ok() { echo "ok: $1"; passed=$((passed + 1)); }
bad() { echo "FAILED: $1"; failed=$((failed + 1)); }
scene=$src/scenes/simple/spheres.json
plugin=$(cd "$bin/../lib/locus" 2>/dev/null && pwd)/liblocus-image-io.so
[ -f "$plugin" ] || { bad "no plugin at $bin/../lib/locus/liblocus-image-io.so"; echo "0 passed, 1 failed"; exit 1; }

# render LOCUS OUT LOG: a small single-process render.
render() { "$1" render "$scene" --size 48x32 --workers 0 -o "$2" >"$3" 2>&1; }

# ---- 1. what each render loads
for b in locus locus-coordinator locus-worker; do
  if readelf -d "$bin/$b" | grep -q 'NEEDED.*libOpenImageIO'; then
    bad "$b links OpenImageIO"
  else
    ok "$b links no OpenImageIO"
  fi
done
for ext in png exr; do
  LD_DEBUG=files LD_DEBUG_OUTPUT="$tmp/ld-$ext" render "$bin/locus" "$tmp/a.$ext" "$tmp/a-$ext.log" ||
    bad "$ext render: $(cat "$tmp/a-$ext.log")"
  if grep -qhE 'file=[^ ]*(liblocus-image-io|libOpenImageIO)' "$tmp"/ld-$ext.*; then
    bad "a .$ext render loaded: $(grep -ohE 'file=[^ ]*(liblocus-image-io|libOpenImageIO)[^ ]*' "$tmp"/ld-$ext.* | sort -u | tr '\n' ' ')"
  else
    ok "a .$ext render loads neither the image plugin nor OpenImageIO ($(cat "$tmp"/ld-$ext.* | grep -c 'file=.*\[0\];  needed by') libraries opened)"
  fi
done
LD_DEBUG=files LD_DEBUG_OUTPUT="$tmp/ld-tif" render "$bin/locus" "$tmp/a.tif" "$tmp/a-tif.log" ||
  bad "TIFF render: $(cat "$tmp/a-tif.log")"
if grep -qhF "file=$plugin" "$tmp"/ld-tif.* && [ -s "$tmp/a.tif" ]; then
  ok "a TIFF render loads the plugin from $plugin and writes a.tif"
else
  bad "a TIFF render did not load $plugin"
fi

# ---- 2. no plugin
mkdir -p "$tmp/alone/bin"
cp "$bin/locus" "$tmp/alone/bin/"
for ext in png exr; do
  render "$tmp/alone/bin/locus" "$tmp/b.$ext" "$tmp/b-$ext.log" && same_pixels "$tmp/a.$ext" "$tmp/b.$ext" &&
    ok "with no plugin, a .$ext render works, the same pixels" ||
    bad ".$ext render with no plugin: $(cat "$tmp/b-$ext.log")"
done
if render "$tmp/alone/bin/locus" "$tmp/b.tif" "$tmp/b-tif.log"; then
  bad "with no plugin, a .tif render succeeded"
elif grep -q "cannot load the image plugin $tmp/alone/lib/locus/liblocus-image-io.so" "$tmp/b-tif.log" &&
     grep -qF "b.tif" "$tmp/b-tif.log"; then
  ok "with no plugin, a .tif render fails naming the plugin and where it looked: $(grep -o 'cannot load.*' "$tmp/b-tif.log" | head -1 | cut -c1-110)..."
else
  bad "with no plugin, the .tif render's message: $(cat "$tmp/b-tif.log")"
fi

# ---- 3. a plugin of another build
mkdir -p "$tmp/alone/lib/locus"
cp "$(readlink -f /lib/x86_64-linux-gnu/libz.so.1)" "$tmp/alone/lib/locus/liblocus-image-io.so"
if render "$tmp/alone/bin/locus" "$tmp/c.tif" "$tmp/c.log"; then
  bad "a stranger's library taken for the plugin"
elif prints "liblocus-image-io.so .* is of another build" cat "$tmp/c.log"; then
  ok "a library without the entry point is refused: $(grep -o 'is of another build.*' "$tmp/c.log" | head -1)"
else
  bad "a stranger's library: $(cat "$tmp/c.log")"
fi

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]

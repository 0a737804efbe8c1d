#!/usr/bin/env bash
# bench/instructions/run.sh [BUILD_DIR] [SIZE] [AA]: instructions per pixel
# of Locus's rendering (callgrind; counts do not depend on the machine's
# load), for scenes (a), (b), (d) and (d) with every material diffuse (the
# floor), written as Markdown to stdout.
#
# Why a harness: OpenImageIO pulls in libhwy, whose start-up runs RDTSCP,
# an instruction valgrind cannot run; ipp.cpp links the renderer's objects
# without common/base/image.cpp, so no OpenImageIO is loaded.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build}
size=${2:-128}
aa=${3:-4}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
objs=$(ls "$build"/common/CMakeFiles/locus_common.dir/*.o | grep -v '/image.cpp.o$')
g++ -O2 -std=c++20 -I"$root" -I"$build" "$root/bench/instructions/ipp.cpp" -o "$tmp/ipp" $objs \
  "$build/proto/liblocus_proto.a" -lprotobuf -lspdlog -lfmt -ltinyobjloader -lpthread
/usr/bin/python3 - "$root/scenes/paper/d_spheres_2lights.json" "$tmp/d_floor.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
for m in d["materials"]:
    for k in ("ks", "t"):
        if k in m: m[k] = 0
json.dump(d, open(sys.argv[2], "w"))
PY
echo "| scene | pixels | ray-traced pixels | instructions | per pixel |"
echo "|---|---|---|---|---|"
for s in "$tmp/d_floor.json" "$root/scenes/paper/d_spheres_2lights.json" \
         "$root/scenes/paper/a_glass.json" "$root/scenes/paper/b_desk.json"; do
  out=$(valgrind --tool=callgrind --toggle-collect='locus::render_band*' \
        --callgrind-out-file="$tmp/cg" "$tmp/ipp" "$s" "$size" "$aa" 2>&1)
  px=$(echo "$out" | awk '/^pixels/ {print $2}')
  tr=$(echo "$out" | awk '/^pixels/ {print $4}')
  ir=$(echo "$out" | awk '/Collected/ {print $4}')
  echo "| $(basename "$s" .json) | $px | $tr | $ir | $((ir / px)) |"
done

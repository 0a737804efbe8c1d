#!/usr/bin/env bash
# check_scene.sh LOCUS SCENE WxH: renders SCENE with Locus (PNG, spp 1) and
# with the independent reference, and compares them (compare.py's limits).
set -euo pipefail
locus=$1 scene=$2 size=$3
here=$(cd "$(dirname "$0")" && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$locus" render "$scene" -o "$tmp/locus.png" --size "$size" --spp 1 --method raytrace
/usr/bin/python3 "$here/nff_ref.py" "$scene" --size "$size" -o "$tmp/ref.npy"
/usr/bin/python3 "$here/compare.py" "$tmp/ref.npy" "$tmp/locus.png" --tol 2/255 --max-bad-fraction 0.005

#!/usr/bin/env bash
# The main job: sets everything up, then renders an animation of an example
# scene on a local farm (an embedded coordinator and 2 workers on loopback)
# into out/.
set -euo pipefail
cd "$(dirname "$0")/../.."
bash deploy/local/build.sh
mkdir -p out
# 24 frames of a moving glass sphere and a turning mirror, on an embedded
# farm: a coordinator inside `locus` and 2 locus-worker processes.
build/bin/locus render scenes/anim/glass_and_mirror.json --frames 1-24 --workers 2 -o out/anim_####.png
echo "demo: frames written to out/"
ls -l out

#!/usr/bin/env bash
# The main job: sets everything up, then renders an animation of an example
# scene on a local farm (an embedded coordinator and 2 workers on loopback)
# into out/.
set -euo pipefail
cd "$(dirname "$0")/../.."
bash deploy/local/build.sh
mkdir -p out
# 24 frames of a moving glass sphere and a turning mirror, on an embedded
# farm: a coordinator inside `locus` and 2 locus-worker processes; then
# the coordinator makes them into a movie with ffmpeg (H.264, 24 fps).
# tests/movie/run.sh runs this same command and checks the movie.
build/bin/locus render scenes/anim/glass_and_mirror.json --frames 1-24 --workers 2 -o out/anim_####.png \
  --movie out/anim.mp4
echo "demo: frames and out/anim.mp4 written to out/"
ls -l out

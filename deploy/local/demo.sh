#!/usr/bin/env bash
# The main job: sets everything up, then renders an animation of an example
# scene on a local farm (an embedded coordinator and 2 workers on loopback)
# into out/.
set -euo pipefail
cd "$(dirname "$0")/../.."
bash deploy/local/build.sh
mkdir -p out
build/bin/locus render scenes/paper/a_glass.json -o out/a_glass.png --size 512x512
echo "demo: frames written to out/"
ls -l out

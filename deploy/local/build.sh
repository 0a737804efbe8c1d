#!/usr/bin/env bash
# Configures and builds Locus (Release) into build/; binaries in build/bin/.
set -euo pipefail
cd "$(dirname "$0")/../.."
bash deploy/local/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j "$(nproc)"

#!/usr/bin/env bash
# Makes the data directory of tests/data/store-v0.13/ with the binaries of
# release v0.13 (tests/data/store-v0.13/README.md): a coordinator on
# 127.0.0.1, one finished job and one left unfinished: its worker killed
# mid-job, then the coordinator stopped as an upgrade stops it (SIGTERM).
# Usage: make.sh BIN OUT   (BIN: v0.13's locus, locus-coordinator,
# locus-worker; OUT: a new directory, the data directory to keep).
set -euo pipefail
bin=$1
out=$2
repo=$(cd "$(dirname "$0")/../../.." && pwd)
work=$(mktemp -d)
trap 'kill -9 $(jobs -p) 2>/dev/null; rm -rf "$work"' EXIT
cd "$work"  # submit --wait fetches j0001's frames here

"$bin/locus-coordinator" --insecure --listen 127.0.0.1:0 --data "$out" --lease-ms 3000 \
  --heartbeat-ms 500 --drain-ms 0 >"$work/coordinator.out" 2>"$work/coordinator.log" &
coordinator=$!
for _ in $(seq 100); do
  port=$(sed -n 's/^listening on port //p' "$work/coordinator.out")
  [ -n "$port" ] && break
  sleep 0.1
done
farm=127.0.0.1:$port

# j0001: finished. Two PNG frames of 32x24, two bands each.
"$bin/locus-worker" --coordinator "$farm" --threads 1 --name fast:1 2>"$work/fast.log" &
fast=$!
"$bin/locus" submit "$repo/scenes/simple/spheres.json" --farm "$farm" -o "shot_####.png" \
  --size 32x24 --frames 1-2 --bands 2 --orbit 30 --wait >"$work/j0001.out"
kill -9 "$fast"
wait "$fast" 2>/dev/null || true

# j0002: unfinished. Two EXR frames of 40x30, three bands each, rendered by a
# worker that waits 500 ms before each band, killed (-9) once four bands
# are accepted (frame 1 written, one band of frame 2 accepted, the next
# leased); then the coordinator stops with SIGTERM, --drain-ms 0: the lease
# stays open in the store, the store is checkpointed and closed.
"$bin/locus" submit "$repo/scenes/anim/glass_and_mirror.json" --farm "$farm" \
  -o "anim_####.exr" --size 40x30 --frames 1-2 --bands 3 --aa 2 --priority 60 >"$work/j0002.out"
"$bin/locus-worker" --coordinator "$farm" --threads 1 --name slow:2 --test-slow-band-ms 500 \
  2>"$work/slow.log" &
slow=$!
for _ in $(seq 300); do
  done_bands=$(sqlite3 -readonly "$out/locus.db" \
    "SELECT COUNT(*) FROM bands WHERE job_id = 'j0002' AND done" 2>/dev/null || echo 0)
  [ "$done_bands" -ge 4 ] && break
  sleep 0.05
done
kill -9 "$slow"
wait "$slow" 2>/dev/null || true
kill -TERM "$coordinator"
wait "$coordinator"
# Closed cleanly: the store is in locus.db alone (its WAL checkpointed).
[ ! -s "$out/locus.db-wal" ] || { echo "the store's WAL was left non-empty" >&2; exit 1; }
rm -f "$out/coordinator.lock"
sqlite3 -readonly "$out/locus.db" \
  "SELECT id, state, (SELECT COUNT(*) FROM bands b WHERE b.job_id = id AND done),
          (SELECT COUNT(*) FROM frames f WHERE f.job_id = id) FROM jobs"
rm -f "$out/locus.db-shm" "$out/locus.db-wal"

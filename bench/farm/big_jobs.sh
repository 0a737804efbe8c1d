#!/usr/bin/env bash
# bench/farm/big_jobs.sh [BUILD_DIR]: big jobs at scale (issue #25, item 5).
# A coordinator (durable, as deployed), WORKERS simulated workers connected,
# then one job of FRAMES x BANDS bands (1,000,000 by default) submitted;
# prints the submit time, the time of `locus status` on it and of the job
# list, and the coordinator's peak RSS over SECONDS while every worker holds
# a lease and the other bands stay queued (locus-farm-scale --measure-queued).
#   WORKERS (1000) JOBS (1) FRAMES (10000) BANDS (100) ROWS (1) WIDTH (16)
#   DELAY_MS (60000: a lease outlives the sampling) SECONDS_SAMPLED (10)
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build}
bin=$build/bin
tmp=$(mktemp -d)
coord=
cleanup() {
  [ -n "$coord" ] && kill -9 "$coord" 2>/dev/null || true
  wait 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT
"$bin/locus-coordinator" --insecure --listen 127.0.0.1:0 --data "$tmp/data" \
  ${COORDINATOR_FLAGS:-} >"$tmp/coord.out" 2>"$tmp/coord.log" &
coord=$!
port=
for _ in $(seq 200); do
  port=$(sed -n 's/^listening on port //p' "$tmp/coord.out")
  [ -n "$port" ] && break
  sleep 0.05
done
[ -n "$port" ] || { echo "the coordinator did not start"; cat "$tmp/coord.log"; exit 1; }
"$bin/locus-farm-scale" --farm "127.0.0.1:$port" --data "$tmp/data" --coordinator-pid "$coord" \
  --scene "$root/scenes/simple/spheres.json" --workers "${WORKERS:-1000}" --jobs "${JOBS:-1}" \
  --frames "${FRAMES:-10000}" --bands "${BANDS:-100}" --rows "${ROWS:-1}" --width "${WIDTH:-16}" \
  --delay-ms "${DELAY_MS:-60000}" --measure-queued "${SECONDS_SAMPLED:-10}"
echo "store_bytes $(du -cb "$tmp/data"/locus.db* | tail -1 | cut -f1)"

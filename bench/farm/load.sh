#!/usr/bin/env bash
# bench/farm/load.sh [BUILD_DIR]: the farm under load on 127.0.0.1. A
# coordinator (fsync on, as deployed) and 2 workers; locus-farm-load's 50
# concurrent clients submit 200 jobs of 50 one-row bands (10,000 bands) and
# follow them to the end. Reports the coordinator's resident memory (sampled
# from /proc while the jobs run) and its dispatch latency (GetTask to lease,
# logged by the coordinator at shutdown), and writes
# bench/results/farm-load.md. CLIENTS, JOBS, BANDS override; RESULTS=0 skips
# the results file (the CTest smoke run does).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build}
bin=$build/bin
clients=${CLIENTS:-50} jobs=${JOBS:-200} bands=${BANDS:-50}
scene=$root/scenes/simple/spheres.json
tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT

"$bin/locus-coordinator" --insecure --listen 127.0.0.1:0 --data "$tmp/data" ${COORDINATOR_FLAGS:-} \
  >"$tmp/coord.out" 2>"$tmp/coord.log" &
coord=$!
pids+=($coord)
port=
for _ in $(seq 200); do
  port=$(sed -n 's/^listening on port //p' "$tmp/coord.out")
  [ -n "$port" ] && break
  sleep 0.05
done
[ -n "$port" ] || { echo "the coordinator did not start"; cat "$tmp/coord.log"; exit 1; }
farm=127.0.0.1:$port
for i in 1 2; do
  "$bin/locus-worker" --coordinator "$farm" --threads 1 2>>"$tmp/workers.log" &
  pids+=($!)
done
sleep 0.5

rc=0
"$bin/locus-farm-load" --farm "$farm" --scene "$scene" --clients "$clients" --jobs "$jobs" \
  --bands "$bands" --coordinator-pid "$coord" >"$tmp/load.out" 2>"$tmp/load.err" || rc=$?
kill -TERM "$coord"
wait "$coord" || true
cat "$tmp/load.out"
dispatch=$(sed -n 's/.*dispatch latency: \(.*\)/\1/p' "$tmp/coord.log" | tail -1)
echo "dispatch $dispatch"
if [ "$rc" -ne 0 ]; then
  echo "FAILED: not every job succeeded"
  head -20 "$tmp/load.err"
  exit 1
fi
get() { awk -v k="$1" '$1 == k {print $2}' "$tmp/load.out"; }
mib() { python3 -c "print(f'{$1 / 1024:.1f}')"; }

if [ "${RESULTS:-1}" != 0 ]; then
  results=$root/bench/results/farm-load.md
  {
    echo "# Farm under load"
    echo
    echo "Written by \`bench/farm/load.sh\` on $(nproc) cores ($(date -u +%Y-%m-%d)): a coordinator"
    echo "(job store with fsync on${COORDINATOR_FLAGS:+, flags \`$COORDINATOR_FLAGS\`}) and 2 workers on 127.0.0.1;"
    echo "$clients concurrent clients (one connection each) submit $jobs jobs of one $((64))x$bands frame in $bands"
    echo "one-row bands of scenes/simple/spheres.json, then follow each to its end."
    echo
    echo "| What | Figure |"
    echo "|---|---|"
    echo "| Jobs succeeded | $(get jobs_succeeded) of $jobs ($(get bands_total) bands) |"
    echo "| Wall time, first submit to last job done | $(get seconds) s ($(get bands_per_second) bands/s) |"
    echo "| Dispatch latency (GetTask to lease, in the coordinator) | $dispatch |"
    echo "| Submit latency, p50 / p99 | $(get submit_p50_ms) / $(get submit_p99_ms) ms |"
    echo "| Job latency (submit to done), p50 / p99 | $(get job_p50_s) / $(get job_p99_s) s |"
    echo "| Coordinator RSS before the first job | $(mib "$(get rss_start_kib)") MiB |"
    echo "| Coordinator RSS, highest sample while jobs ran | $(mib "$(get rss_max_kib)") MiB |"
    echo "| Coordinator RSS after the last job | $(mib "$(get rss_end_kib)") MiB |"
    echo
    echo "RSS as the jobs finish (jobs done: MiB):"
    awk '$1 == "rss_at_jobs_done" {printf "%s%s: %.1f", sep, $2, $3 / 1024; sep = ", "} END {print ""}' "$tmp/load.out"
  } | tee "$results"
fi

#!/usr/bin/env bash
# bench/farm/run.sh [BUILD_DIR]: the farm's figures, as a Markdown table in
# bench/results/farm.md (and on stdout).
#   - one frame on 1 worker and on 2 workers (each --threads 1), a hand-started
#     coordinator on 127.0.0.1; times are the coordinator's, submit to last
#     frame written (its "job ... succeeded in S s" log line);
#   - the coordinator's overhead per band and the bytes per band
#     (locus-farm-bench).
# SCENE, SIZE, SPP and BANDS override the frame (default: scenes/paper/a_glass.json
# at 512x512, spp 8: over 5 s on one core) and REPS the runs of each (3).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build}
bin=$build/bin
scene=${SCENE:-$root/scenes/paper/a_glass.json}
size=${SIZE:-512x512}
spp=${SPP:-8}
bands=${BANDS:-32}
tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT

# Secured as a real farm is (docs/farm.md "Security"): TLS, worker
# certificates and tokens, with throwaway certificates and tokens.
bash "$root/tests/tls/make_certs.sh" "$tmp/tls"
tls=$tmp/tls
head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$tmp/client.tokens"
head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \n' >"$tmp/worker.tokens"
"$bin/locus-coordinator" --listen 127.0.0.1:0 --data "$tmp/data" \
  --tls-cert "$tls/server.pem" --tls-key "$tls/server.key" --tls-ca "$tls/ca.pem" \
  --client-tokens "$tmp/client.tokens" --worker-tokens "$tmp/worker.tokens" \
  >"$tmp/coord.out" 2>"$tmp/coord.log" &
pids+=($!)
port=
for _ in $(seq 200); do
  port=$(sed -n 's/^listening on port //p' "$tmp/coord.out")
  [ -n "$port" ] && break
  sleep 0.05
done
farm=127.0.0.1:$port

# Seconds of the job run with N workers.
run_with() {
  local n=$1 ws=() i
  for i in $(seq "$n"); do
    "$bin/locus-worker" --coordinator "$farm" --threads 1 --token-file "$tmp/worker.tokens" \
      --tls-ca "$tls/ca.pem" --tls-cert "$tls/client.pem" --tls-key "$tls/client.key" 2>>"$tmp/workers.log" &
    ws+=($!)
  done
  sleep 0.5
  local job
  job=$("$bin/locus" submit "$scene" --farm "$farm" --size "$size" --method raytrace --spp "$spp" --bands "$bands" \
    --tls-ca "$tls/ca.pem" --token-file "$tmp/client.tokens" -o "$tmp/out_$n.png" --wait 2>/dev/null | head -1)
  kill "${ws[@]}"
  wait "${ws[@]}" 2>/dev/null || true
  sed -n "s/.*job $job succeeded in \([0-9.]*\) s.*/\1/p" "$tmp/coord.log"
}
# The machine may be shared: take the best of REPS runs of each.
reps=${REPS:-3}
best() {
  local n=$1 best= t
  for _ in $(seq "$reps"); do
    t=$(run_with "$n")
    best=$(python3 -c "print(min(x for x in [$t, ${best:-$t}]))")
  done
  echo "$best"
}
# Other runnable processes now (the load average lags by a minute): the
# mean of procs_running over a second, less this script's own sampler.
busy=$(for _ in 1 2 3 4 5; do awk '/^procs_running/ {print $2 - 1}' /proc/stat; sleep 0.2; done |
  awk '{s += $1} END {printf "%.1f", s / NR}')
t1=$(best 1)
t2=$(best 2)
cmp -s "$tmp/out_1.png" "$tmp/out_2.png" && same=yes || same=NO
ratio=$(python3 -c "print(f'{$t1 / $t2:.2f}')")

bench=$("$bin/locus-farm-bench")
get() { echo "$bench" | awk -v k="$1" '$1 == k {print $2}'; }

results=$root/bench/results/farm.md
mkdir -p "$(dirname "$results")"
{
  echo "# Farm figures"
  echo
  echo "Written by \`bench/farm/run.sh\` on $(nproc) cores ($(date -u +%Y-%m-%d)). Coordinator and"
  echo "workers on 127.0.0.1; each worker renders with one thread; best of $reps runs each ($busy"
  echo "other runnable processes on average just before the runs)."
  echo
  echo "| What | Figure |"
  echo "|---|---|"
  echo "| Frame: $(basename "$scene") ${size}, spp $spp, $bands bands | |"
  echo "| 1 worker | ${t1} s |"
  echo "| 2 workers | ${t2} s |"
  echo "| Speed-up, 2 workers over 1 | **${ratio}x** (frames identical: $same) |"
  echo "| Coordinator overhead per band, no network (dispatch, band file written and fsynced, stitch; $(get logic_bands) bands of 64x1) | $(get logic_us_per_band) us |"
  echo "| Per band over gRPC on loopback (GetTask + CompleteBand + dispatch + stitch, no rendering) | $(get grpc_us_per_band) us |"
  echo "| Bytes of a band's lease (coordinator to worker) | $(get bytes_lease) B |"
  echo "| Bytes of a band result, 64 x 1 pixels | $(get bytes_result_64x1) B |"
  echo "| Bytes of a band result, 640 x 30 pixels (640x480 in 16 bands) | $(get bytes_result_640x30) B |"
  echo "| Bytes of a band result, 1920 x 68 pixels (1080p in 16 bands) | $(get bytes_result_1920x68) B |"
  echo "| Bytes of the scene a_glass.json, sent once per worker per scene | $(get bytes_scene_a_glass) B |"
  echo
  echo "A band's result is 12 bytes per pixel (3 linear floats, packed) plus about 30 bytes of"
  echo "ids and counters."
  if python3 -c "import sys; sys.exit(0 if $busy >= 1.0 else 1)"; then
    echo
    echo "**Warning**: other work was running ($busy runnable processes on $(nproc) cores), so the"
    echo "workers competed for cores and the speed-up understates the farm's. Run again on an idle"
    echo "machine."
  fi
} | tee "$results"

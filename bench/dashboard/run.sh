#!/usr/bin/env bash
# bench/dashboard/run.sh [BUILD_DIR]: what open dashboards cost the farm's
# dispatch (issue #24). A coordinator (fsync on, as deployed, with --http)
# and 2 workers on 127.0.0.1 render a job of 2,400 one-row bands, with no
# dashboard open and with 200 (locus-dashboard-watchers: each polls
# /api/v1/farm with its cursor once a second and, when the farm changed,
# the job, as the job page does). Side by side in ROUNDS rounds (default 3),
# best of each: bands per second end to end, and the coordinator's CPU
# seconds per band (from /proc). Writes bench/results/dashboard.md
# (RESULTS=0: not). WATCHERS overrides 200.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build}
bin=$build/bin
rounds=${ROUNDS:-3} watchers=${WATCHERS:-200}
tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT
token=bench-$RANDOM$RANDOM$RANDOM
echo "bench $token" >"$tmp/clients"
echo "worker-$RANDOM$RANDOM$RANDOM" >"$tmp/workers"
echo "$token" >"$tmp/token"
chmod 600 "$tmp/clients" "$tmp/workers" "$tmp/token"
"$bin/locus-coordinator" --insecure --listen 127.0.0.1:0 --http 127.0.0.1:0 --http-rate 100000 \
  --data "$tmp/data" --client-tokens "$tmp/clients" --worker-tokens "$tmp/workers" \
  >"$tmp/coord.out" 2>"$tmp/coord.log" &
coord=$!
pids+=($coord)
for _ in $(seq 200); do
  grep -q "dashboard on port" "$tmp/coord.out" 2>/dev/null && break
  sleep 0.05
done
port=$(sed -n 's/^listening on port //p' "$tmp/coord.out")
http=$(sed -n 's/^dashboard on port //p' "$tmp/coord.out")
[ -n "$port" ] && [ -n "$http" ] || { echo "the coordinator did not start"; cat "$tmp/coord.log"; exit 1; }
farm=127.0.0.1:$port
for i in 1 2; do
  "$bin/locus-worker" --coordinator "$farm" --token-file "$tmp/workers" --threads 1 \
    2>>"$tmp/workers.log" &
  pids+=($!)
done
sleep 0.5
cpu() { awk '{print $14 + $15}' "/proc/$1/stat"; }  # clock ticks
hz=$(getconf CLK_TCK)
# run WATCHERS N: job number N (jobs are numbered in submission order);
# prints "bands_per_second cpu_ms_per_band"
run() {
  local w=$1 jobs=$2 wp= t0 t1 c0 c1 id bands=2400
  id=$(printf 'j%04d' "$jobs")
  if [ "$w" -gt 0 ]; then
    "$bin/locus-dashboard-watchers" --http "127.0.0.1:$http" --token "$token" --job "$id" \
      --watchers "$w" --seconds 600 >"$tmp/watchers-$jobs.out" 2>&1 &
    wp=$!
    pids+=($wp)
    sleep 2  # every watcher has polled once
  fi
  c0=$(cpu $coord)
  t0=$(date +%s.%N)
  got=$("$bin/locus" submit "$root/scenes/simple/spheres.json" --size 32x600 --bands 600 \
    --frames 1-4 --method raytrace -o "b$jobs/f_####.png" --farm "$farm" --token-file "$tmp/token")
  [ "$got" = "$id" ] || { echo "job id $got, expected $id"; exit 1; }
  "$bin/locus" watch "$id" --farm "$farm" --token-file "$tmp/token" >/dev/null 2>&1
  t1=$(date +%s.%N)
  c1=$(cpu $coord)
  if [ -n "$wp" ]; then
    kill -TERM "$wp"
    wait "$wp" || { echo "watchers reported errors:" $(tr "\n" " " <"$tmp/watchers-$jobs.out") >&2; exit 1; }
  fi
  python3 -c "print(f'{$bands / ($t1 - $t0):.1f} {1000 * ($c1 - $c0) / $hz / $bands:.4f}')"
}
echo "round  watchers  bands/s  coordinator CPU ms/band"
# A first job warms the store and the workers' scene cache (not counted);
# then the order alternates (none first, then 200 first) so that neither
# always meets the larger store.
n=1
run 0 1 >/dev/null
for r in $(seq "$rounds"); do
  order="0 $watchers"
  [ $((r % 2)) -eq 0 ] && order="$watchers 0"
  for w in $order; do
    n=$((n + 1))
    read -r bps cpb < <(run "$w" "$n")
    echo "$r      $w       $bps   $cpb"
    echo "$w $bps $cpb" >>"$tmp/rows"
  done
done
summary=$(python3 - "$tmp/rows" "$watchers" <<'PY'
import sys
rows = [l.split() for l in open(sys.argv[1])]
w = sys.argv[2]
best = lambda k: max(float(r[1]) for r in rows if r[0] == k)
cpu = lambda k: min(float(r[2]) for r in rows if r[0] == k)
b0, bw, c0, cw = best("0"), best(w), cpu("0"), cpu(w)
print(f"best bands/s: {b0:.1f} with none, {bw:.1f} with {w} watchers: ratio {bw / b0:.3f}")
print(f"least coordinator CPU per band: {c0:.4f} ms with none, {cw:.4f} ms with {w}: "
      f"ratio {cw / c0:.3f}")
print("PASS" if bw / b0 >= 0.90 else "FAIL", f"(within 10%: {bw / b0 >= 0.90})")
PY
)
echo "$summary"
requests=$(awk '$1 == "requests" {s += $2} END {print s}' "$tmp"/watchers-*.out)
echo "watchers' requests over the rounds: $requests"
if [ "${RESULTS:-1}" != 0 ]; then
  {
    echo "# Open dashboards against dispatch"
    echo
    echo "\`bench/dashboard/run.sh\`, $(date -u +%Y-%m-%d), $(nproc) cores: a coordinator (fsync on,"
    echo "\`--http\`) and 2 workers on 127.0.0.1, a job of 2,400 one-row bands (spheres.json,"
    echo "32x600, 4 frames, ray tracer), rendered with no dashboard open and with $watchers"
    echo "(each polls \`/api/v1/farm?since=V\` once a second, and the job when the farm"
    echo "changed). A warm-up job, then $rounds rounds side by side, the order alternating; best of each. The watchers run on the same"
    echo "2 cores as the farm, so their own CPU is in the figure too."
    echo
    echo '```'
    column -t "$tmp/rows" | sed 's/^/watchers bands\/s cpu_ms_per_band: /'
    echo "$summary"
    echo "watchers' requests over the rounds: $requests"
    echo '```'
  } >"$root/bench/results/dashboard.md"
fi
grep -q '^PASS' <<<"$summary"

#!/usr/bin/env bash
# tests/faults/run.sh [BINDIR]: the farm across three hosts while faults are
# injected (plaintext with --insecure: security is tested by
# tests/wire/farm_security_test.cpp; here only faults). The hosts are network
# namespaces made here: one coordinator
# host (a bridge, 10.77.0.1) and two worker hosts (10.77.0.2, 10.77.0.3)
# joined to it by veth pairs. Every address is inside those namespaces;
# nothing is sent anywhere else.
#
# Scenarios, each a job of 6 frames x 6 bands (workers play 150 ms per band
# with the test-only --test-slow-band-ms, so that faults land mid-job):
#   worker-sigkill     SIGKILL of a worker holding a band; a new one starts
#   link-cut           a worker's link down for twice the lease, then up
#   coordinator-kill   SIGKILL of the coordinator, restart on the same --data;
#                      the client's `submit --wait` and a new `watch` re-attach
#   slow-worker        one worker 20x slower: its bands are speculated
#   worker-sigterm     SIGTERM of a worker mid-band: it finishes or hands back
#   combined           link cut, coordinator SIGKILL during it, restart,
#                      link up, worker SIGKILL
# Every job must end with all frames present and identical to a clean
# single-process render (`locus render --workers 0`, compared by idiff with
# max error 0), and every band completed exactly once (the job store's
# bands.completions, read with sqlite3). One line per scenario; exit 0 only
# if all pass. Namespaces that cannot be made (not root, no `ip`) fail the
# test with a message: in CI a service a test cannot start is a failure,
# never a skip.
set -uo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
bin=$(cd "${1:-$root/build/bin}" && pwd)

cannot_run() {
  echo "FAILED: fault tests need network namespaces: $1"
  exit 1
}
[ "$(id -u)" -eq 0 ] || cannot_run "not root"
command -v ip >/dev/null || cannot_run "no ip (apt-get install iproute2)"
for tool in sqlite3 idiff; do
  command -v $tool >/dev/null || { echo "FAILED: $tool is missing (deploy/local/install-deps.sh)"; exit 1; }
done

tag=lf$$
C=${tag}c A=${tag}a B=${tag}b
tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null; done
  wait 2>/dev/null
  for ns in $C $A $B; do ip netns del "$ns" 2>/dev/null; done
  if [ -n "${KEEP:-}" ]; then echo "logs kept in $tmp"; else rm -rf "$tmp"; fi
}
trap cleanup EXIT
trap 'exit 130' INT TERM

ip netns add $C 2>/dev/null || cannot_run "ip netns add failed (no CAP_SYS_ADMIN?)"
ip netns add $A && ip netns add $B || cannot_run "ip netns add failed"
set -e
for ns in $C $A $B; do ip -n $ns link set lo up; done
ip -n $C link add br0 type bridge
ip -n $C addr add 10.77.0.1/24 dev br0
ip -n $C link set br0 up
n=2
for ns in $A $B; do
  v=v${ns: -1}  # va / vb: the coordinator's end of this host's link
  ip -n $C link add $v type veth peer name eth0 netns $ns
  ip -n $C link set $v master br0
  ip -n $C link set $v up
  ip -n $ns addr add 10.77.0.$n/24 dev eth0
  ip -n $ns link set eth0 up
  n=$((n + 1))
done
set +e

farm=10.77.0.1:7077
data=$tmp/data
lease_ms=2000
scene=$root/scenes/paper/a_glass.json
job_args=(--size 64x48 --frames 1-6 --orbit 30 --bands 6)
frames=6 bands_total=36
in_c() { ip netns exec $C "$@"; }
locus() { in_c "$bin/locus" "$@" --farm $farm --insecure; }

coord_pid=
start_coordinator() {
  # Not through a shell function: $! must be the coordinator itself (ip
  # netns exec execs it).
  ip netns exec $C "$bin/locus-coordinator" --insecure --listen $farm --data "$data" --lease-ms $lease_ms --heartbeat-ms 400 \
    >"$tmp/coord.out" 2>>"$tmp/coord.log" &
  coord_pid=$!
  pids+=($coord_pid)
  for _ in $(seq 200); do
    grep -q "^listening on port" "$tmp/coord.out" 2>/dev/null && return 0
    sleep 0.05
  done
  echo "coordinator did not start"; return 1
}
# start_worker NS [MS_PER_BAND]: sets $last_worker.
last_worker=
start_worker() {
  ip netns exec "$1" "$bin/locus-worker" --insecure --coordinator $farm --poll-ms 1000 --test-slow-band-ms "${2:-150}" \
    2>>"$tmp/worker-$1.log" &
  last_worker=$!
  pids+=($last_worker)
}
# Progress from the job store (WAL: readers never block the coordinator);
# cheaper than starting `locus status` many times a second.
bands_done() { sql "SELECT COUNT(*) FROM bands WHERE job_id = '$1' AND done = 1" 2>/dev/null; }
wait_bands() {  # wait_bands JOB N: until N bands are done (10 s at most)
  for _ in $(seq 200); do
    [ "$(bands_done "$1")" -ge "$2" ] 2>/dev/null && return 0
    sleep 0.05
  done
  return 1
}
sql() { sqlite3 -readonly "$data/locus.db" "$1"; }
# holding_band PID: whether that worker holds a lease now (its name is host:pid).
holding_band() { [ -n "$(sql "SELECT 1 FROM leases WHERE worker_name LIKE '%:$1' LIMIT 1")" ]; }
. "$(dirname "${BASH_SOURCE[0]}")/../farm_lib.sh"  # signal_busy

# The reference: one clean single-process render.
"$bin/locus" render "$scene" "${job_args[@]}" --workers 0 -o "$tmp/ref/f_####.exr" 2>"$tmp/ref.log" ||
  { echo "FAILED: reference render"; cat "$tmp/ref.log"; exit 1; }

passed=0 failed=0
# check NAME JOB OUTDIR SUBMIT_PID: the job's end, its frames, its bands.
check() {
  local name=$1 job=$2 out=$3 submit=$4 why=
  wait "$submit" || why="submit --wait failed (see $name.log)"
  if [ -z "$why" ]; then
    local f
    for f in $(seq 1 $frames); do
      local file; file=$(printf "%s/f_%04d.exr" "$out" "$f")
      [ -f "$file" ] || { why="frame $f missing"; break; }
      idiff -fail 0 -warn 0 "$tmp/ref/$(basename "$file")" "$file" >"$tmp/idiff.out" 2>&1 ||
        { why="frame $f differs from the single-process render: $(grep -m1 'Max error' "$tmp/idiff.out")"; break; }
    done
  fi
  local counts
  counts=$(sql "SELECT COUNT(*), COALESCE(SUM(completions = 1), 0), COALESCE(MAX(completions), 0)
                FROM bands WHERE job_id = '$job' AND done = 1")
  if [ -z "$why" ] && [ "$counts" != "$bands_total|$bands_total|1" ]; then
    why="bands done|done once|max completions = $counts, expected $bands_total|$bands_total|1"
  fi
  if [ -z "$why" ] && [ -n "${5:-}" ]; then why=$(eval "$5"); fi
  local secs=$(( $(date +%s) - started ))
  if [ -z "$why" ]; then
    echo "ok: $name, ${secs} s ($job: $frames frames identical to the single-process render, $bands_total bands each counted once${6:+; $6})"
    passed=$((passed + 1))
  else
    echo "FAILED: $name ($job, ${secs} s): $why"
    failed=$((failed + 1))
  fi
}
# submit NAME: starts `locus submit --wait` in the background; sets $job, $out, $submit.
submit() {
  started=$(date +%s)
  out=$tmp/out-$1
  locus submit "$scene" "${job_args[@]}" -o "$out/f_####.exr" --wait >"$tmp/$1.out" 2>"$tmp/$1.log" &
  submit=$!
  pids+=($submit)
  job=
  for _ in $(seq 200); do
    job=$(head -1 "$tmp/$1.out" 2>/dev/null)
    [ -n "$job" ] && return 0
    sleep 0.05
  done
  return 1
}
# Charged (failed, lapsed, silent) and other outcomes of a job's leases.
outcomes() { sql "SELECT COUNT(*) FROM attempts WHERE job_id = '$1' AND outcome IN ($2)"; }

start_coordinator || exit 1
start_worker $A; wa=$last_worker
start_worker $B; wb=$last_worker
# Both worker hosts reach the coordinator host across the veth links.
for _ in $(seq 100); do
  [ "$(locus workers 2>/dev/null | grep -c ' 10\.77\.0\.\| :')" -ge 0 ] &&
    [ "$(locus workers 2>/dev/null | tail -n +2 | wc -l)" -ge 2 ] && break
  sleep 0.1
done
[ "$(locus workers 2>/dev/null | tail -n +2 | wc -l)" -ge 2 ] ||
  { echo "FAILED: the workers cannot reach the coordinator across the namespaces"; cat "$tmp"/worker-*.log; exit 1; }

# ---- worker-sigkill
submit worker-sigkill
wait_bands "$job" 6
signal_busy KILL "$wa" "$wb"
wait "$victim" 2>/dev/null  # reaped here, quietly
if [ "$victim" = "$wa" ]; then start_worker $A; wa=$last_worker; else start_worker $B; wb=$last_worker; fi
check worker-sigkill "$job" "$out" "$submit" \
  '[ "$(outcomes "$job" "'"'lapsed','silent'"'")" -ge 1 ] || echo "no lease lapsed: the kill hit no band"' \
  "the killed worker's band leased again"

# ---- link-cut: longer than the lease
submit link-cut
wait_bands "$job" 6
ip -n $C link set vb down
sleep $((2 * lease_ms / 1000))
ip -n $C link set vb up
check link-cut "$job" "$out" "$submit" \
  '[ "$(outcomes "$job" "'"'lapsed','silent'"'")" -ge 1 ] || echo "no lease of the cut worker lapsed"' \
  "link down $((2 * lease_ms / 1000)) s, lease ${lease_ms} ms"

# ---- coordinator-kill: SIGKILL and restart on the same data
submit coordinator-kill
wait_bands "$job" 8
kill -9 "$coord_pid"
wait "$coord_pid" 2>/dev/null
sleep 1
start_coordinator || exit 1
locus watch "$job" >"$tmp/watch.out" 2>&1
watch_rc=$?
check coordinator-kill "$job" "$out" "$submit" \
  '[ "$watch_rc" -eq 0 ] || { echo "locus watch after the restart: exit $watch_rc: $(tail -1 "$tmp/watch.out")"; } ' \
  "resumed from the store; submit --wait and a new watch re-attached"

# ---- slow-worker: one worker 20x slower; its bands are speculated
kill -TERM "$wb"; wait "$wb" 2>/dev/null
start_worker $B 3000; wb=$last_worker
submit slow-worker
check slow-worker "$job" "$out" "$submit" \
  '[ "$(sql "SELECT COALESCE(SUM(speculative), 0) FROM attempts WHERE job_id = '"'"'$job'"'"'")" -ge 1 ] || echo "no band was speculated"' \
  "the slow worker's band leased again speculatively; the first result won"
kill -TERM "$wb"; wait "$wb" 2>/dev/null
start_worker $B; wb=$last_worker

# ---- worker-sigterm: finishes its band or hands it back, then exits 0
submit worker-sigterm
wait_bands "$job" 6
signal_busy TERM "$wa" "$wb"
wait "$victim"
term_rc=$?
if [ "$victim" = "$wa" ]; then start_worker $A; wa=$last_worker; else start_worker $B; wb=$last_worker; fi
check worker-sigterm "$job" "$out" "$submit" \
  '[ "$term_rc" -eq 0 ] || echo "the worker exited with $term_rc after SIGTERM"' \
  "the worker exited 0 after finishing or handing back its band"

# ---- combined: link cut; coordinator killed during it; restart; link up; worker killed
submit combined
wait_bands "$job" 6
ip -n $C link set va down
sleep 1
kill -9 "$coord_pid"; wait "$coord_pid" 2>/dev/null
sleep 0.5
start_coordinator || exit 1
sleep 2
ip -n $C link set va up
wait_bands "$job" 24
signal_busy KILL "$wb" "$wa"
wait "$victim" 2>/dev/null
if [ "$victim" = "$wa" ]; then start_worker $A; wa=$last_worker; else start_worker $B; wb=$last_worker; fi
check combined "$job" "$out" "$submit"

kill -TERM "$wa" "$wb" "$coord_pid" 2>/dev/null
wait 2>/dev/null
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]

#!/usr/bin/env bash
# bench/farm/scale.sh [BUILD_DIR]: the coordinator with many simulated
# workers on 127.0.0.1 (issue #25). Starts a coordinator (durable, as
# deployed, unless COORDINATOR_FLAGS says otherwise) and runs
# locus-farm-scale against it; prints its "key value" lines.
#   WORKERS (1000) JOBS (20) FRAMES (50) BANDS (64, of ROWS=4 rows of WIDTH=256)
#   DELAY_MS (0) DELAY_SIGMA (0) DIE STALL LATE (0) TIMEOUT (600)
#   KEEP=1 keeps the data directory (its path is printed).
#   SCALE_FLAGS: more flags for locus-farm-scale (bench/farm/big_jobs.sh).
#   RESTART_AFTER=S: kill -9 the coordinator S seconds into the run and
#   start it again on the same port and data (a soak; the harness counts
#   calls failed meanwhile apart, --outage-ok; no CPU or sync figures).
#   REVIVE_MS: DIE workers come back after this long, and die again.
#   REPORT=FILE: writes the run as Markdown to FILE (the commit, the
#   machine's load, the settings, every figure); issue #25's target lines
#   are judged once, by targets.sh, which writes
#   bench/results/farm-scale.md around such a report.
#   FIGURES=FILE: copies the run's "key value" lines to FILE
#   (bench/farm/targets.sh).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$root/build}
bin=$build/bin
tmp=$(mktemp -d)
load_start=$(cut -d' ' -f1-3 /proc/loadavg)
coord=
cleanup() {
  [ -n "$coord" ] && kill -9 "$coord" 2>/dev/null || true
  [ -f "$tmp/coord2.pid" ] && kill -9 "$(cat "$tmp/coord2.pid")" 2>/dev/null || true
  wait 2>/dev/null || true
  if [ "${KEEP:-0}" = 1 ]; then echo "data_dir $tmp"; else rm -rf "$tmp"; fi
}
trap cleanup EXIT
# The coordinator counts its syncs itself (server/syncs.h: its own fsync and
# fdatasync calls, and SQLite's through a counting VFS) and logs them when
# it stops: coordinator_syncs. SYNCS=strace counts the same calls with
# strace as well (coordinator_syncs_strace), a cross-check that slows the
# coordinator (hundreds of workers dropped and re-registered at 1,000).
syncs=${SYNCS:-}
[ -n "${RESTART_AFTER:-}" ] && syncs=
if [ "$syncs" = strace ]; then
  strace -f --seccomp-bpf -c -e trace=fsync,fdatasync -o "$tmp/syncs.txt" \
    "$bin/locus-coordinator" --insecure --listen 127.0.0.1:0 --data "$tmp/data" \
    ${COORDINATOR_FLAGS:-} >"$tmp/coord.out" 2>"$tmp/coord.log" &
  tracer=$!
  for _ in $(seq 100); do
    coord=$(pgrep -P "$tracer" || true)
    [ -n "$coord" ] && break
    sleep 0.05
  done
else
  "$bin/locus-coordinator" --insecure --listen 127.0.0.1:0 --data "$tmp/data" \
    ${COORDINATOR_FLAGS:-} >"$tmp/coord.out" 2>"$tmp/coord.log" &
  coord=$!
fi
port=
for _ in $(seq 200); do
  port=$(sed -n 's/^listening on port //p' "$tmp/coord.out")
  [ -n "$port" ] && break
  sleep 0.05
done
[ -n "$port" ] || { echo "the coordinator did not start"; cat "$tmp/coord.log"; exit 1; }
pid_flag=(--coordinator-pid "$coord")
restarter=
if [ -n "${RESTART_AFTER:-}" ]; then
  pid_flag=(--outage-ok)
  (
    sleep "$RESTART_AFTER"
    kill -9 "$coord"
    echo "restart: coordinator $coord killed at $(date +%T)" >&2
    sleep 1
    "$bin/locus-coordinator" --insecure --listen "127.0.0.1:$port" --data "$tmp/data" \
      ${COORDINATOR_FLAGS:-} >>"$tmp/coord2.out" 2>>"$tmp/coord2.log" &
    echo $! >"$tmp/coord2.pid"
    echo "restart: coordinator $! started at $(date +%T)" >&2
    wait
  ) &
  restarter=$!
fi
revive=()
[ -n "${REVIVE_MS:-}" ] && revive=(--revive-ms "$REVIVE_MS")
set +e  # the harness's status is kept, not the end of this script
"$bin/locus-farm-scale" --farm "127.0.0.1:$port" --data "$tmp/data" "${pid_flag[@]}" "${revive[@]}" \
  --scene "$root/scenes/simple/spheres.json" --workers "${WORKERS:-1000}" --jobs "${JOBS:-20}" \
  --frames "${FRAMES:-50}" --bands "${BANDS:-64}" --rows "${ROWS:-4}" --width "${WIDTH:-256}" \
  --delay-ms "${DELAY_MS:-0}" --delay-sigma "${DELAY_SIGMA:-0}" --die "${DIE:-0}" \
  --stall "${STALL:-0}" --late "${LATE:-0}" --timeout "${TIMEOUT:-600}" ${SCALE_FLAGS:-} |
  tee "$tmp/figures.txt"
status=${PIPESTATUS[0]}
set -e
if [ "$syncs" = strace ]; then
  # A clean stop, so that strace writes its count.
  kill -TERM "$coord" 2>/dev/null || true
  wait "$tracer" 2>/dev/null || true
  coord=
  n=$(awk '$NF == "fsync" || $NF == "fdatasync" { s += $4 } END { print s + 0 }' "$tmp/syncs.txt")
  echo "coordinator_syncs_strace $n" | tee -a "$tmp/figures.txt"
fi
# The coordinator's own dispatch latency (a band available to a waiting
# worker, to its lease), logged when it stops; the workers' figures above
# include waiting for a band, which is most of a saturated farm's time.
if [ -n "$coord" ]; then kill -TERM "$coord" 2>/dev/null || true; wait "$coord" 2>/dev/null || true; coord=; fi
if [ -f "$tmp/coord2.pid" ]; then
  kill -TERM "$(cat "$tmp/coord2.pid")" 2>/dev/null || true
  wait "$restarter" 2>/dev/null || true
  cat "$tmp/coord2.log" >>"$tmp/coord.log"
fi
# Its syncs, counted by itself (none with a restart: two processes).
[ -z "${RESTART_AFTER:-}" ] &&
  sed -n 's/.*syncs: \([0-9]*\) (the store.s \([0-9]*\), the coordinator.s files. \([0-9]*\)).*/coordinator_syncs \1\ncoordinator_syncs_store \2\ncoordinator_syncs_files \3/p' "$tmp/coord.log" | tee -a "$tmp/figures.txt"
sed -n 's/.*dispatch latency: \([0-9]*\) bands, p50 \([0-9]*\) us, p99 \([0-9]*\) us, max \([0-9]*\) us.*/coordinator_dispatch_us_p50 \2\ncoordinator_dispatch_us_p99 \3\ncoordinator_dispatch_us_max \4/p' "$tmp/coord.log" | tee -a "$tmp/figures.txt"
[ -n "${FIGURES:-}" ] && cp "$tmp/figures.txt" "$FIGURES"
if [ -n "${REPORT:-}" ]; then
  {
    echo "# bench/farm/scale.sh: one run"
    echo
    echo "Written by the script itself (REPORT=...) at the end of the run, $(date -u '+%Y-%m-%d %H:%M UTC'),"
    echo "commit $(git -C "$root" rev-parse --short HEAD)$(git -C "$root" diff --quiet HEAD -- server common proto worker bench/farm || echo ' (with uncommitted changes)'),"
    echo "on $(nproc) cores; load average (1, 5, 15 min) $load_start at the start, $(cut -d' ' -f1-3 /proc/loadavg) at the end."
    echo
    echo "Settings: WORKERS=${WORKERS:-1000} JOBS=${JOBS:-20} FRAMES=${FRAMES:-50} BANDS=${BANDS:-64}" \
      "ROWS=${ROWS:-4} WIDTH=${WIDTH:-256} DELAY_MS=${DELAY_MS:-0} DIE=${DIE:-0} STALL=${STALL:-0}" \
      "LATE=${LATE:-0} SCALE_FLAGS='${SCALE_FLAGS:-}' COORDINATOR_FLAGS='${COORDINATOR_FLAGS:-}'." \
      "The harness's exit status: $status (0: every band accepted once, every frame identical to its reference)."
    echo
    echo "## Every figure"
    echo
    echo "| Figure | Value |"
    echo "|---|---|"
    awk 'NF == 2 && $1 ~ /^[a-z_0-9]+$/ { printf "| %s | %s |\n", $1, $2 }' "$tmp/figures.txt"
  } >"$REPORT"
  echo "report written: $REPORT"
fi
if [ "$status" != 0 ]; then
  echo "--- coordinator log (last 40 lines)"
  tail -40 "$tmp/coord.log"
fi
exit "$status"

#!/usr/bin/env bash
# tests/faults/disk_full.sh [BINDIR]: the coordinator's data directory fills
# up mid-job (issue #25 item 6; docs/farm.md "A full disk"). The data
# directory is a 32 MiB tmpfs mounted in a mount namespace of this test's own
# (unshare -m: nobody else sees it); the farm is one coordinator and two
# workers on 127.0.0.1. A job of 8 frames x 4 bands runs; once some bands
# are done the tmpfs is filled to the last byte. Then:
#   - a new job is refused with an error that names the data directory;
#   - the coordinator stays up and answers `locus status`;
#   - no band acknowledged before is lost (the store's done bands only grow);
# the filler is removed, and then, with nobody's help:
#   - the job ends with every frame identical to a single-process render
#     (idiff, max error 0) and every band completed exactly once;
#   - a new job is accepted and succeeds.
# Needs root (a mount namespace, a tmpfs): without it the test fails, it
# never skips.
set -uo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
bin=$(cd "${1:-$root/build/bin}" && pwd)

if [ -z "${LOCUS_DISK_FULL_NS:-}" ]; then
  [ "$(id -u)" -eq 0 ] || { echo "FAILED: the disk-full test mounts a tmpfs: needs root"; exit 1; }
  for tool in unshare sqlite3 idiff; do
    command -v $tool >/dev/null || { echo "FAILED: $tool is missing (deploy/local/install-deps.sh)"; exit 1; }
  done
  exec env LOCUS_DISK_FULL_NS=1 unshare --mount --propagation private "$0" "$bin"
fi

tmp=$(mktemp -d)
cd "$tmp"  # `submit --wait` fetches the frames here
data=$tmp/data
mkdir -p "$data"
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null; done
  wait 2>/dev/null
  umount "$data" 2>/dev/null
  if [ -n "${KEEP:-}" ]; then echo "logs kept in $tmp"; else rm -rf "$tmp"; fi
}
trap cleanup EXIT
mount -t tmpfs -o size=32m locus-disk-full "$data" || { echo "FAILED: cannot mount a tmpfs"; exit 1; }

fail() {
  echo "FAILED: $*"
  echo "--- coordinator log (last 30 lines)"
  tail -30 "$tmp/coord.log"
  exit 1
}
ok() { echo "ok: $*"; }

"$bin/locus-coordinator" --insecure --listen 127.0.0.1:0 --data "$data" --min-free-mb 2 \
  --lease-ms 2000 --heartbeat-ms 400 >"$tmp/coord.out" 2>"$tmp/coord.log" &
pids+=($!)
coord=$!
port=
for _ in $(seq 200); do
  port=$(sed -n 's/^listening on port \([0-9]*\)$/\1/p' "$tmp/coord.out" 2>/dev/null)
  [ -n "$port" ] && break
  sleep 0.05
done
[ -n "$port" ] || fail "the coordinator did not start"
farm=127.0.0.1:$port
locus() { "$bin/locus" "$@" --farm "$farm" --insecure; }
for w in 1 2; do
  "$bin/locus-worker" --insecure --coordinator "$farm" --poll-ms 500 --test-slow-band-ms 100 \
    2>"$tmp/worker-$w.log" &
  pids+=($!)
done

scene=$root/scenes/paper/a_glass.json
job_args=(--size 64x48 --frames 1-8 --orbit 30 --bands 4)
frames=8 bands_total=32
"$bin/locus" render "$scene" "${job_args[@]}" --workers 0 -o "$tmp/ref/f_####.exr" 2>"$tmp/ref.log" ||
  fail "the reference render: $(tail -3 "$tmp/ref.log")"

sql() { sqlite3 -readonly "$data/locus.db" "$1" 2>/dev/null; }
done_bands() { sql "SELECT COUNT(*) FROM bands WHERE job_id = '$1' AND done = 1"; }

locus submit "$scene" "${job_args[@]}" -o "f_####.exr" --wait >"$tmp/submit.out" 2>"$tmp/submit.log" &
submit=$!
pids+=($submit)
job=
for _ in $(seq 200); do
  job=$(grep -o 'j[0-9]\{4,\}' "$tmp/submit.out" "$tmp/submit.log" 2>/dev/null | head -1 | sed 's/.*://')
  [ -n "$job" ] && [ "$(done_bands "$job")" -ge 4 ] 2>/dev/null && break
  sleep 0.05
done
[ -n "$job" ] && [ "$(done_bands "$job")" -ge 4 ] || fail "the job did not start (no 4 bands done in 10 s)"
ok "job $job running: $(done_bands "$job") of $bands_total bands done"

# Full to the last byte: dd stops at ENOSPC.
dd if=/dev/zero of="$data/filler" bs=64k 2>/dev/null
free_kb=$(df -k --output=avail "$data" | tail -1 | tr -d ' ')
[ "$free_kb" -le 64 ] || fail "the tmpfs still has $free_kb KiB free after the filler"
for _ in $(seq 200); do
  grep -q 'storage: ' "$tmp/coord.log" && break
  sleep 0.05
done
grep -q 'storage: ' "$tmp/coord.log" || fail "the coordinator did not notice the full disk within 10 s"
ok "disk full: $(grep -m1 'storage: ' "$tmp/coord.log" | cut -c1-200)"
acked=$(done_bands "$job")

if locus submit "$scene" --size 32x24 -o "g_####.png" >"$tmp/refused.out" 2>&1; then
  fail "a job was accepted on a full disk: $(cat "$tmp/refused.out")"
fi
grep -q "cannot write to its data directory $data" "$tmp/refused.out" ||
  fail "the refusal does not name the data directory: $(cat "$tmp/refused.out")"
grep -q "cannot reach" "$tmp/refused.out" &&
  fail "the refusal reads as an unreachable farm: $(cat "$tmp/refused.out")"
ok "a new job is refused: $(head -1 "$tmp/refused.out" | cut -c1-200)"
kill -0 "$coord" 2>/dev/null || fail "the coordinator died"
locus status >"$tmp/status.out" 2>&1 || fail "locus status on a full disk: $(cat "$tmp/status.out")"
ok "the coordinator answers on a full disk"
sleep 2
now=$(done_bands "$job")
[ "$now" -ge "$acked" ] || fail "bands were lost: $acked done, then $now"
kill -0 "$coord" 2>/dev/null || fail "the coordinator died"

rm -f "$data/filler"
ok "space freed"
for _ in $(seq 600); do
  kill -0 "$submit" 2>/dev/null || break
  sleep 0.1
done
kill -0 "$submit" 2>/dev/null && fail "the job did not end within 60 s of space returning"
wait "$submit" || fail "submit --wait failed: $(tail -3 "$tmp/submit.log")"
grep -q 'storage: .*can be written again' "$tmp/coord.log" || fail "no 'written again' in the log"
for f in $(seq 1 $frames); do
  name=$(printf "f_%04d.exr" "$f")
  file=$(find "$data/jobs/$job" -name "$name" | head -1)
  [ -n "$file" ] || fail "frame $f missing"
  idiff -fail 0 -warn 0 "$tmp/ref/$name" "$file" >"$tmp/idiff.out" 2>&1 ||
    fail "frame $f differs from the single-process render: $(grep -m1 'Max error' "$tmp/idiff.out")"
done
counts=$(sql "SELECT COUNT(*), COALESCE(SUM(completions = 1), 0) FROM bands WHERE job_id = '$job' AND done = 1")
[ "$counts" = "$bands_total|$bands_total" ] || fail "bands done|completed once: $counts, not $bands_total|$bands_total"
ok "job $job: $frames frames identical to a single-process render, each band completed once"

locus submit "$scene" --size 32x24 -o "g_####.png" --wait >"$tmp/after.out" 2>&1 ||
  fail "a job after the space returned: $(tail -3 "$tmp/after.out")"
ok "a new job succeeds once space returned"
kill -0 "$coord" 2>/dev/null || fail "the coordinator died"
echo "disk full: passed"

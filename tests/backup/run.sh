#!/usr/bin/env bash
# tests/backup/run.sh BINDIR SOURCE: `locus-coordinator --data DIR backup OUT`
# against a live coordinator process on 127.0.0.1 while a worker returns
# bands, then a coordinator started on OUT (the restore) that has every
# band accepted before the backup began and finishes the job with frames
# holding exactly the pixels of `locus render --workers 0`. Also: the subcommand
# in --help, an existing OUT refused, the running coordinator unharmed.
# Prints one line per check and "N passed, M failed".
set -uo pipefail
bin=$1 src=$2
. "$(dirname "${BASH_SOURCE[0]}")/../farm_lib.sh"  # same_pixels
tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null; done
  wait 2>/dev/null
  rm -rf "$tmp"
}
trap cleanup EXIT
passed=0 failed=0
ok() { echo "ok: $1"; passed=$((passed + 1)); }
bad() { echo "FAILED: $1"; failed=$((failed + 1)); }
scene=$src/scenes/simple/spheres.json
job_args=(--size 32x24 --frames 1-4 --orbit 30)

# start_coordinator DATA NAME: a coordinator on a free loopback port; sets $farm.
start_coordinator() {
  "$bin/locus-coordinator" --insecure --listen 127.0.0.1:0 --data "$1" --lease-ms 3000 \
    --heartbeat-ms 500 --drain-ms 0 >"$tmp/$2.out" 2>"$tmp/$2.log" &
  pids+=($!)
  local port=
  for _ in $(seq 100); do
    port=$(sed -n 's/^listening on port //p' "$tmp/$2.out")
    [ -n "$port" ] && break
    sleep 0.1
  done
  farm=127.0.0.1:$port
}
same_frames() {
  local f
  for f in 1 2 3 4; do same_pixels "$tmp/got/f_000$f.png" "$tmp/ref/f_000$f.png" || return 1; done
}
# bands_done: of j0001, from `locus status`.
bands_done() {
  "$bin/locus" status j0001 --farm "$farm" 2>/dev/null | sed -n 's#.* \([0-9]*\)/[0-9]* bands.*#\1#p'
}

"$bin/locus-coordinator" --help | grep -q "^  backup  " && ok "--help lists the backup subcommand" ||
  bad "--help has no backup subcommand"

# ---- a live coordinator, a slow worker, the backup mid-job
start_coordinator "$tmp/data" live
coordinator=${pids[-1]}
"$bin/locus" submit "$scene" --farm "$farm" -o "f_####.png" --bands 6 "${job_args[@]}" >/dev/null
"$bin/locus-worker" --coordinator "$farm" --threads 1 --name slow:1 --test-slow-band-ms 200 \
  2>"$tmp/slow.log" &
pids+=($!)
worker=$!
for _ in $(seq 200); do
  [ "$(bands_done)" -ge 5 ] 2>/dev/null && break
  sleep 0.05
done
before=$(bands_done)
"$bin/locus-coordinator" --data "$tmp/data" backup "$tmp/backup" >"$tmp/backup.out" 2>"$tmp/backup.log"
rc=$?
after=$(bands_done)
[ $rc -eq 0 ] && grep -q "^backup $tmp/backup: 1 jobs" "$tmp/backup.out" &&
  ok "backup of a running coordinator ($before bands accepted before it, $after after): $(cat "$tmp/backup.out")" ||
  { bad "backup failed ($rc)"; cat "$tmp/backup.out" "$tmp/backup.log"; }
[ "$before" -ge 5 ] && [ "$before" -lt 24 ] && ok "the job was mid-way ($before of 24 bands)" ||
  bad "the job was not mid-way: $before of 24 bands"
[ "$(ls -A "$tmp" | grep -c partial)" -eq 0 ] && [ ! -e "$tmp/backup/coordinator.lock" ] &&
  ok "no temporary directory left, no lock copied" || { bad "leftovers"; ls -la "$tmp" "$tmp/backup"; }
"$bin/locus-coordinator" --data "$tmp/data" backup "$tmp/backup" >/dev/null 2>"$tmp/again.log"
[ $? -ne 0 ] && grep -q "exists; give a new directory" "$tmp/again.log" && ok "an existing OUT is refused" ||
  { bad "an existing OUT was not refused"; cat "$tmp/again.log"; }
kill -0 "$coordinator" && [ "$(bands_done)" -ge "$after" ] && ok "the live coordinator went on" ||
  bad "the live coordinator stopped"
kill -9 "$worker" "$coordinator"

# ---- the restore: a coordinator on OUT
start_coordinator "$tmp/backup" restored
restored=$(bands_done)
[ -n "$restored" ] && [ "$restored" -ge "$before" ] &&
  ok "restored with $restored bands accepted (>= $before before the backup)" ||
  { bad "restored with '$restored' bands, $before before the backup"; cat "$tmp/restored.log"; }
"$bin/locus-worker" --coordinator "$farm" --threads 1 --name fast:2 2>"$tmp/fast.log" &
pids+=($!)
timeout 30 "$bin/locus" watch j0001 --farm "$farm" >"$tmp/watch.out" 2>&1 &&
  "$bin/locus" fetch j0001 "$tmp/got" --farm "$farm" >/dev/null 2>&1 &&
  "$bin/locus" render "$scene" "${job_args[@]}" --workers 0 -o "$tmp/ref/f_####.png" 2>/dev/null &&
  same_frames &&
  ok "the restored job finished with frames identical to --workers 0" ||
  { bad "the restored job"; cat "$tmp/watch.out" "$tmp/restored.log"; }

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]

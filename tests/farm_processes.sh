#!/usr/bin/env bash
# farm_processes.sh BINDIR SHARED SOURCE: the farm as real processes on
# 127.0.0.1 (ephemeral ports only): the embedded farm of `locus render`, a
# coordinator and workers started by hand with `locus submit --wait`, a
# worker killed with SIGKILL mid-job, cancel, and the CLI's errors. Frames are
# compared byte for byte with `--workers 0` renders (identical files imply
# identical decoded pixels). Prints one line per check and
# "N passed, M failed".
set -uo pipefail
bin=$1 shared=$2 src=$3
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
same_frames() {  # same_frames DIR_A PREFIX_A DIR_B PREFIX_B FIRST LAST
  local f
  for f in $(seq "$5" "$6"); do
    local n; n=$(printf %04d "$f")
    cmp -s "$1/$2_$n.png" "$3/$4_$n.png" || { echo "  frame $f differs or is missing"; return 1; }
  done
}

balls=$shared/spd/s1/balls.nff
anim=$src/scenes/anim/glass_and_mirror.json
glass=$src/scenes/paper/a_glass.json

# ---- the embedded farm equals the in-process renderer
"$bin/locus" render "$balls" --orbit 30 --frames 1-6 --size 64x48 --workers 2 -o "$tmp/e/f_####.png" 2>"$tmp/e.log" &&
  "$bin/locus" render "$balls" --orbit 30 --frames 1-6 --size 64x48 --workers 0 -o "$tmp/r/f_####.png" 2>>"$tmp/e.log" &&
  same_frames "$tmp/e" f "$tmp/r" f 1 6 && ok "render --workers 2 == --workers 0 (balls.nff, orbit 30, 6 frames)" ||
  { bad "embedded farm, balls.nff"; cat "$tmp/e.log"; }
"$bin/locus" render "$anim" --frames 1-4 --size 64x48 --workers 2 --bands 5 -o "$tmp/e/a_####.png" 2>"$tmp/e.log" &&
  "$bin/locus" render "$anim" --frames 1-4 --size 64x48 --workers 0 -o "$tmp/r/a_####.png" 2>>"$tmp/e.log" &&
  same_frames "$tmp/e" a "$tmp/r" a 1 4 && ok "render --workers 2 == --workers 0 (scenes/anim, 4 frames, 5 bands)" ||
  { bad "embedded farm, scenes/anim"; cat "$tmp/e.log"; }

# ---- a coordinator and two workers started by hand
"$bin/locus-coordinator" --listen 127.0.0.1:0 --data "$tmp/data" --lease-ms 3000 --heartbeat-ms 300 \
  >"$tmp/coord.out" 2>"$tmp/coord.log" &
pids+=($!)
port=
for _ in $(seq 100); do
  port=$(sed -n 's/^listening on port //p' "$tmp/coord.out")
  [ -n "$port" ] && break
  sleep 0.05
done
[ -n "$port" ] || { bad "coordinator did not start"; cat "$tmp/coord.log"; exit 1; }
farm=127.0.0.1:$port
"$bin/locus-worker" --coordinator "$farm" 2>"$tmp/w1.log" &
w1=$!
"$bin/locus-worker" --coordinator "$farm" 2>"$tmp/w2.log" &
w2=$!
pids+=("$w1" "$w2")

"$bin/locus" submit "$balls" --farm "$farm" --orbit 30 --frames 1-6 --size 64x48 -o "$tmp/s/f_####.png" --wait \
  >"$tmp/submit.out" 2>"$tmp/submit.log" && same_frames "$tmp/s" f "$tmp/r" f 1 6 &&
  ok "submit --wait to a hand-started farm == --workers 0" || { bad "submit --wait"; cat "$tmp/submit.log"; }
job=$(head -1 "$tmp/submit.out")
"$bin/locus" fetch "$job" "$tmp/fetched" --farm "$farm" >/dev/null && same_frames "$tmp/fetched" f "$tmp/r" f 1 6 &&
  ok "fetch $job" || bad "fetch $job"

# ---- SIGKILL of a worker in the middle of a job
# About 3 s of work for two workers: long enough to freeze one, see it
# holding a band and kill it (the lease, 3 s, outlives that look).
"$bin/locus" render "$glass" --orbit 20 --frames 1-8 --size 96x72 --method raytrace --spp 12 --workers 0 -o "$tmp/r/k_####.png" 2>/dev/null
"$bin/locus" submit "$glass" --farm "$farm" --orbit 20 --frames 1-8 --size 96x72 --method raytrace --spp 12 --bands 4 \
  -o "$tmp/k/k_####.png" --wait >"$tmp/kill.out" 2>"$tmp/kill.log" &
submit=$!
for _ in $(seq 500); do
  grep -q " running " "$tmp/kill.log" 2>/dev/null && break
  sleep 0.02
done
victim=
for _ in $(seq 10); do
  # Freeze a worker, so that what `locus workers` says of it stays true,
  # and kill it only if it holds a band.
  kill -STOP "$w1"
  if "$bin/locus" workers --farm "$farm" 2>/dev/null | awk -v pid="$w1" '$4 == "busy" && $2 ~ (":" pid "$")' | grep -q .; then
    victim=$w1
    kill -9 "$w1"
    break
  fi
  kill -CONT "$w1"
  sleep 0.03
done
if [ -n "$victim" ]; then
  wait "$submit" && same_frames "$tmp/k" k "$tmp/r" k 1 8 &&
    ok "worker $victim killed with SIGKILL holding a band: the job completed with identical frames" ||
    { bad "job after SIGKILL"; cat "$tmp/kill.log"; }
  grep -q "back in the queue" "$tmp/coord.log" && ok "the killed worker's band was leased again" ||
    bad "no band was re-leased after the SIGKILL"
else
  wait "$submit"
  bad "no worker seen holding a band to kill"
fi

# ---- cancel
"$bin/locus" submit "$glass" --farm "$farm" --frames 1-400 --size 96x72 --method raytrace --spp 4 -o "$tmp/c/c_####.png" \
  >"$tmp/cancel.out" 2>"$tmp/cancel.log"
cjob=$(head -1 "$tmp/cancel.out")
sleep 0.3
"$bin/locus" cancel "$cjob" --farm "$farm" | grep -q cancelled && ok "cancel $cjob" || bad "cancel $cjob"
before=$("$bin/locus" status "$cjob" --farm "$farm" | awk '/progress/ {print $2}')
sleep 0.5
after=$("$bin/locus" status "$cjob" --farm "$farm" | awk '/progress/ {print $2}')
[ "$before" = "$after" ] && ok "no band completes after cancel ($after)" || bad "work went on after cancel: $before -> $after"
"$bin/locus" watch "$cjob" --farm "$farm" >"$tmp/watch.out"
[ $? -eq 1 ] && tail -1 "$tmp/watch.out" | grep -q cancelled && ok "watch of a cancelled job ends (exit 1)" ||
  { bad "watch of a cancelled job"; cat "$tmp/watch.out"; }

# ---- errors a user can cause
printf '{"camera": {"from": [0,0,5], "at": [0,0,0], "width": 32, "height": 24},\n "objects": [{"sphere": {"radius": -1}}]}\n' \
  >"$tmp/bad.json"
jobs_before=$("$bin/locus" status --farm "$farm" | wc -l)
"$bin/locus" submit "$tmp/bad.json" --farm "$farm" -o "$tmp/x.png" 2>"$tmp/err" && bad "a bad scene was accepted" ||
  { grep -q "bad.json" "$tmp/err" && grep -q "radius" "$tmp/err" && ok "bad scene at submit: $(head -1 "$tmp/err")" ||
    { bad "bad scene message"; cat "$tmp/err"; }; }
jobs_after=$("$bin/locus" status --farm "$farm" | wc -l)
[ "$jobs_before" = "$jobs_after" ] && ok "the bad scene created no job" || bad "the bad scene created a job"
"$bin/locus" status j9999 --farm "$farm" 2>"$tmp/err" && bad "unknown job accepted" ||
  { grep -q "unknown" "$tmp/err" && ok "unknown job: $(cat "$tmp/err")" || bad "unknown job message"; }
"$bin/locus" workers --farm 127.0.0.1:1 2>"$tmp/err" && bad "unreachable farm accepted" ||
  { grep -q "cannot reach the farm at 127.0.0.1:1" "$tmp/err" && ok "unreachable farm: cannot reach ..." ||
    { bad "unreachable farm message"; cat "$tmp/err"; }; }

# ---- graceful stop
kill -TERM "$w1" "$w2" 2>/dev/null
kill -TERM "${pids[0]}"
wait "${pids[0]}" && ok "coordinator exits cleanly on SIGTERM" || bad "coordinator exit status"

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]

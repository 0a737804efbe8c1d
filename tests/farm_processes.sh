#!/usr/bin/env bash
# farm_processes.sh BINDIR SHARED SOURCE: the farm as real processes on
# 127.0.0.1 (ephemeral ports only): the embedded farm of `locus render`, a
# coordinator and workers started by hand (TLS, worker certificates and
# tokens, certificates made here with tests/tls/make_certs.sh) with `locus
# submit --wait`, a worker killed with SIGKILL mid-job, cancel, refused
# credentials, and the CLI's errors. Frames are
# compared pixel for pixel with `--workers 0` renders (same_pixels: a PNG
# frame joined from its bands' streams is compressed otherwise). Prints one line per check and
# "N passed, M failed".
set -uo pipefail
bin=$1 shared=$2 src=$3
. "$(dirname "${BASH_SOURCE[0]}")/farm_lib.sh"  # same_pixels, listening_port
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
    same_pixels "$1/$2_$n.png" "$3/$4_$n.png" || { echo "  frame $f differs or is missing"; return 1; }
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

# ---- the embedded farm takes a scene of more objects than a shared
# coordinator's --max-objects (100,000): its one client is this process
# (client/local_farm.cpp)
/usr/bin/python3 - "$tmp/many.nff" <<'PY'
import sys
with open(sys.argv[1], "w") as f:
    f.write("v\nfrom 0 0 -8\nat 0 0 0\nup 0 1 0\nangle 40\nhither 1\nresolution 16 16\n")
    f.write("l 2 4 -6\nf 0.8 0.6 0.4 0.8 0.2 10 0 1\n")
    n = 317  # 317 x 317 = 100,489 spheres
    for i in range(n * n):
        x, y = i % n, i // n
        f.write(f"s {4 * x / n - 2:.5f} {4 * y / n - 2:.5f} 0 0.006\n")
PY
"$bin/locus" render "$tmp/many.nff" --size 16x16 --workers 1 -o "$tmp/e/many.png" 2>"$tmp/e.log" &&
  "$bin/locus" render "$tmp/many.nff" --size 16x16 --workers 0 -o "$tmp/r/many.png" 2>>"$tmp/e.log" &&
  same_pixels "$tmp/e/many.png" "$tmp/r/many.png" &&
  ok "render --workers 1 of 100,489 spheres (over a coordinator's default --max-objects) == --workers 0" ||
  { bad "embedded farm, 100,489 spheres"; cat "$tmp/e.log"; }

# ---- EXR frames of the embedded farm: written from the workers' blocks
# when its workers fill the machine's cores, else compressed by its
# coordinator; the single-process render's file, byte for byte, either way
# (docs/farm.md "Frames")
cores=$(nproc)
for w in 1 2; do
  "$bin/locus" render "$glass" --size 64x48 --bands 3 --workers "$w" -o "$tmp/x/w$w.exr" 2>"$tmp/x.log" &&
    "$bin/locus" render "$glass" --size 64x48 --workers 0 -o "$tmp/x/w0.exr" 2>>"$tmp/x.log" &&
    same_pixels "$tmp/x/w$w.exr" "$tmp/x/w0.exr" || { bad "EXR, $w workers: pixels"; cat "$tmp/x.log"; continue; }
  cmp -s "$tmp/x/w$w.exr" "$tmp/x/w0.exr" && ok "EXR on $w workers ($cores cores): the single-process file, byte for byte" ||
    bad "EXR on $w workers ($cores cores): the file differs from the single-process render's"
done

# ---- the embedded farm's token is in its workers' environment, not on their command line
"$bin/locus" render "$glass" --frames 1-6 --size 160x120 --aa 8 --workers 2 -o "$tmp/e/t_####.png" 2>"$tmp/t.log" &
render=$!
seen=
workers_seen=()
# Until the render ends: each worker's command line, then its environment,
# read once into variables, as a worker may exit between two reads of /proc
# (a token in the environment means it was alive when its command line was
# read).
while [ -z "$seen" ] && kill -0 "$render" 2>/dev/null; do
  for w in $(pgrep -P "$render" 2>/dev/null); do
    [[ " ${workers_seen[*]} " == *" $w "* ]] || workers_seen+=("$w")
    cmd_w=$(tr '\0' ' ' <"/proc/$w/cmdline" 2>/dev/null) || continue
    env_w=$(tr '\0' '\n' <"/proc/$w/environ" 2>/dev/null) || continue
    token=$(printf '%s\n' "$env_w" | sed -n 's/^LOCUS_TOKEN=//p')
    if [[ $token =~ ^[0-9a-f]{64}$ ]]; then
      case "$cmd_w" in
        *"$token"*) seen=cmdline ;;
        *) seen=${seen:-env} ;;
      esac
    fi
  done
  sleep 0.01
done
# The render must succeed: a refused one (it was `--spp 6`, refused by the
# local method) leaves its workers alive only while the farm starts and
# stops, and the check above raced their exit.
wait "$render" && render_rc=0 || render_rc=$?
[ "$render_rc" = 0 ] || { bad "embedded farm token: the render failed ($render_rc)"; cat "$tmp/t.log"; }
[ "$seen" = env ] && ok "embedded farm: random 64-hex token in the workers' LOCUS_TOKEN, not on their command line" ||
  bad "embedded farm token: '$seen'"
# ... and its workers are gone with it, reaped, not zombies left to PID 1
# (which may never reap, in a container): `locus render` ends its farm with
# a quick exit (docs/farm.md "Start and end of the embedded farm").
left=
for w in "${workers_seen[@]}"; do [ -e "/proc/$w" ] && left+=" $w($(awk '{print $3}' "/proc/$w/stat" 2>/dev/null))"; done
[ "${#workers_seen[@]}" -gt 0 ] && [ -z "$left" ] &&
  ok "embedded farm: its ${#workers_seen[@]} workers reaped when locus render returns" ||
  bad "embedded farm: workers seen: ${workers_seen[*]}; left after the render:$left"

# ---- a coordinator refuses to start without TLS or tokens unless --insecure
bash "$src/tests/tls/make_certs.sh" "$tmp/tls"
tls=$tmp/tls
printf '# clients\nclient-token-%s\n' "$RANDOM$RANDOM" >"$tmp/client.tokens"
printf 'worker-token-%s\n' "$RANDOM$RANDOM" >"$tmp/worker.tokens"
chmod 600 "$tmp/client.tokens" "$tmp/worker.tokens"
"$bin/locus-coordinator" --listen 127.0.0.1:0 --data "$tmp/d0" --client-tokens "$tmp/client.tokens" \
  --worker-tokens "$tmp/worker.tokens" >/dev/null 2>"$tmp/err"
[ $? -ne 0 ] && grep -q "refusing to serve without TLS" "$tmp/err" && ok "no TLS, no --insecure: refused to start" ||
  { bad "started without TLS"; cat "$tmp/err"; }
"$bin/locus-coordinator" --listen 127.0.0.1:0 --data "$tmp/d0" --tls-cert "$tls/server.pem" --tls-key "$tls/server.key" \
  >/dev/null 2>"$tmp/err"
[ $? -ne 0 ] && grep -q "refusing to serve without tokens" "$tmp/err" && ok "no token files, no --insecure: refused to start" ||
  { bad "started without tokens"; cat "$tmp/err"; }

# ---- a coordinator (TLS, worker certificates, tokens) and two workers started by hand
"$bin/locus-coordinator" --listen 127.0.0.1:0 --data "$tmp/data" --lease-ms 3000 --heartbeat-ms 300 \
  --tls-cert "$tls/server.pem" --tls-key "$tls/server.key" --tls-ca "$tls/ca.pem" \
  --client-tokens "$tmp/client.tokens" --worker-tokens "$tmp/worker.tokens" \
  >"$tmp/coord.out" 2>"$tmp/coord.log" &
pids+=($!)
port=$(listening_port "$tmp/coord.out")
[ -n "$port" ] || { bad "coordinator did not start"; cat "$tmp/coord.log"; exit 1; }
farm=127.0.0.1:$port
wflags=(--tls-ca "$tls/ca.pem" --tls-cert "$tls/client.pem" --tls-key "$tls/client.key" --token-file "$tmp/worker.tokens")
"$bin/locus-worker" --coordinator "$farm" "${wflags[@]}" 2>"$tmp/w1.log" &
w1=$!
"$bin/locus-worker" --coordinator "$farm" "${wflags[@]}" 2>"$tmp/w2.log" &
w2=$!
pids+=("$w1" "$w2")
# Every farm command below: TLS verified against the test CA, and the
# client token (from LOCUS_TOKEN here; --token-file works alike).
export LOCUS_TOKEN
LOCUS_TOKEN=$(sed -n 2p "$tmp/client.tokens")
locus() { "$bin/locus" "$@" --tls-ca "$tls/ca.pem"; }

# ---- refused credentials
env -u LOCUS_TOKEN "$bin/locus" status --farm "$farm" --tls-ca "$tls/ca.pem" 2>"$tmp/err" && bad "no token accepted" ||
  { grep -q UNAUTHENTICATED "$tmp/err" && ok "no token: $(cat "$tmp/err")" || { bad "no token message"; cat "$tmp/err"; }; }
"$bin/locus" status --farm "$farm" --tls-ca "$tls/ca.pem" --token-file "$tmp/worker.tokens" 2>"$tmp/err" &&
  bad "a worker token listed jobs" ||
  { grep -q PERMISSION_DENIED "$tmp/err" && ok "worker token on ClientService: $(cat "$tmp/err")" ||
    { bad "worker token message"; cat "$tmp/err"; }; }
"$bin/locus" status --farm "$farm" 2>"$tmp/err" && bad "plaintext to a TLS farm accepted" ||
  { grep -q -- "--tls-ca" "$tmp/err" && ok "plaintext to a TLS farm: refused, with a hint at --tls-ca" ||
    { bad "plaintext to TLS message"; cat "$tmp/err"; }; }
timeout 20 "$bin/locus-worker" --coordinator "$farm" "${wflags[@]:0:6}" --token-file "$tmp/client.tokens" 2>"$tmp/err"
[ $? -eq 1 ] && grep -q PERMISSION_DENIED "$tmp/err" && ok "a worker with a client token exits 1 (PERMISSION_DENIED)" ||
  { bad "worker with a client token"; cat "$tmp/err"; }
timeout 20 "$bin/locus-worker" --coordinator "$farm" --tls-ca "$tls/ca.pem" --token-file "$tmp/worker.tokens" 2>"$tmp/err"
[ $? -eq 1 ] && grep -q "client certificate" "$tmp/err" && ok "a worker without a client certificate exits 1 (UNAUTHENTICATED)" ||
  { bad "worker without a certificate"; cat "$tmp/err"; }
# ---- the address on a descriptor (how `locus render`'s embedded farm starts
# its workers before its coordinator listens)
timeout 20 "$bin/locus-worker" --coordinator-fd 3 "${wflags[@]}" 3</dev/null 2>"$tmp/err"
[ $? -eq 2 ] && grep -q -- "--coordinator-fd 3: closed before an address came" "$tmp/err" &&
  ok "--coordinator-fd closed unwritten: exit 2, $(cat "$tmp/err")" || { bad "--coordinator-fd closed"; cat "$tmp/err"; }
printf '%02000d' 0 | timeout 20 "$bin/locus-worker" --coordinator-fd 0 "${wflags[@]}" 2>"$tmp/err"
[ $? -eq 2 ] && grep -q -- "--coordinator-fd 0: the address is longer than 1024 bytes" "$tmp/err" &&
  ok "--coordinator-fd: an address of 2000 bytes refused (exit 2)" || { bad "--coordinator-fd long address"; cat "$tmp/err"; }
timeout 20 "$bin/locus-worker" --coordinator-fd 3 --coordinator "$farm" "${wflags[@]}" 3</dev/null 2>"$tmp/err"
[ $? -ne 0 ] && grep -q "excludes" "$tmp/err" && ok "--coordinator-fd with --coordinator: refused" ||
  { bad "--coordinator-fd with --coordinator"; cat "$tmp/err"; }
timeout 20 "$bin/locus-worker" --coordinator-fd 3 "${wflags[@]:0:6}" --token-file "$tmp/client.tokens" \
  3< <(echo "$farm") 2>"$tmp/err"
[ $? -eq 1 ] && grep -q PERMISSION_DENIED "$tmp/err" && ok "--coordinator-fd: the address read from it is dialled" ||
  { bad "--coordinator-fd's address"; cat "$tmp/err"; }
grep -q "refused WorkerService.Register" "$tmp/coord.log" && grep -q "refused ClientService.ListJobs" "$tmp/coord.log" &&
  ! grep -qF "$LOCUS_TOKEN" "$tmp/coord.log" && ok "refusals logged by the coordinator, tokens never" ||
  bad "refusal logs"

locus submit "$balls" --farm "$farm" --orbit 30 --frames 1-6 --size 64x48 -o "$tmp/s/f_####.png" --wait \
  >"$tmp/submit.out" 2>"$tmp/submit.log" && same_frames "$tmp/s" f "$tmp/r" f 1 6 &&
  ok "submit --wait to a hand-started farm == --workers 0" || { bad "submit --wait"; cat "$tmp/submit.log"; }
job=$(head -1 "$tmp/submit.out")
locus fetch "$job" "$tmp/fetched" --farm "$farm" >/dev/null && same_frames "$tmp/fetched" f "$tmp/r" f 1 6 &&
  ok "fetch $job" || bad "fetch $job"

# ---- SIGKILL of a worker in the middle of a job
# About 3 s of work for two workers: long enough to freeze one, see it
# holding a band and kill it (the lease, 3 s, outlives that look).
"$bin/locus" render "$glass" --orbit 20 --frames 1-8 --size 96x72 --method raytrace --spp 12 --workers 0 -o "$tmp/r/k_####.png" 2>/dev/null
locus submit "$glass" --farm "$farm" --orbit 20 --frames 1-8 --size 96x72 --method raytrace --spp 12 --bands 4 \
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
  if locus workers --farm "$farm" 2>/dev/null | awk -v pid="$w1" '$4 == "busy" && $2 ~ (":" pid "$")' | grep -q .; then
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
  # Leased again either when its lease lapses, or earlier, speculatively,
  # once it runs far longer than its peers (docs/farm.md).
  grep -qE "back in the queue|second lease to worker" "$tmp/coord.log" &&
    ok "the killed worker's band was leased again" ||
    bad "no band was re-leased after the SIGKILL"
else
  wait "$submit"
  bad "no worker seen holding a band to kill"
fi

# ---- cancel
locus submit "$glass" --farm "$farm" --frames 1-400 --size 96x72 --method raytrace --spp 4 -o "$tmp/c/c_####.png" \
  >"$tmp/cancel.out" 2>"$tmp/cancel.log"
cjob=$(head -1 "$tmp/cancel.out")
sleep 0.3
prints cancelled locus cancel "$cjob" --farm "$farm" && ok "cancel $cjob" || bad "cancel $cjob"
before=$(locus status "$cjob" --farm "$farm" | awk '/progress/ {print $2}')
sleep 0.5
after=$(locus status "$cjob" --farm "$farm" | awk '/progress/ {print $2}')
[ "$before" = "$after" ] && ok "no band completes after cancel ($after)" || bad "work went on after cancel: $before -> $after"
locus watch "$cjob" --farm "$farm" >"$tmp/watch.out"
[ $? -eq 1 ] && tail -1 "$tmp/watch.out" | grep -q cancelled && ok "watch of a cancelled job ends (exit 1)" ||
  { bad "watch of a cancelled job"; cat "$tmp/watch.out"; }

# ---- errors a user can cause
printf '{"camera": {"from": [0,0,5], "at": [0,0,0], "width": 32, "height": 24},\n "objects": [{"sphere": {"radius": -1}}]}\n' \
  >"$tmp/bad.json"
jobs_before=$(locus status --farm "$farm" | wc -l)
locus submit "$tmp/bad.json" --farm "$farm" -o "$tmp/x.png" 2>"$tmp/err" && bad "a bad scene was accepted" ||
  { grep -q "bad.json" "$tmp/err" && grep -q "radius" "$tmp/err" && ok "bad scene at submit: $(head -1 "$tmp/err")" ||
    { bad "bad scene message"; cat "$tmp/err"; }; }
jobs_after=$(locus status --farm "$farm" | wc -l)
[ "$jobs_before" = "$jobs_after" ] && ok "the bad scene created no job" || bad "the bad scene created a job"
for tol in 0 -1 nan; do
  locus submit "$src/scenes/teapot.json" --farm "$farm" --tess-tol "$tol" -o "$tmp/x.png" 2>"$tmp/err" &&
    bad "--tess-tol $tol accepted" ||
    { grep -q -- "--tess-tol must be a positive number of pixels" "$tmp/err" &&
      ok "--tess-tol $tol at submit: $(head -1 "$tmp/err")" || { bad "--tess-tol $tol message"; cat "$tmp/err"; }; }
done
"$bin/locus" render "$src/scenes/teapot.json" --workers 0 --tess-tol 0 -o "$tmp/x.png" 2>"$tmp/err" &&
  bad "render --tess-tol 0 accepted" ||
  { grep -q -- "--tess-tol must be a positive number of pixels" "$tmp/err" &&
    ok "render --tess-tol 0: $(head -1 "$tmp/err")" || { bad "render --tess-tol 0 message"; cat "$tmp/err"; }; }
locus status j9999 --farm "$farm" 2>"$tmp/err" && bad "unknown job accepted" ||
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

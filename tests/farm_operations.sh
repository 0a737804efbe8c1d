#!/usr/bin/env bash
# farm_operations.sh BINDIR SOURCE_DIR: the farm operators' features with
# real processes, the coordinator killed with SIGKILL in the middle of each
# scenario and restarted on the same --data directory and address.
#
# Everything runs inside one network namespace made here (root; no skip:
# a namespace that cannot be made is a failure): the coordinator on
# 127.0.0.1:7090 in it (plaintext with --insecure, client, admin and worker
# tokens: users ann and bob, admin root), workers that play 200 ms per band
# (--test-slow-band-ms, so that a kill lands mid-job) and every CLI call.
# Nothing is sent to any other address. Speculation is off
# (--speculate-factor 0) so that a hung band is taken back by its timeout
# and nothing else. Jobs: scenes/simple/spheres.json at 48x36, 2 bands per
# frame, --orbit 20 (every frame differs); their frames, fetched with
# `locus fetch`, must hold exactly the pixels of `locus render --workers 0`
# (same_pixels).
#
# Scenarios (each with a kill -9 of the coordinator and a restart):
#   1 priorities and owners: ann's job (priority 50), paused by admin root;
#     bob's job of priority 90 submitted after it started; killed with both
#     unfinished; bob's priority and owner survive, bob may neither pause nor
#     cancel ann's job before and after the restart (PERMISSION_DENIED),
#     root resumes it, bob's job takes the workers first, the history names
#     "admin root"
#   2 pause: paused mid-way, killed; still paused after the restart, no
#     lease in 3 s with the workers back; resumed, it finishes
#   3 dependencies: D --after C, killed while C runs; D's first lease
#     follows C's last frame; E --after a job then cancelled fails naming it
#   4 pools: a job requiring tag big waits for such a worker (status says
#     so) across the restart; a worker --tag big renders all its bands
#   5 band timeout: a hung worker (its band never returns, heartbeats go on)
#     holds a band at the kill; after the restart another hung worker takes
#     one and the job's --band-timeout 3 takes it back; the job completes
#   6 events and logs: a worker killed with SIGKILL holding a band, then the
#     coordinator; `locus events` shows every lease of the job and how each
#     ended (the killed worker's not done); `locus logs` answers
#   7 requeue and retry: a frame file of a finished job deleted and
#     requeued, killed while it renders again, the file back after the
#     restart; a job cancelled mid-way, killed, restarted, retried: it
#     finishes
#   8 fair share: workers disabled while ann submits 10 small jobs and bob
#     one of 10 frames, then enabled; each user gets 40-60% of the first 16
#     leases; killed after them, all 11 jobs finish
# After every scenario: every band done was accepted exactly once
# (bands.completions = 1 in the job store, read with sqlite3), every job
# that succeeded has all its bands, no job is left unfinished and no lease
# open. Prints one line per check and "N passed, M failed"; exit 0 only if
# all passed. KEEP=1 keeps the logs and the data directory.
set -uo pipefail
[ $# -eq 2 ] || { echo "usage: $0 BINDIR SOURCE_DIR" >&2; exit 2; }
bin=$(cd "$1" && pwd) src=$(cd "$2" && pwd) || exit 2

setup_failed() {
  echo "FAILED: $1"
  exit 1
}
[ "$(id -u)" -eq 0 ] || setup_failed "farm_operations needs root to make its network namespace (ip netns add)"
for tool in ip sqlite3 cmp; do
  command -v $tool >/dev/null || setup_failed "$tool is missing (deploy/local/install-deps.sh)"
done
for b in locus locus-coordinator locus-worker; do
  [ -x "$bin/$b" ] || setup_failed "$bin/$b is missing"
done

ns=lo$$ops
tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null; done
  wait 2>/dev/null
  ip netns del "$ns" 2>/dev/null
  if [ -n "${KEEP:-}" ]; then echo "logs kept in $tmp"; else rm -rf "$tmp"; fi
}
trap cleanup EXIT
trap 'exit 130' INT TERM
ip netns add "$ns" 2>"$tmp/netns.err" ||
  setup_failed "cannot make the network namespace $ns: $(cat "$tmp/netns.err")"
ip -n "$ns" link set lo up 2>"$tmp/netns.err" ||
  setup_failed "cannot bring up lo in the network namespace $ns: $(cat "$tmp/netns.err")"

passed=0 failed=0
ok() { echo "ok: $1"; passed=$((passed + 1)); }
bad() { echo "FAILED: $1"; failed=$((failed + 1)); }

farm=127.0.0.1:7090
data=$tmp/data
scene=$src/scenes/simple/spheres.json
in_ns() { ip netns exec "$ns" "$@"; }

# Tokens: users ann and bob, admin root, one worker token. A client's
# token file holds the token alone.
printf 'ann ann-%s\nbob bob-%s\n' "$RANDOM$RANDOM" "$RANDOM$RANDOM" >"$tmp/client.tokens"
printf 'root root-%s\n' "$RANDOM$RANDOM" >"$tmp/admin.tokens"
printf 'worker-%s\n' "$RANDOM$RANDOM" >"$tmp/worker.token"
for u in ann bob; do sed -n "s/^$u //p" "$tmp/client.tokens" >"$tmp/$u.token"; done
sed -n 's/^root //p' "$tmp/admin.tokens" >"$tmp/root.token"
chmod 600 "$tmp"/*.tokens "$tmp"/*.token

# cli USER ARGS...: the CLI with that user's token.
cli() {
  local user=$1
  shift
  in_ns "$bin/locus" "$@" --farm "$farm" --token-file "$tmp/$user.token"
}
# submit USER ARGS...: prints the job id.
submit() {
  local user=$1
  shift
  cli "$user" submit "$scene" --size 48x36 --bands 2 --orbit 20 -o 'f_####.png' "$@" 2>>"$tmp/cli.log"
}

coord=
start_coordinator() {
  : >"$tmp/coord.out"
  # Not through a shell function: $! must be the coordinator itself (ip
  # netns exec execs it).
  ip netns exec "$ns" "$bin/locus-coordinator" --listen "$farm" --data "$data" --lease-ms 2000 \
    --heartbeat-ms 300 --speculate-factor 0 --insecure --client-tokens "$tmp/client.tokens" \
    --admin-tokens "$tmp/admin.tokens" --worker-tokens "$tmp/worker.token" \
    >"$tmp/coord.out" 2>>"$tmp/coord.log" &
  coord=$!
  pids+=("$coord")
  for _ in $(seq 300); do
    grep -q '^listening on port' "$tmp/coord.out" 2>/dev/null && return 0
    kill -0 "$coord" 2>/dev/null || break
    sleep 0.05
  done
  bad "the coordinator did not start on $farm"
  tail -5 "$tmp/coord.log"
  exit 1
}
# restart: SIGKILL of the coordinator, and a new one on the same data and address.
restarts=0
restart() {
  kill -9 "$coord"
  wait "$coord" 2>/dev/null
  restarts=$((restarts + 1))
  start_coordinator
}
# start_worker LOG MS_PER_BAND [ARGS...]: sets $last_worker (its name is host:pid).
last_worker=
start_worker() {
  local log=$1 ms=$2
  shift 2
  ip netns exec "$ns" "$bin/locus-worker" --coordinator "$farm" --token-file "$tmp/worker.token" \
    --threads 1 --test-slow-band-ms "$ms" "$@" 2>>"$tmp/worker-$log.log" &
  last_worker=$!
  pids+=("$last_worker")
}

# The job store (WAL: readers never block the coordinator).
sql() { sqlite3 -readonly -cmd '.timeout 5000' "$data/locus.db" "$1" 2>>"$tmp/sql.err"; }
state_of() { sql "SELECT state FROM jobs WHERE id = '$1'"; }
job_is() { [ "$(state_of "$1")" = "$2" ]; }
bands_done() { sql "SELECT COUNT(*) FROM bands WHERE job_id = '$1' AND done = 1"; }
leases_of() { sql "SELECT COUNT(*) FROM attempts WHERE job_id = '$1'"; }
done_ge() { [ "$(bands_done "$1")" -ge "$2" ] 2>/dev/null; }
leases_ge() { [ "$(leases_of "$1")" -ge "$2" ] 2>/dev/null; }
no_lease_open() { [ "$(sql "SELECT COUNT(*) FROM leases WHERE job_id = '$1'")" = 0 ]; }
# holding_band PID [JOB]: whether that worker holds a lease now.
holding_band() {
  [ -n "$(sql "SELECT 1 FROM leases WHERE worker_name LIKE '%:$1'${2:+ AND job_id = '$2'} LIMIT 1")" ]
}
all_succeeded() {
  local j
  for j in "$@"; do job_is "$j" succeeded || return 1; done
}
# poll SECONDS CMD...: CMD every 50 ms until it succeeds; status 1 after SECONDS.
poll() {
  local end=$(($(date +%s%N) / 1000000 + $1 * 1000))
  shift
  until "$@"; do
    [ "$(($(date +%s%N) / 1000000))" -ge "$end" ] && return 1
    sleep 0.05
  done
}
workers_up() { [ "$(cli root workers 2>/dev/null | tail -n +2 | wc -l)" -ge "$1" ]; }
# wait_workers N: until N workers are registered (after a restart they re-register).
wait_workers() { poll 20 workers_up "$1" || bad "fewer than $1 workers registered after 20 s"; }
worker_up() { cli root workers 2>/dev/null | awk -v pid="$1" '$2 ~ (":" pid "$") {f = 1} END {exit !f}'; }

. "$(dirname "${BASH_SOURCE[0]}")/farm_lib.sh"  # signal_busy, same_pixels

# freeze / thaw: the two ordinary workers stopped (SIGSTOP) around a CLI
# action that must land mid-job however slow the CLI is on a loaded
# machine: frozen, they finish no band. (Frozen longer than the lease,
# 2 s, their bands would lapse and render again: still counted once.)
freeze() { kill -STOP "$w1" "$w2"; }
thaw() { kill -CONT "$w1" "$w2"; }
# set_workers disable|enable: both ordinary workers (by name) at once, as
# admin root: disabled, a worker takes no band but stays connected.
set_workers() {
  local names n p=() rc=0
  names=$(cli root workers 2>/dev/null | awk -v a="$w1" -v b="$w2" '$2 ~ (":(" a "|" b ")$") {print $2}')
  for n in $names; do
    cli root "$1" "$n" >/dev/null 2>>"$tmp/cli.log" &
    p+=($!)
  done
  for n in "${p[@]}"; do wait "$n" || rc=1; done
  [ ${#p[@]} -eq 2 ] && [ $rc -eq 0 ]
}

# References: one single-process render per frame range (the orbit makes
# frames depend on the range).
for range in 1-1 1-4 1-6 1-8 1-10 1-24; do
  in_ns "$bin/locus" render "$scene" --size 48x36 --orbit 20 --frames "$range" --workers 0 \
    -o "$tmp/ref/$range/f_####.png" 2>>"$tmp/ref.log" || { bad "reference render $range"; cat "$tmp/ref.log"; exit 1; }
done
# same_frames JOB FIRST LAST: the job's frames, fetched, equal the reference's.
same_frames() {
  local job=$1 f n
  rm -rf "$tmp/fetch/$job"
  cli ann fetch "$job" "$tmp/fetch/$job" >/dev/null 2>>"$tmp/cli.log" || { echo "  fetch $job failed"; return 1; }
  for f in $(seq "$2" "$3"); do
    n=$(printf %04d "$f")
    same_pixels "$tmp/ref/$2-$3/f_$n.png" "$tmp/fetch/$job/f_$n.png" ||
      { echo "  job $job: frame $f differs from the single-process render or is missing"; return 1; }
  done
}
frames_check() {  # frames_check SCENARIO JOB FIRST LAST
  same_frames "$2" "$3" "$4" && ok "[$1] $2: frames $3-$4 identical to the single-process render" ||
    bad "[$1] $2: frames"
}
# end_checks SCENARIO: over every job of the store, each band done was
# accepted once, each job that succeeded has all its bands, none is left
# unfinished, no lease is open.
end_checks() {
  local twice short open leases
  twice=$(sql "SELECT COUNT(*) FROM bands WHERE completions > 1 OR (done = 1 AND completions <> 1)")
  short=$(sql "SELECT group_concat(id, ' ') FROM jobs j WHERE state = 'succeeded' AND
                 (SELECT COUNT(*) FROM bands b WHERE b.job_id = j.id AND b.done = 1 AND b.completions = 1)
                 <> (frame_last - frame_first + 1) * bands")
  open=$(sql "SELECT group_concat(id || ' ' || state, ', ') FROM jobs
              WHERE state NOT IN ('succeeded', 'failed', 'cancelled')")
  leases=$(sql "SELECT COUNT(*) FROM leases")
  if [ "$twice" = 0 ] && [ -z "$short" ] && [ -z "$open" ] && [ "$leases" = 0 ]; then
    ok "[$1] every band accepted exactly once ($(sql "SELECT COUNT(*) FROM bands WHERE done = 1") bands of $(sql "SELECT COUNT(*) FROM jobs") jobs), no job unfinished, no lease open"
  else
    bad "[$1] store: $twice bands accepted other than once; succeeded without all bands: '$short'; unfinished: '$open'; open leases: $leases"
  fi
}
# refused USER ACTION JOB OWNER: the action is refused, naming the owner.
refused() {
  local out rc
  out=$(cli "$1" "$2" "$3" 2>&1)
  rc=$?
  [ $rc -ne 0 ] && grep -q PERMISSION_DENIED <<<"$out" && grep -q "belongs to $4" <<<"$out" && return 0
  echo "  $1 $2 $3: exit $rc: $out"
  return 1
}

start_time=$(date +%s)
start_coordinator
start_worker w1 200; w1=$last_worker
start_worker w2 200; w2=$last_worker
wait_workers 2

# ---- 1. priorities and owners
scenario1() {
  local A B out n rc
  A=$(submit ann --frames 1-6)
  [ -n "$A" ] || { bad "[1] ann's submission"; return; }
  poll 10 leases_ge "$A" 1 || { bad "[1] $A never started"; return; }
  freeze
  out=$(cli root pause "$A" 2>&1)
  rc=$?
  thaw
  [ $rc -eq 0 ] && grep -q paused <<<"$out" && ok "[1] admin root paused ann's $A: $out" ||
    bad "[1] root pause $A: $out"
  refused bob pause "$A" ann && refused bob cancel "$A" ann && job_is "$A" paused &&
    ok "[1] bob may neither pause nor cancel ann's $A (PERMISSION_DENIED, belongs to ann)" ||
    bad "[1] bob acted on ann's $A"
  B=$(submit bob --frames 1-6 --priority 90)
  [ -n "$B" ] || { bad "[1] bob's submission"; return; }
  poll 10 done_ge "$B" 1 || { bad "[1] $B never rendered"; return; }
  restart
  n="$A $(bands_done "$A")/12, $B $(bands_done "$B")/12 bands"
  if ! job_is "$A" succeeded && ! job_is "$B" succeeded; then
    ok "[1] coordinator killed with both jobs unfinished ($n)"
  else
    bad "[1] a job had ended before the kill ($n)"
  fi
  # Resumed before the workers are back: then both jobs have bands queued.
  out=$(cli root resume "$A" 2>&1) && ok "[1] root resumed $A after the restart: $out" || bad "[1] root resume $A: $out"
  out=$(cli ann status "$B" 2>&1)
  grep -Eq 'owner +bob, priority 90' <<<"$out" &&
    [ "$(sql "SELECT owner || ' ' || priority FROM jobs WHERE id = '$B'")" = "bob 90" ] &&
    ok "[1] after the restart $B is still bob's with priority 90" || bad "[1] status $B: $out"
  refused bob pause "$A" ann && refused bob cancel "$A" ann &&
    ok "[1] after the restart bob still may neither pause nor cancel $A" || bad "[1] bob acted on $A after the restart"
  poll 30 all_succeeded "$A" "$B" || { bad "[1] $A: $(state_of "$A"), $B: $(state_of "$B") after 30 s"; return; }
  ok "[1] both jobs succeeded"
  # Priority 90 first: ann's job got no lease after the resume before
  # bob's last one.
  n=$(sql "SELECT (SELECT MIN(started_at) FROM attempts WHERE job_id = '$A' AND started_at >
                     (SELECT MAX(at) FROM history WHERE job_id = '$A' AND text LIKE 'resumed by%'))
                  >= (SELECT MAX(started_at) FROM attempts WHERE job_id = '$B')")
  [ "$n" = 1 ] && ok "[1] $B (priority 90) had every band leased before $A (priority 50) got one after its resume" ||
    bad "[1] $A got a lease while $B of priority 90 still had bands queued"
  out=$(cli ann events "$A" 2>&1)
  grep -q "paused by admin root" <<<"$out" && grep -q "resumed by admin root" <<<"$out" &&
    ok "[1] $A's history: paused by admin root, resumed by admin root" ||
    { bad "[1] $A's history does not name admin root"; grep -E 'paused|resumed' <<<"$out"; }
  frames_check 1 "$A" 1 6
  frames_check 1 "$B" 1 6
  S7_job=$A
}

# ---- 2. pause
scenario2() {
  local P n d out
  P=$(submit ann --frames 1-6)
  [ -n "$P" ] || { bad "[2] submission"; return; }
  poll 10 done_ge "$P" 2 || { bad "[2] $P: no 2 bands done"; return; }
  freeze
  out=$(cli ann pause "$P" 2>&1) || bad "[2] pause $P: $out"
  thaw
  poll 10 no_lease_open "$P" || bad "[2] $P: bands in flight did not finish after the pause"
  d=$(bands_done "$P")
  n=$(leases_of "$P")
  restart
  wait_workers 2
  out=$(cli ann status "$P" 2>&1)
  grep -q "^job $P: paused" <<<"$out" && [ "$d" -lt 12 ] && ok "[2] $P paused at $d/12 bands: still paused after the restart" ||
    bad "[2] $P after the restart ($d/12 bands done at the kill): $out"
  sleep 3  # the check itself: nothing may happen in this time
  [ "$(leases_of "$P")" = "$n" ] && ok "[2] no lease of paused $P in 3 s with the workers back ($n leases in all)" ||
    bad "[2] paused $P got $(($(leases_of "$P") - n)) leases after the restart"
  out=$(cli ann resume "$P" 2>&1) || bad "[2] resume $P: $out"
  poll 30 job_is "$P" succeeded && ok "[2] resumed $P succeeded" || { bad "[2] $P: $(state_of "$P")"; return; }
  prints "paused by ann" cli ann events "$P" && ok "[2] $P's history: paused by ann" ||
    bad "[2] $P's history lacks 'paused by ann'"
  frames_check 2 "$P" 1 6
}

# ---- 3. dependencies
scenario3() {
  local X E C D out n
  # E waits for X, which is then cancelled (X requires a tag no worker has:
  # it cannot have started).
  X=$(submit ann --frames 1-4 --require nowhere)
  E=$(submit ann --frames 1-4 --after "$X")
  [ -n "$X" ] && [ -n "$E" ] || { bad "[3] submissions"; return; }
  cli ann cancel "$X" >/dev/null 2>&1 || bad "[3] cancel $X"
  poll 10 job_is "$E" failed && grep -q "job $X, which it waits for (--after), cancelled" <<<"$(sql "SELECT error FROM jobs WHERE id = '$E'")" &&
    ok "[3] $E --after $X failed when $X was cancelled: $(sql "SELECT error FROM jobs WHERE id = '$E'")" ||
    bad "[3] $E after $X was cancelled: $(state_of "$E"): $(sql "SELECT error FROM jobs WHERE id = '$E'")"
  # C and D submitted with the workers disabled: D waits for C whatever
  # the CLI's speed.
  set_workers disable || bad "[3] disable the workers"
  C=$(submit ann --frames 1-8)
  D=$(submit ann --frames 1-4 --after "$C")
  [ -n "$C" ] && [ -n "$D" ] || { bad "[3] submissions"; set_workers enable; return; }
  out=$(cli ann status "$D" 2>&1)
  grep -q "waiting for job $C (queued)" <<<"$out" && ok "[3] $D: $(grep "waiting for" <<<"$out" | sed 's/^ *//')" ||
    bad "[3] status $D: $out"
  set_workers enable || bad "[3] enable the workers"
  poll 10 done_ge "$C" 2 || { bad "[3] $C did not start"; return; }
  restart
  n="$C $(bands_done "$C")/16 bands, $D $(leases_of "$D") leases"
  ! job_is "$C" succeeded && [ "$(leases_of "$D")" = 0 ] && ok "[3] coordinator killed while $C ran ($n)" ||
    bad "[3] at the kill: $n"
  out=$(cli ann status "$E" 2>&1)
  grep -q "^job $E: failed" <<<"$out" && grep -q "error .*job $X, which it waits for (--after), cancelled" <<<"$out" &&
    ok "[3] after the restart status $E still names $X" || bad "[3] status $E after the restart: $out"
  poll 30 all_succeeded "$C" "$D" || { bad "[3] $C: $(state_of "$C"), $D: $(state_of "$D")"; return; }
  n=$(sql "SELECT (SELECT MIN(started_at) FROM attempts WHERE job_id = '$D') >
                  (SELECT MAX(at) FROM history WHERE job_id = '$C' AND text LIKE 'frame % written%')")
  [ "$n" = 1 ] && ok "[3] both succeeded; $D's first lease came after $C's last frame was written" ||
    bad "[3] $D leased a band before $C's last frame was written"
  frames_check 3 "$C" 1 8
  frames_check 3 "$D" 1 4
}

# ---- 4. pools
scenario4() {
  local G out wb n
  G=$(submit ann --frames 1-4 --require big)
  [ -n "$G" ] || { bad "[4] submission"; return; }
  out=$(cli ann status "$G" 2>&1)
  grep -q "waiting for a worker tagged big (none is connected)" <<<"$out" &&
    ok "[4] $G: $(grep "waiting for" <<<"$out" | sed 's/^ *//')" || bad "[4] status $G: $out"
  restart
  wait_workers 2
  out=$(cli ann status "$G" 2>&1)
  grep -q "waiting for a worker tagged big (none is connected)" <<<"$out" && [ "$(leases_of "$G")" = 0 ] &&
    ok "[4] after the restart, with untagged workers back, $G still waits for a worker tagged big" ||
    bad "[4] status $G after the restart: $out"
  start_worker big 200 --tag big
  wb=$last_worker
  poll 30 job_is "$G" succeeded || { bad "[4] $G: $(state_of "$G") with a worker tagged big"; kill -9 "$wb"; return; }
  n=$(sql "SELECT COUNT(*) || ' ' || SUM(worker_name LIKE '%:$wb') FROM attempts WHERE job_id = '$G'")
  [ "${n% *}" -ge 8 ] && [ "${n% *}" = "${n#* }" ] && ok "[4] $G succeeded; all its ${n% *} leases went to the worker tagged big (pid $wb)" ||
    bad "[4] $G's leases: $n (all, by pid $wb)"
  cli ann workers 2>/dev/null | grep -E ":$wb .* big$" >/dev/null && ok "[4] locus workers lists the tag big" ||
    bad "[4] locus workers does not list the tag"
  frames_check 4 "$G" 1 4
  kill -9 "$wb"
  wait "$wb" 2>/dev/null
}

# ---- 5. band timeout
scenario5() {
  local T h1 h2 n out
  start_worker hung1 600000 --abandon-grace 600
  h1=$last_worker
  poll 20 worker_up "$h1" || bad "[5] the hung worker did not register"
  # Enough bands that some are still queued when the second hung worker
  # comes (the ordinary workers render the others meanwhile).
  T=$(submit ann --frames 1-24 --band-timeout 3)
  [ -n "$T" ] || { bad "[5] submission"; return; }
  poll 10 holding_band "$h1" "$T" || { bad "[5] the hung worker got no band of $T"; return; }
  poll 10 done_ge "$T" 2 || { bad "[5] $T: no 2 bands done"; return; }
  restart
  ! job_is "$T" succeeded && ok "[5] coordinator killed while the hung worker held a band of $T ($(bands_done "$T")/48 bands done)" ||
    bad "[5] $T ended before the kill"
  # The first hung worker learns from its next heartbeat that the restarted
  # coordinator does not know it: its band is void, and it abandons it
  # (instead of hanging on to it for ever). Then it goes; a second hung
  # worker takes a band from the restarted coordinator, whose band timeout
  # must take it back.
  poll 20 grep -q "void: the coordinator no longer knows this worker" "$tmp/worker-hung1.log" &&
    ok "[5] the first hung worker abandoned its band, void after the restart" ||
    bad "[5] the first hung worker did not hear that its band is void"
  kill -9 "$h1"
  wait "$h1" 2>/dev/null
  # The ordinary workers back first (gRPC's reconnect backoff takes up to
  # several seconds): with the hung worker alone, a farm of one, its band
  # would go back to it until the attempt limit fails the job.
  poll 20 worker_up "$w1" && poll 20 worker_up "$w2" || bad "[5] the workers did not come back"
  start_worker hung2 600000 --abandon-grace 600
  h2=$last_worker
  poll 40 job_is "$T" succeeded || bad "[5] $T: $(state_of "$T") after 40 s"
  n=$(sql "SELECT COUNT(*) FROM attempts WHERE job_id = '$T' AND worker_name LIKE '%:$h2' AND outcome = 'timed out'")
  out=$(cli ann events "$T" 2>&1)
  [ "$n" -ge 1 ] && grep -q "timed out: band hung" <<<"$out" &&
    ok "[5] $T completed; the hung band taken back by the timeout: $(grep -m1 "timed out" <<<"$out" | sed 's/^[-0-9]* [0-9:.]*  //')" ||
    bad "[5] no band of $T timed out on the hung worker (attempts: $(sql "SELECT worker_name || ' ' || COALESCE(outcome, '-') FROM attempts WHERE job_id = '$T' AND outcome <> 'done'" | tr '\n' ';'))"
  [ "$(sql "SELECT COUNT(*) FROM attempts WHERE job_id = '$T' AND worker_name LIKE '%:$h1' AND outcome = 'void'")" -ge 1 ] &&
    ok "[5] the first hung worker's lease was voided by the restart" || bad "[5] the first hung worker's lease did not end as void"
  poll 5 grep -q "revoked" "$tmp/worker-hung2.log" && ok "[5] the hung worker heard its lease was revoked" ||
    bad "[5] the hung worker was not told of the revocation"
  prints "hung .*taken back by the band timeout" cli ann status "$T" && ok "[5] locus status $T counts the hung band" ||
    bad "[5] status $T does not count the hung band"
  frames_check 5 "$T" 1 24
  kill -9 "$h2"
  wait "$h2" 2>/dev/null
}

# ---- 6. a worker killed holding a band, then the coordinator: events and logs
scenario6() {
  local K ev grants rows missing vl
  K=$(submit ann --frames 1-6)
  [ -n "$K" ] || { bad "[6] submission"; return; }
  poll 10 done_ge "$K" 2 || { bad "[6] $K did not start"; return; }
  signal_busy KILL "$w1" "$w2" || { bad "[6] no worker seen holding a band"; return; }
  wait "$victim" 2>/dev/null
  restart
  ok "[6] worker $victim killed with SIGKILL holding a band of $K, then the coordinator ($(bands_done "$K")/12 bands done)"
  if [ "$victim" = "$w1" ]; then
    start_worker w1-again 200; w1=$last_worker
  else
    start_worker w2-again 200; w2=$last_worker
  fi
  poll 30 job_is "$K" succeeded && ok "[6] $K succeeded" || { bad "[6] $K: $(state_of "$K")"; return; }
  cli ann events "$K" >"$tmp/events-$K" 2>&1 || bad "[6] locus events $K failed"
  ev=$tmp/events-$K
  grants=$(grep -cE '  lease [^ ]+: band [0-9]+ of frame [0-9]+ to worker ' "$ev")
  rows=$(leases_of "$K")
  [ "$grants" = "$rows" ] && ok "[6] locus events $K lists all $rows leases of the attempts table" ||
    bad "[6] locus events $K lists $grants leases, the attempts table has $rows"
  missing=
  while IFS='|' read -r lease outcome; do
    grep -qF "  lease $lease $outcome" "$ev" || missing+=" $lease ($outcome)"
  done < <(sql "SELECT lease_id, outcome FROM attempts WHERE job_id = '$K' ORDER BY started_at")
  [ -z "$missing" ] && ok "[6] locus events $K shows how each lease ended" ||
    bad "[6] locus events $K lacks the end of leases:$missing"
  vl=$(sql "SELECT lease_id || ' ' || outcome FROM attempts WHERE job_id = '$K' AND worker_name LIKE '%:$victim' AND outcome <> 'done'")
  if [ -n "$vl" ] && ! grep -qF "  lease ${vl%% *} done" "$ev"; then
    ok "[6] the killed worker's lease ${vl%% *} ended '${vl#* }', not done"
  else
    bad "[6] the killed worker's lease: '$vl'"
  fi
  cli ann logs "$K" >"$tmp/logs-$K" 2>&1 && ok "[6] locus logs $K answers after the restart ($(wc -l <"$tmp/logs-$K") lines)" ||
    bad "[6] locus logs $K: $(cat "$tmp/logs-$K")"
  frames_check 6 "$K" 1 6
}

# ---- 7. requeue and retry
scenario7() {
  local A=${S7_job:-} R n file out d
  if [ -z "$A" ] || ! job_is "$A" succeeded; then
    bad "[7] no finished job from scenario 1 to requeue"
  else
    file=$data/jobs/$A/f_0002.png
    [ -f "$file" ] || bad "[7] $file is missing before the test"
    rm -f "$file"
    n=$(leases_of "$A")
    # The workers frozen: a band leased to one (its long poll answered)
    # stays in its hands until the coordinator is gone.
    freeze
    out=$(cli ann requeue "$A" --frames 2-2 2>&1) || bad "[7] requeue $A: $out"
    poll 10 leases_ge "$A" $((n + 1)) || bad "[7] $A: no new lease after the requeue"
    restart
    thaw
    [ -z "$(sql "SELECT 1 FROM frames WHERE job_id = '$A' AND frame = 2")" ] &&
      ok "[7] frame 2 of $A deleted and requeued; coordinator killed while it rendered again" ||
      bad "[7] frame 2 of $A was written again before the kill (the kill came too late)"
    poll 30 job_is "$A" succeeded && [ -f "$file" ] &&
      same_pixels "$file" "$tmp/ref/1-6/f_0002.png" && ok "[7] $file is back, identical to the reference" ||
      bad "[7] $A: $(state_of "$A"); $file: $(ls "$file" 2>&1)"
    prints "frames 2-2 requeued by ann" cli ann events "$A" && ok "[7] $A's history: frames 2-2 requeued by ann" ||
      bad "[7] $A's history lacks the requeue"
    frames_check 7 "$A" 1 6
  fi
  R=$(submit ann --frames 1-6)
  [ -n "$R" ] || { bad "[7] submission"; return; }
  poll 10 done_ge "$R" 3 || { bad "[7] $R did not start"; return; }
  freeze
  out=$(cli ann cancel "$R" 2>&1)
  thaw
  job_is "$R" cancelled || { bad "[7] cancel $R: $out"; return; }
  d=$(bands_done "$R")
  restart
  [ "$d" -lt 12 ] && job_is "$R" cancelled && ok "[7] $R cancelled at $d/12 bands; still cancelled after the restart" ||
    bad "[7] $R: $(state_of "$R") at $d/12 bands"
  out=$(cli ann retry "$R" 2>&1) || bad "[7] retry $R: $out"
  poll 30 job_is "$R" succeeded && ok "[7] retried $R succeeded" || { bad "[7] $R: $(state_of "$R")"; return; }
  prints "retried by ann" cli ann events "$R" && ok "[7] $R's history: retried by ann" ||
    bad "[7] $R's history lacks the retry"
  frames_check 7 "$R" 1 6
}

# ---- 8. fair share
scenario8() {
  local jobs=() Bj j ann bob list t
  wait_workers 2
  set_workers disable || { bad "[8] disable the workers"; return; }
  for _ in $(seq 10); do jobs+=("$(submit ann --frames 1-1)"); done
  Bj=$(submit bob --frames 1-10)
  list=$(printf "'%s'," "${jobs[@]}" "$Bj")
  list=${list%,}
  [ "$(leases_of "$Bj")" = 0 ] || bad "[8] a disabled worker took a band"
  set_workers enable || bad "[8] enable the workers"
  # The window opens once both workers are back: one enabled a moment
  # before the other may take a band or two alone (equal shares go to the
  # oldest job, ann's).
  t=$(date +%s.%N)
  leases16() { [ "$(sql "SELECT COUNT(*) FROM attempts WHERE job_id IN ($list) AND started_at >= $t")" -ge 16 ]; }
  poll 20 leases16 || { bad "[8] fewer than 16 leases after 20 s"; return; }
  restart
  ok "[8] coordinator killed after 16 leases ($(sql "SELECT COUNT(*) FROM jobs WHERE id IN ($list) AND state <> 'succeeded'") of 11 jobs unfinished)"
  poll 40 all_succeeded "${jobs[@]}" "$Bj" || { bad "[8] not all 11 jobs succeeded after 40 s"; return; }
  read -r ann bob < <(sql "SELECT SUM(owner = 'ann'), SUM(owner = 'bob') FROM
                             (SELECT j.owner FROM attempts a JOIN jobs j ON j.id = a.job_id
                              WHERE a.job_id IN ($list) AND a.started_at >= $t ORDER BY a.started_at LIMIT 16)" | tr '|' ' ')
  [ "$ann" -ge 7 ] && [ "$ann" -le 9 ] && [ "$bob" -ge 7 ] && [ "$bob" -le 9 ] &&
    ok "[8] first 16 leases: ann (10 jobs) $ann, bob (1 job) $bob: each 40-60%" ||
    bad "[8] first 16 leases: ann $ann, bob $bob (each must be 7-9)"
  for j in "${jobs[@]}"; do same_frames "$j" 1 1 >/dev/null || { bad "[8] $j: frame"; return; }; done
  ok "[8] all 11 jobs succeeded; ann's 10 frames identical to the reference"
  frames_check 8 "$Bj" 1 10
}

for s in 1 2 3 4 5 6 7 8; do
  t0=$(date +%s)
  "scenario$s"
  end_checks "$s"
  echo "  (scenario $s: $(($(date +%s) - t0)) s)"
done

kill -TERM "$w1" "$w2" 2>/dev/null
kill -TERM "$coord"
wait "$coord" && ok "coordinator exits cleanly on SIGTERM after $restarts restarts" || bad "coordinator exit status"
echo "$passed passed, $failed failed ($(($(date +%s) - start_time)) s)"
[ "$failed" -eq 0 ]

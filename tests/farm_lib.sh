# Helpers the farm's process tests share (sourced by tests/faults/run.sh,
# tests/farm_operations.sh, tests/farm_processes.sh, tests/backup/run.sh,
# tests/cost_map/run.sh and tests/slurm/run.sh). For signal_busy, the caller defines holding_band PID:
# whether that worker (named host:PID) holds a lease now.

# same_pixels A B: both images exist and hold the same pixels, exactly
# (idiff, max error 0). Not the same bytes: a PNG frame the coordinator
# joins from its bands' deflate streams (docs/farm.md "Frames") is
# compressed otherwise than a single-process render's.
same_pixels() {
  idiff -fail 0 -warn 0 "$1" "$2" >/dev/null 2>&1
}

# listening_port OUT: the port a coordinator started with --listen HOST:0
# prints on its stdout (OUT, the line "listening on port N"), waited for up
# to 5 s; empty when none came.
listening_port() {
  local port=
  for _ in $(seq 100); do
    port=$(sed -n 's/^listening on port //p' "$1" 2>/dev/null)
    [ -n "$port" ] && break
    sleep 0.05
  done
  echo "$port"
}

# signal_busy SIG PID...: freezes each worker in turn and sends SIG to the
# first one seen holding a band (frozen, it cannot finish it meanwhile);
# sets $victim. Status 1 when none was seen holding one within about 2 s.
signal_busy() {
  local sig=$1 p
  shift
  victim=
  for _ in $(seq 100); do
    for p in "$@"; do
      kill -STOP "$p"
      if holding_band "$p"; then
        victim=$p
        kill "-$sig" "$p"
        kill -CONT "$p"
        return 0
      fi
      kill -CONT "$p"
    done
    sleep 0.02
  done
  return 1
}

# prints PATTERN CMD...: CMD succeeds and its whole output matches PATTERN
# (grep -E). Not `CMD | grep -q`: grep -q stops reading at the first match,
# and when CMD writes again after that it dies of SIGPIPE, which pipefail
# counts as the pipeline failing: a test that fails by chance.
prints() {
  local pattern=$1 out
  shift
  out=$("$@" 2>/dev/null) || return 1
  grep -Eq -- "$pattern" <<<"$out"
}

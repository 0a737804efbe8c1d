# Helpers the farm's process tests share (sourced by tests/faults/run.sh
# and tests/farm_operations.sh). The caller defines holding_band PID: whether
# that worker (named host:PID) holds a lease now.

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

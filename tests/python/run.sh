#!/usr/bin/env bash
# run.sh BINDIR SOURCE_DIR BUILD_DIR: the Python client (client/python,
# docs/python.md) against a real farm on 127.0.0.1: a coordinator
# (plaintext with --insecure, but with client tokens for two users, ann and
# bob, and a worker token) and 2 workers, plus a TLS coordinator without
# workers (certificates from tests/tls/make_certs.sh), then
# tests/python/test_client.py with PYTHONPATH=BUILD_DIR/python. No skip: a
# missing grpcio or missing stubs are failures.
set -uo pipefail
bin=$1 src=$2 build=$3
python=${LOCUS_PYTHON3:-/usr/bin/python3}
tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null; done
  wait 2>/dev/null
  rm -rf "$tmp"
}
trap cleanup EXIT

if ! "$python" -c 'import grpc, google.protobuf' 2>"$tmp/err"; then
  echo "FAILED: $python cannot import grpc and google.protobuf: apt-get install python3-grpcio" \
    "python3-protobuf (deploy/local/install-deps.sh)"
  cat "$tmp/err"
  exit 1
fi
if [ ! -f "$build/python/locus/proto/locus_pb2_grpc.py" ]; then
  echo "FAILED: no generated stubs in $build/python/locus/proto (build the locus_python target)"
  exit 1
fi

token() { head -c 16 /dev/urandom | od -An -tx1 | tr -d ' \n'; }
ann=$(token) bob=$(token) worker=$(token)
printf '# client tokens\nann %s\nbob %s\n' "$ann" "$bob" >"$tmp/client.tokens"
printf '%s\n' "$worker" >"$tmp/worker.tokens"
chmod 600 "$tmp/client.tokens" "$tmp/worker.tokens"

# start_coordinator NAME FLAGS...: a coordinator on an ephemeral port of
# 127.0.0.1; sets $port from its stdout line "listening on port N".
start_coordinator() {
  local name=$1
  shift
  "$bin/locus-coordinator" --listen 127.0.0.1:0 --data "$tmp/$name-data" --no-fsync \
    --client-tokens "$tmp/client.tokens" --worker-tokens "$tmp/worker.tokens" "$@" \
    >"$tmp/$name.out" 2>"$tmp/$name.log" &
  pids+=($!)
  port=
  for _ in $(seq 200); do
    port=$(sed -n 's/^listening on port //p' "$tmp/$name.out")
    [ -n "$port" ] && return 0
    sleep 0.05
  done
  echo "FAILED: the coordinator ($name) did not start"
  cat "$tmp/$name.log"
  exit 1
}

# The farm the tests render on: plaintext, tokens checked.
start_coordinator coord --insecure --lease-ms 3000 --heartbeat-ms 300
farm_port=$port
# A TLS coordinator without workers, for the client's TLS rules.
bash "$src/tests/tls/make_certs.sh" "$tmp/tls"
# gRPC's handshake trace, so that a failed TLS handshake says why on the
# server's side too (CI once saw "Handshake read failed" from the client).
GRPC_VERBOSITY=DEBUG GRPC_TRACE=handshaker \
  start_coordinator tls --tls-cert "$tmp/tls/server.pem" --tls-key "$tmp/tls/server.key"
tls_port=$port
for i in 1 2; do
  LOCUS_TOKEN=$worker "$bin/locus-worker" --coordinator "127.0.0.1:$farm_port" --threads 1 \
    2>"$tmp/worker$i.log" &
  pids+=($!)
done

export PYTHONPATH=$build/python
export LOCUS_TEST_FARM=127.0.0.1:$farm_port LOCUS_TEST_BIN=$bin LOCUS_TEST_SOURCE=$src
export LOCUS_TEST_TLS_FARM=127.0.0.1:$tls_port LOCUS_TEST_TLS=$tmp/tls
export LOCUS_TEST_TMP=$tmp LOCUS_TEST_ANN=$ann LOCUS_TEST_BOB=$bob LOCUS_TEST_WORKER=$worker
unset LOCUS_TOKEN LOCUS_FARM
# gRPC core's own log lines (the TLS tests' failed handshakes, on purpose)
# would only look like failures here; the tests check the errors.
export PYTHONDONTWRITEBYTECODE=1 GRPC_VERBOSITY=NONE
"$python" "$src/tests/python/test_client.py" 2>&1
rc=$?
if [ $rc -ne 0 ]; then
  echo "---- coordinator log (last 40 lines)"
  tail -40 "$tmp/coord.log"
  echo "---- TLS coordinator log (last 80 lines)"
  tail -80 "$tmp/tls.log"
  echo "---- sockets on the TLS port $tls_port"
  ss -tanp | grep -F ":$tls_port " || true
fi
exit $rc

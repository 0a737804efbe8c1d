#!/usr/bin/env bash
# tests/container/run.sh BINDIR SOURCE: the farm in containers (CTest
# `container_farm`, label container). Builds the two images
# (deploy/docker/Dockerfile, on a Debian 12 base made by
# deploy/docker/make-base.sh; the worker's must stay within
# LOCUS_WORKER_IMAGE_MIB, 250 MiB), runs a coordinator and 2 workers with
# deploy/compose.yaml (TLS, worker certificates and tokens, as secrets),
# submits a 3-frame job from this host through the coordinator's port
# published on 127.0.0.1, and checks:
#   - the frames equal a local render (`locus render --workers 0`) exactly
#     (linear float EXR, max error 0);
#   - `locus workers` lists the two containers;
#   - GET /metrics answers with every series docs/deploy.md lists;
#   - the dashboard answers on its published HTTPS port: the page, 401
#     without a token, the job with a client token;
#   - Docker's HEALTHCHECK (`locus health`, `locus-worker health`) says
#     healthy, the worker's health service answers inside its container,
#     logs are JSON lines with band ids, the containers run as uid 10001;
#   - SIGTERM drains the coordinator, which exits 0.
# No Docker daemon running: starts Debian's dockerd (root), with its
# networks in 10.79.0.0/16, and stops it at the end. No skip: an engine
# that cannot start or run a container fails the test. Traffic: the
# containers talk on their own bridge network; this host reaches the
# coordinator on 127.0.0.1 only; image builds use the host's network for
# Debian's mirror. Prints each phase's time and "N passed, M failed".
#
# tests/container/run.sh --prepare BINDIR SOURCE: the engine and the images
# only (tests/run.sh starts it in the background after its Release build,
# so that debootstrap and apt, which mostly wait on the network and dpkg,
# overlap the sanitizer and fuzz builds; the test itself then finds every
# layer cached).
#
# The images hold BINDIR's binaries (the Dockerfile's `prebuilt` stage: the
# same sources built on this Debian 12 host; the runtime packages found
# here by deploy/docker/runtime-packages.sh), so that CI compiles the
# sources once, not again inside the image build. LOCUS_CONTAINER_FROM_SOURCE=1
# builds them from the sources as a user does (the Dockerfile's build
# stages; about 20 more minutes of compile on 2 cores).
set -uo pipefail
prepare=
if [ "${1:-}" = --prepare ]; then
  prepare=1
  shift
fi
src=$(cd "$2" && pwd)
[ -n "$prepare" ] || bin=$(cd "$1" && pwd)
tag=${LOCUS_TEST_TAG:-test}
# Debian's python3, with its numpy and OpenImageIO (install-deps.sh).
py=/usr/bin/python3
[ -x "$py" ] || py=python3
base=${LOCUS_BASE:-locus-debian:12}
start=$SECONDS
phase() { echo "container: $1 ($((SECONDS - start)) s)"; }
passed=0 failed=0
ok() { echo "ok: $1"; passed=$((passed + 1)); }
bad() { echo "FAILED: $1"; failed=$((failed + 1)); }
# No engine is a failure, not a skip: CI runs this test everywhere.
no_engine() {
  bad "container engine: $1"
  echo "$passed passed, $failed failed"
  exit 1
}

# Debian's client with Debian's daemon, where both are installed.
docker=${DOCKER:-docker}
[ -z "${DOCKER:-}" ] && [ -x /usr/bin/docker ] && docker=/usr/bin/docker
export DOCKER=$docker
command -v "$docker" >/dev/null || no_engine "no docker client (deploy/local/install-deps.sh installs docker.io)"
command -v docker-compose >/dev/null || no_engine "no docker-compose (deploy/local/install-deps.sh installs it)"

tmp=$(mktemp -d /var/tmp/locus-container-test.XXXXXX)
dockerd_pid=
project=locustest$$
compose() {
  docker-compose -f "$src/deploy/compose.yaml" -p "$project" "$@"
}
cleanup() {
  if [ -n "${compose_up:-}" ]; then
    compose down -v --remove-orphans >/dev/null 2>&1
  fi
  if [ -n "$dockerd_pid" ]; then
    kill "$dockerd_pid" 2>/dev/null
    wait "$dockerd_pid" 2>/dev/null
  fi
  rm -rf "$tmp"
}
trap cleanup EXIT
trap 'exit 143' TERM INT

# ---- the engine
if ! "$docker" info >/dev/null 2>&1; then
  command -v dockerd >/dev/null || no_engine "no Docker daemon running, and no dockerd to start"
  [ "$(id -u)" -eq 0 ] || no_engine "no Docker daemon running, and starting dockerd needs root"
  log=/var/log/locus-test-dockerd.log
  setsid dockerd --bip 10.79.0.1/24 --default-address-pool base=10.79.0.0/16,size=24 \
    </dev/null >"$log" 2>&1 &
  dockerd_pid=$!
  for _ in $(seq 120); do
    "$docker" info >/dev/null 2>&1 && break
    kill -0 "$dockerd_pid" 2>/dev/null || break
    sleep 0.5
  done
  if ! "$docker" info >/dev/null 2>&1; then
    tail -5 "$log"
    no_engine "dockerd could not start here (see $log)"
  fi
  phase "started dockerd (pid $dockerd_pid)"
fi

# ---- the images
bash "$src/deploy/docker/make-base.sh" "$base" || { bad "base image $base"; exit 1; }
phase "base image $base"
if ! "$docker" run --rm --network none "$base" true 2>"$tmp/run.err"; then
  cat "$tmp/run.err"
  no_engine "the engine cannot run a container here"
fi
# The two targets side by side, with BuildKit (the engine's own builder):
# it runs independent stages at once and shares the steps both builds have
# in common, so the worker's image (its compile a part of the
# coordinator's) is done while the coordinator's compile goes on.
binaries=()
if [ "${LOCUS_CONTAINER_FROM_SOURCE:-0}" = 1 ]; then
  phase "images from the sources (LOCUS_CONTAINER_FROM_SOURCE=1)"
else
  # build/docker-bin/: the binaries and the packages that own the
  # libraries they load, as the build stages would make them.
  stage=$src/build/docker-bin
  rm -rf "$stage"
  mkdir -p "$stage/worker" "$stage/coordinator"
  bin_dir=$(cd "$1" && pwd) || { bad "no binaries in $1"; exit 1; }
  mkdir -p "$stage/coordinator/lib"
  cp "$bin_dir/locus-worker" "$stage/worker/" &&
    cp "$bin_dir/locus" "$bin_dir/locus-coordinator" "$bin_dir/locus-worker" "$stage/coordinator/" &&
    cp "$bin_dir/../lib/locus/liblocus-image-io.so" "$stage/coordinator/lib/" &&
    bash "$src/deploy/docker/runtime-packages.sh" "$stage/worker/locus-worker" >"$stage/worker/packages" &&
    bash "$src/deploy/docker/runtime-packages.sh" "$stage/coordinator/locus" \
      "$stage/coordinator/locus-coordinator" "$stage/coordinator/locus-worker" \
      "$stage/coordinator/lib/liblocus-image-io.so" >"$stage/coordinator/packages" ||
    { bad "staging the binaries of $1 for the images"; exit 1; }
  binaries=(--build-arg WORKER_BINARIES=prebuilt --build-arg COORDINATOR_BINARIES=prebuilt)
  phase "binaries of $bin_dir staged"
fi
build_pids=()
for target in worker coordinator; do
  DOCKER_BUILDKIT=1 "$docker" build --progress plain --network host -f "$src/deploy/docker/Dockerfile" \
    --build-arg "BASE=$base" "${binaries[@]}" --target "$target" -t "locus-$target:$tag" "$src" \
    >"$tmp/build-$target.log" 2>&1 &
  build_pids+=($!)
done
built=0
for i in 0 1; do
  target=$([ "$i" = 0 ] && echo worker || echo coordinator)
  if wait "${build_pids[$i]}"; then
    built=$((built + 1))
  else
    tail -40 "$tmp/build-$target.log"
    echo "FAILED: docker build --target $target"
  fi
  # Where the time went: the build's steps of 10 s or more.
  awk -v t="$target" '/^#[0-9]+ \[/ { name[$1] = substr($0, length($1) + 2, 70) }
    /^#[0-9]+ DONE/ && $3 + 0 >= 10 { printf "container: %s build: %s %s\n", t, $3, name[$1] }' \
    "$tmp/build-$target.log"
done
[ "$built" -eq 2 ] || { bad "docker build"; echo "$passed passed, $failed failed"; exit 1; }
mib() { echo $(("$("$docker" image inspect -f '{{.Size}}' "$1")" / 1048576)); }
ok "images built: locus-coordinator:$tag ($(mib "locus-coordinator:$tag") MiB), locus-worker:$tag"
phase "images built"
# Every node of a worker pool pulls the worker's image: it holds
# locus-worker and the libraries it loads, nothing of the coordinator's.
limit=${LOCUS_WORKER_IMAGE_MIB:-250}
size=$("$docker" image inspect -f '{{.Size}}' "locus-worker:$tag")
if [ "$size" -le $((limit * 1048576)) ]; then
  ok "the worker's image is $((size / 1048576)) MiB (at most $limit)"
else
  bad "the worker's image is $((size / 1048576)) MiB, over $limit"
fi
if [ -n "$prepare" ]; then
  echo "$passed passed, $failed failed"
  exit 0
fi

# ---- secrets: certificates (the coordinator's names the service
# `coordinator`, which the workers dial, and 127.0.0.1), tokens
bash "$src/tests/tls/make_certs.sh" "$tmp/tls" DNS:coordinator
sec=$tmp/secrets
mkdir -p "$sec"
cp "$tmp/tls/ca.pem" "$tmp/tls/server.pem" "$tmp/tls/server.key" "$sec/"
cp "$tmp/tls/client.pem" "$sec/worker.pem"
cp "$tmp/tls/client.key" "$sec/worker.key"
client_token=$(head -c 16 /dev/urandom | od -An -tx1 | tr -d ' \n')
worker_token=$(head -c 16 /dev/urandom | od -An -tx1 | tr -d ' \n')
echo "$client_token" >"$sec/client.tokens"
echo "$worker_token" >"$sec/worker.tokens"
echo "$worker_token" >"$sec/worker.token"
# The containers' user reads them; nobody else.
chown 10001:10001 "$sec"/*
chmod 600 "$sec"/*
free_port() { "$py" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
port=$(free_port)
metrics_port=$(free_port)
http_port=$(free_port)
export LOCUS_SECRETS=$sec LOCUS_TAG=$tag LOCUS_PUBLISH=127.0.0.1 LOCUS_PORT=$port \
  LOCUS_METRICS_PORT=$metrics_port LOCUS_HTTP_PORT=$http_port LOCUS_LOG_FORMAT=json

# ---- a coordinator and 2 workers
compose_up=1
if ! compose up -d --no-build --scale worker=2 >"$tmp/up.log" 2>&1; then
  cat "$tmp/up.log"
  bad "docker-compose up"
  echo "$passed passed, $failed failed"
  exit 1
fi
farm=(--farm "127.0.0.1:$port" --tls-ca "$tmp/tls/ca.pem")
export LOCUS_TOKEN=$client_token
for _ in $(seq 120); do
  [ "$("$bin/locus" workers "${farm[@]}" 2>/dev/null | grep -c '^w[0-9]')" -ge 2 ] && break
  sleep 0.5
done
phase "farm up"
"$bin/locus" health "127.0.0.1:$port" --tls-ca "$tmp/tls/ca.pem" >/dev/null &&
  ok "coordinator ready (health service on its published TLS port)" || bad "coordinator health"

# ---- a 3-frame job from this host, and the same job rendered here
scene=$src/scenes/anim/glass_and_mirror.json
job=(--frames 1-3 --size 160x120)
if "$bin/locus" submit "$scene" "${job[@]}" "${farm[@]}" -o "$tmp/farm/anim_####.exr" --wait \
  >"$tmp/submit.out" 2>"$tmp/submit.err"; then
  ok "3-frame job rendered by the containers: $(head -1 "$tmp/submit.out")"
else
  bad "submit --wait"
  tail -5 "$tmp/submit.err"
fi
phase "job done"
"$bin/locus" render "$scene" "${job[@]}" --workers 0 -o "$tmp/local/anim_####.exr" 2>"$tmp/local.err" ||
  { bad "local render"; cat "$tmp/local.err"; }
if "$py" - "$tmp/farm" "$tmp/local" <<'EOF'; then
import sys
import numpy as np
import OpenImageIO as oiio
worst = 0.0
for f in (1, 2, 3):
    a, b = (oiio.ImageBuf(f"{d}/anim_{f:04d}.exr") for d in sys.argv[1:3])
    pa, pb = a.get_pixels(oiio.FLOAT), b.get_pixels(oiio.FLOAT)
    if pa is None or pb is None or pa.shape != pb.shape:
        sys.exit(f"frame {f}: missing or of another size")
    worst = max(worst, float(np.max(np.abs(pa - pb))))
print(f"frames 1-3: max error {worst}")
sys.exit(0 if worst == 0 else 1)
EOF
  ok "frames identical to a local render (--workers 0)"
else
  bad "frames differ from the local render"
fi

# ---- the workers, by their containers' host names
"$bin/locus" workers "${farm[@]}" >"$tmp/workers.out" 2>&1
cat "$tmp/workers.out"
found=0
for id in $(compose ps -q worker); do
  host=$("$docker" inspect -f '{{.Config.Hostname}}' "$id")
  grep -q " $host:" "$tmp/workers.out" && found=$((found + 1))
done
[ "$found" -eq 2 ] && [ "$(grep -c '^w[0-9]' "$tmp/workers.out")" -eq 2 ] &&
  ok "locus workers lists the 2 container workers" || bad "locus workers: $found of 2 containers listed"

# ---- metrics through the published port
if "$py" - "$metrics_port" <<'EOF'; then
import re, sys, urllib.request
text = urllib.request.urlopen(f"http://127.0.0.1:{sys.argv[1]}/metrics", timeout=10).read().decode()
want = [
    'locus_bands{state="queued"}', 'locus_bands{state="running"}', 'locus_bands{state="done"}',
    'locus_jobs{state="queued"}', 'locus_jobs{state="running"}', 'locus_jobs{state="succeeded"}',
    'locus_jobs{state="failed"}', 'locus_jobs{state="cancelled"}', 'locus_workers_connected',
    'locus_band_render_seconds_bucket', 'locus_band_render_seconds_count',
    'locus_band_failures_total', 'locus_band_retries_total', 'locus_bands_completed_total',
    'locus_rpc_received_bytes_total', 'locus_rpc_sent_bytes_total',
]
values = {}
for line in text.splitlines():
    if line and not line.startswith("#"):
        series, value = line.rsplit(" ", 1)
        values[series] = float(value)
missing = [w for w in want if not any(s == w or s.startswith(w + "{") or s.startswith(w) for s in values)]
if missing:
    sys.exit(f"missing series: {missing}")
checks = {'locus_jobs{state="succeeded"}': 1, 'locus_workers_connected': 2,
          'locus_bands{state="queued"}': 0, 'locus_bands{state="running"}': 0}
wrong = {k: values.get(k) for k, v in checks.items() if values.get(k) != v}
if wrong:
    sys.exit(f"unexpected values: {wrong}")
done = values['locus_bands{state="done"}']
if done < 3 or values["locus_band_render_seconds_count"] != done:
    sys.exit(f"bands done {done}, band seconds observed {values['locus_band_render_seconds_count']}")
print(f"metrics: {len(values)} samples, {int(done)} bands done")
EOF
  ok "GET /metrics (127.0.0.1:$metrics_port) answers with every listed series"
else
  bad "metrics"
fi

# ---- the dashboard through its published HTTPS port, with the TLS port's
# certificate: the page for anyone, the API with a client token only
if "$py" - "$http_port" "$tmp/tls/ca.pem" "$client_token" <<'EOF'; then
import json, ssl, sys, urllib.error, urllib.request
port, ca, token = sys.argv[1:4]
ctx = ssl.create_default_context(cafile=ca)
base = f"https://127.0.0.1:{port}"
page = urllib.request.urlopen(base + "/", context=ctx, timeout=10)
if "script-src 'self'" not in page.headers.get("Content-Security-Policy", ""):
    sys.exit("the page has no Content-Security-Policy")
try:
    urllib.request.urlopen(base + "/api/v1/jobs", context=ctx, timeout=10)
    sys.exit("the API answered without a token")
except urllib.error.HTTPError as e:
    if e.code != 401 or b"j0001" in e.read():
        sys.exit(f"without a token: {e.code}")
req = urllib.request.Request(base + "/api/v1/jobs", headers={"Authorization": "Bearer " + token})
jobs = json.loads(urllib.request.urlopen(req, context=ctx, timeout=10).read())["jobs"]
if not jobs or jobs[0]["state"] != "JOB_STATE_SUCCEEDED":
    sys.exit(f"jobs: {jobs}")
print(f"dashboard: {len(jobs)} job(s) over HTTPS")
EOF
  ok "the dashboard (https://127.0.0.1:$http_port): the page, 401 without a token, the job with one"
else
  bad "dashboard"
fi

# ---- health checks, logs, user
healthy=0
for _ in $(seq 60); do
  healthy=0
  for id in $(compose ps -q); do
    [ "$("$docker" inspect -f '{{.State.Health.Status}}' "$id")" = healthy ] && healthy=$((healthy + 1))
  done
  [ "$healthy" -eq 3 ] && break
  sleep 1
done
[ "$healthy" -eq 3 ] && ok "Docker HEALTHCHECK: 3 containers healthy" || bad "HEALTHCHECK: $healthy of 3 healthy"
compose exec -T --index=1 worker locus-worker health 127.0.0.1:7001 --service liveness >/dev/null &&
  ok "a worker's health service answers in its container" || bad "worker health in its container"
[ "$(compose exec -T coordinator id -u | tr -d '\r')" = 10001 ] &&
  [ "$(compose exec -T --index=1 worker id -u | tr -d '\r')" = 10001 ] &&
  ok "the coordinator and the workers run as uid 10001" || bad "the containers' user"
# The coordinator makes movies (--movie): its image carries ffmpeg with H.264.
encoders=$(compose exec -T coordinator ffmpeg -hide_banner -encoders 2>/dev/null)
grep -q libx264 <<<"$encoders" &&
  ok "the coordinator's image has ffmpeg with libx264 (movies)" || bad "no ffmpeg in the coordinator's image"
compose logs --no-color worker >"$tmp/worker.log" 2>&1
if "$py" - "$tmp/worker.log" <<'EOF'; then
import json, sys
with_band = 0
for line in open(sys.argv[1]):
    if "|" not in line:
        continue
    entry = json.loads(line.split("|", 1)[1])  # every line must be one JSON object
    with_band += all(k in entry for k in ("job", "frame", "band"))
sys.exit(0 if with_band > 0 else "no line carries job, frame and band")
EOF
  ok "worker logs: JSON lines, with job, frame and band ids"
else
  bad "worker logs"
  tail -5 "$tmp/worker.log"
fi

# ---- SIGTERM drains the coordinator, which exits 0
compose stop -t 30 coordinator >/dev/null 2>&1
cid=$(compose ps -q coordinator)
code=$("$docker" inspect -f '{{.State.ExitCode}}' "$cid")
compose logs --no-color coordinator >"$tmp/coordinator.log" 2>&1
[ "$code" = 0 ] && grep -q '"msg":"drained' "$tmp/coordinator.log" &&
  ok "SIGTERM: the coordinator drained and exited 0" ||
  { bad "coordinator stop: exit $code"; tail -5 "$tmp/coordinator.log"; }
compose down -v --remove-orphans >/dev/null 2>&1
compose_up=
phase "done"
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]

#!/usr/bin/env bash
# tests/dashboard/run.sh BINDIR SOURCE_DIR [OUT_DIR]: the dashboard in a real
# browser (issue #24). Debian's chromium, headless, driven by python3-selenium
# through chromium-driver, with a coordinator (--http) and three workers, all
# inside a network namespace made here with nothing but a loopback
# interface: chromium's own traffic (updates, safe browsing, metrics) has
# nowhere to go, and every address used is 127.0.0.1 inside it.
#
# The job: scene (d) of the paper, 24 frames of 320x240, 16 bands each, on
# two workers that take 80 ms per band (--test-slow-band-ms) and one that
# hangs on its first band (--band-timeout 2 takes it back: a retried band).
# One worker's name is markup. tests/dashboard/browser_test.py then checks
# the pages (see there) and saves a screenshot of each in OUT_DIR (default
# BINDIR/../dashboard-screens). Fails, never skips, when the browser or the
# namespace cannot start.
set -uo pipefail
bin=$(cd "$1" && pwd)
src=$(cd "$2" && pwd)
out=${3:-$bin/../dashboard-screens}
mkdir -p "$out"
out=$(cd "$out" && pwd)

fail() {
  echo "FAILED: $1"
  exit 1
}
[ "$(id -u)" -eq 0 ] || fail "needs root, for its network namespace"
for tool in ip chromium chromedriver; do
  command -v $tool >/dev/null || fail "$tool is missing (deploy/local/install-deps.sh)"
done
/usr/bin/python3 -c "import selenium, numpy, PIL" 2>/dev/null ||
  fail "python3-selenium, python3-numpy or python3-pil is missing (deploy/local/install-deps.sh)"

ns=locusdash$$
tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null; done
  wait 2>/dev/null
  ip netns pids $ns 2>/dev/null | xargs -r kill -9 2>/dev/null
  ip netns del $ns 2>/dev/null
  if [ -n "${KEEP:-}" ]; then echo "kept $tmp"; else rm -rf "$tmp"; fi
}
trap cleanup EXIT
ip netns add $ns || fail "ip netns add failed (no CAP_SYS_ADMIN?)"
ip -n $ns link set lo up || fail "cannot bring up lo in $ns"
in_ns() { ip netns exec $ns "$@"; }

# Tokens: ann and bob (clients), root (admin), the workers'.
for u in ann bob root worker; do
  printf '%s-token-%s%s\n' $u $RANDOM$RANDOM $RANDOM$RANDOM >"$tmp/$u.tok"
done
chmod 600 "$tmp"/*.tok
printf 'ann %s\nbob %s\n' "$(cat "$tmp/ann.tok")" "$(cat "$tmp/bob.tok")" >"$tmp/clients"
printf 'root %s\n' "$(cat "$tmp/root.tok")" >"$tmp/admins"
chmod 600 "$tmp/clients" "$tmp/admins"

farm=127.0.0.1:7070
in_ns "$bin/locus-coordinator" --listen $farm --http 127.0.0.1:7080 --data "$tmp/data" --insecure \
  --client-tokens "$tmp/clients" --admin-tokens "$tmp/admins" --worker-tokens "$tmp/worker.tok" \
  --lease-ms 2000 --heartbeat-ms 300 --always-cost-bands \
  >"$tmp/coordinator.out" 2>"$tmp/coordinator.log" &
pids+=($!)
locus() { in_ns "$bin/locus" "$@" --farm $farm --token-file "$tmp/ann.tok"; }
for _ in $(seq 100); do
  locus workers >/dev/null 2>&1 && break
  sleep 0.1
done
locus workers >/dev/null 2>&1 || { cat "$tmp/coordinator.log"; fail "the coordinator did not start"; }

# Each worker's pid is its own (exec, twice: the subshell becomes `ip netns
# exec`, which becomes the worker), so that killing the hung one kills it.
worker() {  # worker NAME MS_PER_BAND
  (exec ip netns exec $ns "$bin/locus-worker" --coordinator $farm --token-file "$tmp/worker.tok" \
    --threads 1 --name "$1" --test-slow-band-ms "$2" --abandon-grace 1 >>"$tmp/workers.log" 2>&1) &
  pids+=($!)
}
# The hung worker first, so that it takes the first band.
worker hung-worker 600000
hung=${pids[-1]}
for _ in $(seq 100); do
  [ "$(locus workers 2>/dev/null | grep -c hung-worker)" -ge 1 ] && break
  sleep 0.05
done
job=$(locus submit "$src/scenes/paper/d_spheres_2lights.json" --size 320x240 --frames 1-24 \
  --bands 16 --band-timeout 2 -o "shot_####.png" 2>>"$tmp/client.log") ||
  { cat "$tmp/client.log"; fail "submit"; }
for _ in $(seq 100); do
  [ "$(locus events "$job" 2>/dev/null | grep -c "(hung-worker)")" -ge 1 ] && break
  sleep 0.05
done
worker render-1 80
worker '<img src=x onerror="window.xss=1">' 80

echo "job $job; dashboard at http://127.0.0.1:7080 in namespace $ns"
in_ns /usr/bin/python3 "$src/tests/dashboard/browser_test.py" --url http://127.0.0.1:7080 \
  --farm $farm --bin "$bin" --tokens "$tmp" --job "$job" --hung-pid "$hung" --out "$out" \
  --work "$tmp" --scene "$src/scenes/simple/spheres.json"
rc=$?

# HTTPS: a second coordinator with TLS serves the dashboard with the gRPC
# port's certificate (made here); the page, 401 without a token, data with.
bash "$src/tests/tls/make_certs.sh" "$tmp/tls" >/dev/null 2>&1 || fail "make_certs.sh"
in_ns "$bin/locus-coordinator" --listen 127.0.0.1:7071 --http 127.0.0.1:7081 --data "$tmp/data-tls" \
  --tls-cert "$tmp/tls/server.pem" --tls-key "$tmp/tls/server.key" \
  --client-tokens "$tmp/clients" --worker-tokens "$tmp/worker.tok" >/dev/null 2>"$tmp/tls.log" &
pids+=($!)
if in_ns /usr/bin/python3 - "$tmp/tls/ca.pem" "$(cat "$tmp/ann.tok")" <<'PY'; then
import json, ssl, sys, time, urllib.error, urllib.request
ctx = ssl.create_default_context(cafile=sys.argv[1])
base = "https://127.0.0.1:7081"
for _ in range(100):
    try:
        page = urllib.request.urlopen(base + "/", context=ctx, timeout=5)
        break
    except OSError:
        time.sleep(0.1)
else:
    sys.exit("the TLS coordinator's dashboard did not answer")
assert "script-src 'self'" in page.headers["Content-Security-Policy"]
try:
    urllib.request.urlopen(base + "/api/v1/farm", context=ctx, timeout=5)
    sys.exit("data without a token")
except urllib.error.HTTPError as e:
    assert e.code == 401, e.code
req = urllib.request.Request(base + "/api/v1/farm", headers={"Authorization": "Bearer " + sys.argv[2]})
farm = json.loads(urllib.request.urlopen(req, context=ctx, timeout=5).read())
assert farm["jobs"] == [], farm
PY
  echo "ok: HTTPS with the gRPC port's certificate: the page, 401 without a token, the farm with one"
else
  echo "FAILED: the dashboard over HTTPS"; tail -5 "$tmp/tls.log"; rc=1
fi
if [ $rc -ne 0 ]; then
  echo "--- coordinator log (tail)"; tail -n 30 "$tmp/coordinator.log"
  echo "--- workers log (tail)"; tail -n 30 "$tmp/workers.log"
fi
exit $rc

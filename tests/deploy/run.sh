#!/usr/bin/env bash
# tests/deploy/run.sh SOURCE: the deployment files without running them
# (CTest `deploy_manifests`):
#   - deploy/compose.yaml: `docker-compose config -q` (Debian's docker-compose);
#   - deploy/k8s: rendered with `kubectl kustomize` where kubectl is
#     installed (alone, and with the queue-depth component), with secrets
#     made here; each rendering and the sources themselves go through the
#     schema test tests/deploy/check_manifests.py.
# Prints one line per check and "N passed, M failed".
set -uo pipefail
src=$(cd "$1" && pwd)
py=/usr/bin/python3
[ -x "$py" ] || py=python3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
passed=0 failed=0
ok() { echo "ok: $1"; passed=$((passed + 1)); }
bad() { echo "FAILED: $1"; failed=$((failed + 1)); }

# The files the compose file and the kustomization read.
secrets=$tmp/k8s/secrets
cp -r "$src/deploy/k8s" "$tmp/k8s"
bash "$src/tests/tls/make_certs.sh" "$tmp/tls" DNS:locus-coordinator,DNS:locus-coordinator.locus.svc
cp "$tmp/tls/ca.pem" "$tmp/tls/server.pem" "$tmp/tls/server.key" "$secrets/"
cp "$tmp/tls/client.pem" "$secrets/worker.pem"
cp "$tmp/tls/client.key" "$secrets/worker.key"
echo client-token >"$secrets/client.tokens"
echo worker-token >"$secrets/worker.tokens"
echo worker-token >"$secrets/worker.token"

if command -v docker-compose >/dev/null; then
  LOCUS_SECRETS=$secrets docker-compose -f "$src/deploy/compose.yaml" config -q 2>"$tmp/compose.err" &&
    ok "docker-compose config -q deploy/compose.yaml" || { bad "compose file"; cat "$tmp/compose.err"; }
else
  bad "docker-compose is not installed (deploy/local/install-deps.sh installs it)"
fi

"$py" "$src/tests/deploy/check_manifests.py" --raw "$src/deploy/k8s" &&
  ok "schema test on deploy/k8s (sources)" || bad "schema test on deploy/k8s (sources)"
if command -v kubectl >/dev/null; then
  if kubectl kustomize "$tmp/k8s" >"$tmp/rendered.yaml" 2>"$tmp/kustomize.err"; then
    "$py" "$src/tests/deploy/check_manifests.py" "$tmp/rendered.yaml" &&
      ok "kubectl kustomize deploy/k8s: $(grep -c '^kind:' "$tmp/rendered.yaml") objects pass the schema test" ||
      bad "schema test on the rendered manifests"
  else
    bad "kubectl kustomize deploy/k8s"
    cat "$tmp/kustomize.err"
  fi
  mkdir "$tmp/queue"
  printf 'resources: [../k8s]\ncomponents: [../k8s/queue-depth]\n' >"$tmp/queue/kustomization.yaml"
  if kubectl kustomize "$tmp/queue" >"$tmp/queue.yaml" 2>"$tmp/kustomize.err" &&
    grep -q "name: locus_bands_queued" "$tmp/queue.yaml" &&
    "$py" "$src/tests/deploy/check_manifests.py" "$tmp/queue.yaml"; then
    ok "kubectl kustomize with the queue-depth component: the HPA scales on locus_bands_queued"
  else
    bad "queue-depth component"
    cat "$tmp/kustomize.err"
  fi
else
  echo "note: kubectl is not installed; the manifests were checked from their sources only"
fi
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]

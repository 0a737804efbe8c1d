#!/usr/bin/env python3
"""check_manifests.py: a small schema test of Locus' Kubernetes manifests.

  check_manifests.py rendered.yaml      the output of `kubectl kustomize`
  check_manifests.py --raw deploy/k8s   the sources, without kubectl: the
                                        kustomization's resources, its
                                        namespace, and its generated Secrets

Checks kinds and apiVersions, selectors against labels, the Service the
workers dial and its ports, the gRPC health probes on the --health port,
the PVC of the coordinator, the secrets each pod mounts and the files its
flags name in them, the autoscaler's target, and the non-root user of the
image. Prints one line per problem and exits 1 if there is any.
"""
import os
import sys

import yaml

KNOWN = {
    "Namespace": "v1",
    "Service": "v1",
    "Secret": "v1",
    "StatefulSet": "apps/v1",
    "Deployment": "apps/v1",
    "HorizontalPodAutoscaler": "autoscaling/v2",
}
IMAGE_UID = 10001  # deploy/docker/Dockerfile: the `locus` user

problems = []


def check(ok, message):
    if not ok:
        problems.append(message)
    return ok


def load_rendered(path):
    with open(path) as f:
        return [d for d in yaml.safe_load_all(f) if d]


def load_raw(directory):
    """The kustomization's resources, as kustomize would give them (its
    namespace applied, its generated Secrets with their files as keys)."""
    with open(os.path.join(directory, "kustomization.yaml")) as f:
        kust = yaml.safe_load(f)
    docs = []
    for resource in kust.get("resources", []):
        with open(os.path.join(directory, resource)) as f:
            docs += [d for d in yaml.safe_load_all(f) if d]
    namespace = kust.get("namespace")
    for d in docs:
        if namespace and d["kind"] != "Namespace":
            d["metadata"]["namespace"] = namespace
    for gen in kust.get("secretGenerator", []):
        keys = {os.path.basename(p): "" for p in gen.get("files", [])}
        docs.append({"apiVersion": "v1", "kind": "Secret",
                     "metadata": {"name": gen["name"], "namespace": namespace}, "data": keys})
    return docs


def flags(container):
    """--name=value flags of a container's args (and "--name value")."""
    out, args = {}, container.get("args", []) + container.get("command", [])[1:]
    for i, a in enumerate(args):
        if a.startswith("--"):
            if "=" in a:
                k, v = a.split("=", 1)
            else:
                k, v = a, (args[i + 1] if i + 1 < len(args) else "")
            out[k] = v
    return out


def port_of(address):
    return int(address.rsplit(":", 1)[1])


def secret_name(name, secrets):
    """The Secret `name` names: exactly, or with kustomize's hash suffix."""
    for s in secrets:
        if s == name or s.rsplit("-", 1)[0] == name:
            return s
    return None


def check_pod(kind, obj, secrets, health_flag="--health"):
    name = obj["metadata"]["name"]
    where = f"{kind} {name}"
    spec = obj["spec"]
    template = spec["template"]
    labels = template["metadata"].get("labels", {})
    for k, v in spec["selector"]["matchLabels"].items():
        check(labels.get(k) == v, f"{where}: selector {k}={v} does not match the pod template's labels")
    pod = template["spec"]
    sc = pod.get("securityContext", {})
    check(sc.get("runAsNonRoot") is True, f"{where}: runAsNonRoot is not set")
    check(sc.get("runAsUser") == IMAGE_UID, f"{where}: runAsUser is not the image's user {IMAGE_UID}")
    check(pod.get("terminationGracePeriodSeconds", 30) >= 30,
          f"{where}: terminationGracePeriodSeconds too short for a drain")
    containers = pod["containers"]
    check(len(containers) == 1, f"{where}: expected one container")
    c = containers[0]
    f = flags(c)
    ports = {p["containerPort"]: p.get("name") for p in c.get("ports", [])}
    # Health: gRPC probes on the --health port; liveness asks "liveness".
    if check(health_flag in f, f"{where}: no {health_flag} flag"):
        hp = port_of(f[health_flag])
        check(hp in ports, f"{where}: the health port {hp} is not a container port")
        for probe, service in (("readinessProbe", ""), ("livenessProbe", "liveness")):
            p = c.get(probe)
            if not check(p and "grpc" in p, f"{where}: {probe} is not a grpc probe"):
                continue
            check(p["grpc"].get("port") == hp, f"{where}: {probe} is on port {p['grpc'].get('port')}, not --health {hp}")
            check(p["grpc"].get("service", "") == service,
                  f"{where}: {probe} asks service '{p['grpc'].get('service', '')}', expected '{service}'")
    if check("--metrics" in f, f"{where}: no --metrics flag"):
        mp = port_of(f["--metrics"])
        check(mp in ports, f"{where}: the metrics port {mp} is not a container port")
        ann = template["metadata"].get("annotations", {})
        check(ann.get("prometheus.io/port") == str(mp), f"{where}: prometheus.io/port is not {mp}")
    # Secrets: each mounted one exists, and every file a flag names under a
    # mount is a key of its secret.
    volumes = {v["name"]: v for v in pod.get("volumes", [])}
    mounts = {m["mountPath"]: m["name"] for m in c.get("volumeMounts", [])}
    for path, vol in mounts.items():
        v = volumes.get(vol)
        if v is None:
            claims = [t["metadata"]["name"] for t in spec.get("volumeClaimTemplates", [])]
            check(vol in claims, f"{where}: mount {path} names no volume or claim '{vol}'")
            continue
        if "secret" in v:
            s = secret_name(v["secret"]["secretName"], secrets)
            check(s is not None, f"{where}: secret '{v['secret']['secretName']}' does not exist")
    for flag, value in f.items():
        for path, vol in mounts.items():
            if not value.startswith(path + "/"):
                continue
            v = volumes.get(vol, {})
            if "secret" not in v:
                continue
            s = secret_name(v["secret"]["secretName"], secrets)
            if s:
                key = value[len(path) + 1:]
                check(key in secrets[s], f"{where}: {flag}={value}: secret {s} has no key '{key}'")
    return c, f, ports


def main(argv):
    if len(argv) == 3 and argv[1] == "--raw":
        docs = load_raw(argv[2])
    elif len(argv) == 2:
        docs = load_rendered(argv[1])
    else:
        print(__doc__)
        return 2
    by_kind = {}
    for d in docs:
        kind, api = d.get("kind"), d.get("apiVersion")
        name = d.get("metadata", {}).get("name")
        check(name, f"{kind}: no metadata.name")
        if check(kind in KNOWN, f"{kind} {name}: unexpected kind"):
            check(api == KNOWN[kind], f"{kind} {name}: apiVersion {api}, expected {KNOWN[kind]}")
        by_kind.setdefault(kind, []).append(d)
    for kind in ("StatefulSet", "Deployment", "Service", "HorizontalPodAutoscaler"):
        check(len(by_kind.get(kind, [])) == 1, f"expected one {kind}, got {len(by_kind.get(kind, []))}")
    if problems:
        return report()
    secrets = {s["metadata"]["name"]: set(s.get("data", {})) | set(s.get("stringData", {}))
               for s in by_kind.get("Secret", [])}
    namespaces = {n["metadata"]["name"] for n in by_kind.get("Namespace", [])}
    for d in docs:
        ns = d["metadata"].get("namespace")
        if d["kind"] != "Namespace" and namespaces:
            check(ns in namespaces, f"{d['kind']} {d['metadata']['name']}: namespace {ns} is not created")

    sts, deploy = by_kind["StatefulSet"][0], by_kind["Deployment"][0]
    svc, hpa = by_kind["Service"][0], by_kind["HorizontalPodAutoscaler"][0]

    # The coordinator: one replica, its data on a claim, behind the Service.
    coord, cf, cports = check_pod("StatefulSet", sts, secrets)
    check(sts["spec"].get("replicas", 1) == 1, "StatefulSet: one coordinator per data directory (replicas 1)")
    check(sts["spec"].get("serviceName") == svc["metadata"]["name"],
          "StatefulSet: serviceName is not the Service")
    claims = [t["metadata"]["name"] for t in sts["spec"].get("volumeClaimTemplates", [])]
    check(claims, "StatefulSet: no volumeClaimTemplates (the job store needs a PersistentVolumeClaim)")
    data_mounts = [m for m in coord.get("volumeMounts", []) if m["name"] in claims]
    check(any(m["mountPath"] == cf.get("--data") for m in data_mounts),
          f"StatefulSet: --data {cf.get('--data')} is not on the claim's mount")
    sts_labels = sts["spec"]["template"]["metadata"]["labels"]
    dep_labels = deploy["spec"]["template"]["metadata"]["labels"]
    selector = svc["spec"].get("selector", {})
    check(selector and all(sts_labels.get(k) == v for k, v in selector.items()),
          "Service: its selector does not select the coordinator's pods")
    check(not all(dep_labels.get(k) == v for k, v in selector.items()),
          "Service: its selector also selects the workers")
    # The dashboard: --http on a container port, its startup probe on it.
    if check("--http" in cf, "StatefulSet: no --http flag (the dashboard)"):
        http = port_of(cf["--http"])
        check(http in cports, f"StatefulSet: the --http port {http} is not a container port")
        probe = coord.get("startupProbe", {}).get("httpGet", {})
        target = probe.get("port")
        target = {name: port for port, name in cports.items()}.get(target, target)
        check(target == http, f"StatefulSet: the startupProbe is not on the --http port {http}")
        check(probe.get("scheme") == ("HTTPS" if "--tls-cert" in cf else "HTTP"),
              "StatefulSet: the startupProbe's scheme does not match the port's TLS")
    named = {name: port for port, name in cports.items()}
    svc_ports = {}
    for p in svc["spec"]["ports"]:
        target = p.get("targetPort", p["port"])
        target = named.get(target, target)
        check(target in cports, f"Service port {p['port']}: target {p.get('targetPort')} is no container port")
        svc_ports[p["port"]] = target

    # The workers dial the Service by name, on the port that reaches --listen.
    worker, wf, _ = check_pod("Deployment", deploy, secrets)
    service, ns = svc["metadata"]["name"], svc["metadata"].get("namespace")
    if check("--coordinator" in wf, "Deployment: no --coordinator flag"):
        host, port = wf["--coordinator"].rsplit(":", 1)
        check(host in (service, f"{service}.{ns}", f"{service}.{ns}.svc", f"{service}.{ns}.svc.cluster.local"),
              f"Deployment: --coordinator {host} is not the Service {service}")
        check(svc_ports.get(int(port)) == port_of(cf.get("--listen", ":0")),
              f"Deployment: port {port} of the Service does not reach the coordinator's --listen")
    if "--http" in cf:
        check(port_of(cf["--http"]) in svc_ports.values(),
              "Service: no port reaches the coordinator's --http (the dashboard)")
    check(deploy["spec"].get("strategy", {}).get("rollingUpdate", {}).get("maxUnavailable", 1) == 0,
          "Deployment: a rolling update should keep every worker until its successor is ready")

    # The autoscaler: the worker Deployment, on CPU (requests set) or queue depth.
    ref = hpa["spec"]["scaleTargetRef"]
    check(ref.get("kind") == "Deployment" and ref.get("name") == deploy["metadata"]["name"],
          "HorizontalPodAutoscaler: does not target the worker Deployment")
    check(1 <= hpa["spec"].get("minReplicas", 1) <= hpa["spec"]["maxReplicas"],
          "HorizontalPodAutoscaler: minReplicas..maxReplicas is empty")
    metrics = hpa["spec"].get("metrics", [])
    check(metrics, "HorizontalPodAutoscaler: no metrics")
    for m in metrics:
        if m["type"] == "Resource":
            check(m["resource"]["name"] == "cpu", "HorizontalPodAutoscaler: a resource other than cpu")
            check("cpu" in worker.get("resources", {}).get("requests", {}),
                  "Deployment: no cpu request, which the CPU utilisation target needs")
        elif m["type"] == "External":
            check(m["external"]["metric"]["name"] == "locus_bands_queued",
                  "HorizontalPodAutoscaler: the external metric is not locus_bands_queued")
        else:
            check(False, f"HorizontalPodAutoscaler: unexpected metric type {m['type']}")
    return report()


def report():
    for p in problems:
        print("FAILED:", p)
    if not problems:
        print("manifests: ok")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

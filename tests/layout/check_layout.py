#!/usr/bin/env python3
"""The house's dependency direction (docs/architecture.md "Rules"), checked.

  check_layout.py SOURCE_DIR              includes point down, never up
  check_layout.py --worker-link BUILD_DIR the worker links no coordinator

Includes: a file in common/<stage>/ includes only its own stage and the
stages below it (base < scene < geometry < prepare < trace < scan <
render.{h,cpp} < farm); nothing in common/ includes gRPC, the generated
gRPC stubs, proto/wire/ or a process folder; worker/ includes neither
server/ nor client/; client/ includes server/ only in local_farm.{h,cpp},
where it embeds the coordinator; server/ includes neither worker/ nor
client/; proto/wire/ includes no process folder. Every violation is
printed as FILE:LINE: what is wrong; the exit status is 1 if there is one.

Worker link: the link command of locus-worker (CMake's link.txt with the
Makefile generator, build.ninja with Ninja) names neither SQLite nor any
coordinator or CLI library.
"""
import os
import re
import subprocess
import sys

# Stages of common/, bottom to top. `render` is common/render.{h,cpp}.
STAGES = ["base", "scene", "geometry", "prepare", "trace", "scan", "render", "farm"]
RANK = {s: i for i, s in enumerate(STAGES)}
CHECKED = ("common", "proto/wire", "server", "worker", "client")
INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]')
GRPC_SYSTEM = ("grpc/", "grpcpp/", "grpc++/")


def stage_of(path):
    """The stage of a path under common/ ('common/scan/x.h' -> 'scan'), or None."""
    parts = path.split("/")
    if parts[0] != "common":
        return None
    if len(parts) == 2:
        return "render" if parts[1] in ("render.h", "render.cpp") else ""
    return parts[1] if parts[1] in RANK else ""


def problems_of_include(src, kind, inc):
    """What is wrong with `src` including `inc` (kind '<' or '"'), or None."""
    top = src.split("/")[0]
    if kind == "<":
        if src.startswith("common/") and inc.startswith(GRPC_SYSTEM):
            return f"includes <{inc}>: common/ never includes gRPC"
        return None
    inc_top = inc.split("/")[0]
    if src.startswith("common/"):
        mine = stage_of(src)
        if inc.startswith("proto/"):
            if inc.startswith("proto/wire/") or inc.endswith(".grpc.pb.h"):
                return f'includes "{inc}": common/ links the messages only, never gRPC'
            return None
        if inc_top in ("server", "worker", "client"):
            return f'includes "{inc}": common/ is below every process'
        theirs = stage_of(inc)
        if theirs is None:
            return None
        if theirs == "":
            return f'includes "{inc}", which is in no stage folder of common/'
        if RANK[theirs] > RANK[mine]:
            return (f'includes "{inc}": {mine} is below {theirs} '
                    f"(order: {' < '.join(STAGES)})")
        return None
    if top == "worker" and inc_top in ("server", "client"):
        return f'includes "{inc}": the worker never sees the coordinator or the CLI'
    if top == "client" and inc_top == "server":
        if os.path.basename(src).split(".")[0] != "local_farm":
            return (f'includes "{inc}": only client/local_farm.{{h,cpp}} embeds the '
                    "coordinator")
    if top == "server" and inc_top in ("worker", "client"):
        return f'includes "{inc}": the coordinator never sees the worker or the CLI'
    if src.startswith("proto/wire/") and inc_top in ("server", "worker", "client"):
        return f'includes "{inc}": the adapters are below every process'
    return None


def check_sources(root):
    found = []
    for folder in CHECKED:
        base = os.path.join(root, folder)
        for dirpath, _, files in os.walk(base):
            for name in sorted(files):
                if not name.endswith((".h", ".cpp")):
                    continue
                path = os.path.join(dirpath, name)
                rel = os.path.relpath(path, root).replace(os.sep, "/")
                if rel.startswith("common/") and stage_of(rel) == "":
                    found.append(f"{rel}:1: is in no stage folder of common/ "
                                 f"({', '.join(s for s in STAGES if s != 'render')})")
                with open(path, encoding="utf-8", errors="replace") as f:
                    for lineno, line in enumerate(f, 1):
                        m = INCLUDE.match(line)
                        if not m:
                            continue
                        why = problems_of_include(rel, m.group(1), m.group(2))
                        if why:
                            found.append(f"{rel}:{lineno}: {why}")
    return found


FORBIDDEN_IN_WORKER = re.compile(
    r"sqlite|liblocus_server\.a|liblocus_service\.a|liblocus_client\.a|liblocus_local_farm\.a")


def worker_link_line(build):
    txt = os.path.join(build, "worker", "CMakeFiles", "locus-worker.dir", "link.txt")
    if os.path.exists(txt):
        with open(txt) as f:
            return f.read()
    ninja = os.path.join(build, "build.ninja")
    if not os.path.exists(ninja):
        raise SystemExit(f"{build}: neither link.txt of locus-worker nor build.ninja found")
    with open(ninja) as f:
        text = f.read()
    m = re.search(r"^build bin/locus-worker: .*?(?=^build |\Z)", text, re.S | re.M)
    if not m:
        raise SystemExit(f"{ninja}: no link step for bin/locus-worker")
    return m.group(0)


# Shared libraries the built locus-worker must not load: OpenImageIO (and
# the ~250 libraries behind it) makes every worker's start slower and the
# worker's container image six times bigger; the worker never writes an
# image (an object file that does, pulled in for one small function, is how
# it crept in before).
FORBIDDEN_WORKER_NEEDED = re.compile(r"libOpenImageIO|libsqlite3|libavcodec|libhttplib")


def worker_needed(build):
    binary = os.path.join(build, "bin", "locus-worker")
    if not os.path.exists(binary):
        raise SystemExit(f"{binary}: not built")
    out = subprocess.run(["readelf", "-d", binary], check=True, capture_output=True,
                         text=True).stdout
    return re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", out)


def check_worker_link(build):
    line = worker_link_line(build)
    bad = sorted(set(FORBIDDEN_IN_WORKER.findall(line)))
    found = [f"locus-worker links {b}: the worker is stateless and never the coordinator"
             for b in bad]
    found += [f"locus-worker loads {lib}: the worker never writes images or keeps a store"
              for lib in worker_needed(build) if FORBIDDEN_WORKER_NEEDED.search(lib)]
    return found


def main(argv):
    if len(argv) == 3 and argv[1] == "--worker-link":
        found = check_worker_link(argv[2])
        what = "worker link line"
    elif len(argv) == 2:
        found = check_sources(argv[1])
        what = "include direction"
    else:
        print(__doc__, file=sys.stderr)
        return 2
    for p in found:
        print(p)
    print(f"check_layout: {what}: {len(found)} problem(s)")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

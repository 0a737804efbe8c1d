"""The layout check itself: each rule fails on a tree that breaks it, and a
tree that keeps them all passes (python3 -m unittest, run by CTest)."""
import _sqlite3
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "check_layout.py")

GOOD = {
    "common/base/math.h": "#pragma once\n#include <cmath>\n",
    "common/scene/scene.h": '#include "common/base/math.h"\n#include "proto/scene.pb.h"\n',
    "common/scan/rows.cpp": '#include "common/scene/scene.h"\n#include "common/scan/rows.h"\n',
    "common/scan/rows.h": '#include "common/base/math.h"\n',
    "common/render.h": '#include "common/scan/rows.h"\n',
    "common/farm/types.h": '#include "common/render.h"\n',
    "proto/wire/rpc.h": '#include <grpcpp/grpcpp.h>\n#include "common/farm/types.h"\n',
    "server/coordinator.h": '#include "proto/wire/rpc.h"\n',
    "worker/band_renderer.h": '#include "common/render.h"\n#include "proto/wire/rpc.h"\n',
    "client/local_farm.h": '#include "server/coordinator.h"\n',
    "client/main.cpp": '#include "client/local_farm.h"\n',
}


def run(tree, *args):
    with tempfile.TemporaryDirectory() as root:
        for rel, text in tree.items():
            path = os.path.join(root, rel)
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "w") as f:
                f.write(text)
        r = subprocess.run([sys.executable, SCRIPT, *args, root], capture_output=True, text=True)
        return r.returncode, r.stdout


def with_file(rel, text):
    tree = dict(GOOD)
    tree[rel] = text
    return tree


class Layout(unittest.TestCase):
    def test_good_tree_passes(self):
        code, out = run(GOOD)
        self.assertEqual(code, 0, out)

    def assert_refused(self, tree, where, words):
        code, out = run(tree)
        self.assertEqual(code, 1, out)
        self.assertIn(where, out)
        self.assertIn(words, out)

    def test_upward_include_between_stages(self):
        self.assert_refused(with_file("common/scene/scene.h", '#include "common/scan/rows.h"\n'),
                            "common/scene/scene.h:1:", "scene is below scan")

    def test_stage_including_render(self):
        self.assert_refused(with_file("common/scan/rows.h", '#include "common/render.h"\n'),
                            "common/scan/rows.h:1:", "scan is below render")

    def test_render_including_farm(self):
        self.assert_refused(with_file("common/render.h", '#include "common/farm/types.h"\n'),
                            "common/render.h:1:", "render is below farm")

    def test_grpc_in_common(self):
        self.assert_refused(with_file("common/farm/x.cpp", "#include <grpcpp/grpcpp.h>\n"),
                            "common/farm/x.cpp:1:", "never includes gRPC")
        self.assert_refused(with_file("common/farm/x.cpp", '#include "proto/locus.grpc.pb.h"\n'),
                            "common/farm/x.cpp:1:", "never gRPC")
        self.assert_refused(with_file("common/farm/x.cpp", '#include "proto/wire/rpc.h"\n'),
                            "common/farm/x.cpp:1:", "never gRPC")

    def test_common_including_a_process(self):
        self.assert_refused(with_file("common/farm/x.h", '#include "server/coordinator.h"\n'),
                            "common/farm/x.h:1:", "below every process")

    def test_file_outside_stage_folders(self):
        self.assert_refused(with_file("common/stray.h", "#pragma once\n"),
                            "common/stray.h:1:", "no stage folder")

    def test_worker_including_server_or_client(self):
        self.assert_refused(with_file("worker/main.cpp", '\n#include "server/metrics.h"\n'),
                            "worker/main.cpp:2:", "never sees the coordinator")
        self.assert_refused(with_file("worker/main.cpp", '#include "client/farm_client.h"\n'),
                            "worker/main.cpp:1:", "never sees the coordinator")

    def test_client_including_server_outside_local_farm(self):
        self.assert_refused(with_file("client/farm_client.h", '#include "server/coordinator.h"\n'),
                            "client/farm_client.h:1:", "only client/local_farm")

    def test_server_including_worker(self):
        self.assert_refused(with_file("server/x.cpp", '#include "worker/band_renderer.h"\n'),
                            "server/x.cpp:1:", "never sees the worker")

    def test_wire_including_server(self):
        self.assert_refused(with_file("proto/wire/x.cpp", '#include "server/coordinator.h"\n'),
                            "proto/wire/x.cpp:1:", "below every process")


class WorkerLink(unittest.TestCase):
    # A stand-in for the built worker: an ELF file whose NEEDED entries are
    # known (/bin/true loads libc only; Python's _sqlite3 module loads
    # libsqlite3, which a worker must not).
    CLEAN_ELF = "/bin/true"
    SQLITE_ELF = _sqlite3.__file__

    def link(self, libraries, binary=CLEAN_ELF):
        with tempfile.TemporaryDirectory() as build:
            d = os.path.join(build, "worker", "CMakeFiles", "locus-worker.dir")
            os.makedirs(d)
            with open(os.path.join(d, "link.txt"), "w") as f:
                f.write("/usr/bin/c++ -O2 main.cpp.o -o bin/locus-worker " + libraries + "\n")
            os.makedirs(os.path.join(build, "bin"))
            shutil.copy(binary, os.path.join(build, "bin", "locus-worker"))
            r = subprocess.run([sys.executable, SCRIPT, "--worker-link", build],
                               capture_output=True, text=True)
            return r.returncode, r.stdout

    def test_clean_worker(self):
        code, out = self.link("worker/liblocus_worker.a common/liblocus_farm.a -lgrpc++")
        self.assertEqual(code, 0, out)

    def test_sqlite_or_coordinator_refused(self):
        for lib in ("/usr/lib/x86_64-linux-gnu/libsqlite3.so", "server/liblocus_server.a",
                    "server/liblocus_service.a", "client/liblocus_local_farm.a"):
            code, out = self.link("worker/liblocus_worker.a " + lib)
            self.assertEqual(code, 1, lib + ": " + out)
            self.assertIn("locus-worker links", out)

    def test_loaded_library_refused(self):
        code, out = self.link("worker/liblocus_worker.a", binary=self.SQLITE_ELF)
        self.assertEqual(code, 1, out)
        self.assertIn("locus-worker loads libsqlite3", out)


if __name__ == "__main__":
    unittest.main()

"""The Python client (client/python) against a real farm.

Run by tests/python/run.sh, which starts a coordinator (plaintext; client
tokens of ann and bob, a worker token) and 2 workers on 127.0.0.1, and a
TLS coordinator without workers, and passes them in LOCUS_TEST_* variables.
Frames fetched from the farm are compared byte for byte with `locus render
--workers 0` of the same settings.
"""

import os
import socket
import struct
import subprocess
import sys
import tempfile
import time
import unittest

import grpc  # a missing python3-grpcio fails here, it does not skip
from PIL import Image  # python3-pil

import locus

FARM = os.environ["LOCUS_TEST_FARM"]
BIN = os.environ["LOCUS_TEST_BIN"]
SOURCE = os.environ["LOCUS_TEST_SOURCE"]
TMP = os.environ["LOCUS_TEST_TMP"]
ANN = os.environ["LOCUS_TEST_ANN"]
BOB = os.environ["LOCUS_TEST_BOB"]
WORKER = os.environ["LOCUS_TEST_WORKER"]
TLS_FARM = os.environ["LOCUS_TEST_TLS_FARM"]
TLS = os.environ["LOCUS_TEST_TLS"]  # make_certs.sh: ca.pem, other-ca.pem, client.pem, ...

SPHERES = os.path.join(SOURCE, "scenes/simple/spheres.json")
ANIMATED = os.path.join(SOURCE, "scenes/anim/glass_and_mirror.json")
C = grpc.StatusCode


def wait_for(predicate, seconds, what):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out after {seconds} s waiting for {what}")


def render_in_process(scene, directory, pattern, *args):
    """`locus render --workers 0`: the reference frames."""
    subprocess.run([os.path.join(BIN, "locus"), "render", scene, "--workers", "0",
                    "-o", os.path.join(directory, pattern), *args],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    assert head[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    return struct.unpack(">II", head[16:24])


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class FarmTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.farm = locus.Farm(FARM, token=ANN)
        wait_for(lambda: len(cls.farm.workers()) >= 2, 20, "2 workers")

    @classmethod
    def tearDownClass(cls):
        cls.farm.close()

    def tmpdir(self):
        return tempfile.mkdtemp(dir=TMP)

    def assertFarmError(self, code, call, *args, **kwargs):
        with self.assertRaises(locus.FarmError) as cm:
            call(*args, **kwargs)
        self.assertEqual(cm.exception.code, code, str(cm.exception))
        return cm.exception

    def assertSameFrames(self, fetched, reference, names):
        # The same pixels, exactly; not the same bytes: a PNG frame the
        # coordinator joins from its bands' deflate streams (docs/farm.md
        # "Frames") is compressed otherwise than a single-process render's.
        self.assertEqual(sorted(os.path.basename(p) for p in fetched), sorted(names))
        for name in names:
            want = Image.open(os.path.join(reference, name))
            got = Image.open(os.path.join(os.path.dirname(fetched[0]), name))
            self.assertEqual((got.mode, got.size), (want.mode, want.size), name)
            self.assertEqual(got.tobytes(), want.tobytes(),
                             f"{name} differs from `locus render --workers 0`")

    # ---- the package

    def test_generated_stubs_import_as_one_package(self):
        self.assertIs(locus.locus_pb2.JobSpec().scene.__class__, locus.Scene)
        self.assertTrue(locus.locus_pb2.__name__.startswith("locus.proto."))
        self.assertFalse([m for m in sys.modules if m == "proto" or m.startswith("proto.")],
                         "the stubs must not need a top-level package `proto`")

    # ---- a shot: submit, watch, fetch, same frames as the CLI

    def test_submit_watch_fetch_equals_in_process_render(self):
        job = self.farm.submit(SPHERES, frames=(1, 3), out="shots/s_####.png", size=(48, 36),
                               orbit=30.0)
        self.assertRegex(job, r"^j\d+$")
        statuses = list(self.farm.watch(job))
        self.assertTrue(statuses)
        last = statuses[-1]
        self.assertEqual(last.state, "succeeded", last.error)
        self.assertTrue(last.finished)
        self.assertEqual((last.width, last.height, last.frame_first, last.frame_last),
                         (48, 36, 1, 3))
        self.assertEqual(last.owner, "ann")
        self.assertEqual(last.output, "s_####.png")
        self.assertEqual(last.bands_done, last.bands_total)
        self.assertEqual(sorted(last.frames_written), [1, 2, 3])
        for before, after in zip(statuses, statuses[1:]):
            self.assertLessEqual(before.bands_done, after.bands_done)
            self.assertLessEqual(before.frames_done, after.frames_done)
        self.assertTrue(all(s.job_id == job for s in statuses))

        reference = self.tmpdir()
        render_in_process(SPHERES, reference, "s_####.png", "--size", "48x36", "--frames", "1-3",
                          "--orbit", "30")
        out = self.tmpdir()
        paths = self.farm.fetch(job, os.path.join(out, "frames"))
        names = ["s_0001.png", "s_0002.png", "s_0003.png"]
        self.assertSameFrames(paths, reference, names)
        self.assertEqual(png_size(paths[0]), (48, 36))
        self.assertFalse([n for n in os.listdir(os.path.join(out, "frames")) if "partial" in n])
        # One frame only, on request.
        one = self.farm.fetch(job, self.tmpdir(), frames=[2])
        self.assertEqual([os.path.basename(p) for p in one], ["s_0002.png"])

        self.assertEqual(self.farm.job(job).state, "succeeded")
        self.assertIn(job, [j.job_id for j in self.farm.jobs()])
        events = self.farm.events(job)
        self.assertTrue(events)
        self.assertEqual([e.seq for e in events], sorted(e.seq for e in events))
        self.assertTrue(any("frame 3" in e.text for e in events), [e.text for e in events])
        later = self.farm.events(job, after=events[0].seq)
        self.assertEqual(len(later), len(events) - 1)
        self.assertIsInstance(self.farm.logs(job), list)
        self.assertIsInstance(self.farm.logs(job, frame=1, band=0), list)

    def test_a_scene_message_with_keyframes_renders_like_the_cli(self):
        scene = locus.load_scene(ANIMATED)
        self.assertIsInstance(scene, locus.Scene)
        self.assertTrue(scene.HasField("animation"))
        job = self.farm.submit(scene, frames=(1, 2), out="a_####.png", size="48x36", bands=3,
                               method="raytrace", spp=2, scene_name="glass_and_mirror")
        last = self.farm.wait(job)
        self.assertEqual(last.state, "succeeded", last.error)
        self.assertEqual((last.bands_per_frame, last.scene_name), (3, "glass_and_mirror"))
        reference = self.tmpdir()
        render_in_process(ANIMATED, reference, "a_####.png", "--size", "48x36", "--frames", "1-2",
                          "--method", "raytrace", "--spp", "2")
        self.assertSameFrames(self.farm.fetch(job, self.tmpdir()), reference,
                              ["a_0001.png", "a_0002.png"])

    def test_a_request_id_makes_the_submission_idempotent(self):
        scene = {"camera": {"from": [0, 1, 5], "at": [0, 1, 0], "width": 16, "height": 12},
                 "lights": [{"position": [3, 5, 4]}],
                 "materials": [{"color": [0.8, 0.3, 0.2]}],
                 "objects": [{"sphere": {"center": [0, 1, 0], "radius": 1}}]}
        first = self.farm.submit(scene, out="r.png", request_id="python-test-request-1")
        again = self.farm.submit(scene, out="r.png", request_id="python-test-request-1")
        self.assertEqual(first, again)
        self.assertFarmError(C.ALREADY_EXISTS, self.farm.submit, scene, out="other.png",
                             request_id="python-test-request-1")
        self.assertNotEqual(self.farm.submit(scene, out="r.png"), first)  # a fresh uuid4

    # ---- operations

    def test_pause_holds_a_job_back_and_resume_lets_it_finish(self):
        # A job for a worker tagged py-late, which is not there yet: it stays queued.
        job = self.farm.submit(SPHERES, frames=(1, 2), out="p_####.png", size=(32, 24),
                               require=["py-late"])
        status = self.farm.job(job)
        self.assertEqual(status.state, "queued")
        self.assertIn("py-late", status.waiting)
        self.assertEqual(self.farm.pause(job).state, "paused")
        # The worker it needs connects; a paused job still gets no lease.
        log = open(os.path.join(TMP, "late-worker.log"), "wb")
        env = dict(os.environ, LOCUS_TOKEN=WORKER)
        worker = subprocess.Popen([os.path.join(BIN, "locus-worker"), "--coordinator", FARM,
                                   "--tag", "py-late", "--threads", "1"], env=env, stderr=log)
        try:
            wait_for(lambda: any("py-late" in w.tags for w in self.farm.workers()), 20,
                     "the worker tagged py-late")
            time.sleep(1.0)
            status = self.farm.job(job)
            self.assertEqual((status.state, status.bands_done, status.bands_running),
                             ("paused", 0, 0))
            self.assertIn(self.farm.resume(job).state, ("queued", "running", "succeeded"))
            self.assertFarmError(C.FAILED_PRECONDITION, self.farm.resume, job)
            last = self.farm.wait(job)
            self.assertEqual(last.state, "succeeded", last.error)
            self.assertFarmError(C.FAILED_PRECONDITION, self.farm.pause, job)  # finished
        finally:
            worker.terminate()
            try:
                worker.wait(10)
            except subprocess.TimeoutExpired:
                worker.kill()
                worker.wait()
            log.close()
        texts = [e.text for e in self.farm.events(job)]
        self.assertTrue(any("paused by ann" in t for t in texts), texts)
        self.assertTrue(any("resumed by ann" in t for t in texts), texts)

    def test_only_the_owner_acts_on_a_job(self):
        job = self.farm.submit(SPHERES, out="o.png", size=(16, 12), require=["py-never"])
        with locus.Farm(FARM, token=BOB) as bob:
            e = self.assertFarmError(C.PERMISSION_DENIED, bob.cancel, job)
            self.assertIn("refused the call (PERMISSION_DENIED)", str(e))
            self.assertIn("belongs to ann", e.details)
            self.assertFarmError(C.PERMISSION_DENIED, bob.pause, job)
            self.assertFarmError(C.PERMISSION_DENIED, bob.priority, job, 90)
            self.assertEqual(bob.job(job).state, "queued")  # reading stays open
        self.assertEqual(self.farm.priority(job, 70).priority, 70)
        self.assertFarmError(C.FAILED_PRECONDITION, self.farm.delete, job)  # cancel it first
        self.assertEqual(self.farm.cancel(job).state, "cancelled")
        self.assertEqual(self.farm.retry(job).state, "queued")
        self.assertEqual(self.farm.cancel(job).state, "cancelled")
        self.assertEqual(self.farm.delete(job, outputs=True).job_id, job)
        self.assertFarmError(C.NOT_FOUND, self.farm.job, job)

    def test_a_watch_reopens_the_servers_capped_streams(self):
        job = self.farm.submit(SPHERES, out="w.png", size=(16, 12), require=["py-never"])
        saved = locus.farm.WATCH_STREAM_SECONDS
        locus.farm.WATCH_STREAM_SECONDS = 1  # the server ends each stream after 1 s
        try:
            start = time.monotonic()
            seen = []
            for status in self.farm.watch(job):
                seen.append(status)
                if time.monotonic() - start > 2.5:
                    break
        finally:
            locus.farm.WATCH_STREAM_SECONDS = saved
        # One status at the opening of each stream (nothing changes meanwhile).
        self.assertGreaterEqual(len(seen), 3)
        self.assertTrue(all(s.state == "queued" for s in seen))
        self.assertEqual(self.farm.cancel(job).state, "cancelled")

    def test_requeue_renders_written_frames_again(self):
        job = self.farm.submit(SPHERES, frames=(1, 2), out="q_####.png", size=(16, 12))
        self.assertEqual(self.farm.wait(job).state, "succeeded")
        self.assertIn(self.farm.requeue(job, 2, 2).state, ("queued", "running", "succeeded"))
        self.assertEqual(self.farm.wait(job).state, "succeeded")
        self.assertFarmError(C.INVALID_ARGUMENT, self.farm.requeue, job, 5, 6)

    def test_workers(self):
        workers = self.farm.workers()
        self.assertGreaterEqual(len(workers), 2)
        for w in workers:
            self.assertRegex(w.worker_id, r"^w\d+$")
            self.assertIn(w.state, ("idle", "busy", "draining", "disabled"))

    # ---- errors

    def test_an_unknown_job_is_not_found(self):
        e = self.assertFarmError(C.NOT_FOUND, self.farm.job, "j9999")
        self.assertIn("j9999", str(e))
        self.assertFarmError(C.NOT_FOUND, lambda: list(self.farm.watch("j9999")))

    def test_a_bad_token_is_unauthenticated(self):
        with locus.Farm(FARM, token="not-a-token-of-this-farm") as f:
            e = self.assertFarmError(C.UNAUTHENTICATED, f.jobs)
            self.assertIn(f"the farm at {FARM} refused the call (UNAUTHENTICATED)", str(e))
            self.assertNotIn("not-a-token-of-this-farm", str(e))
        with locus.Farm(FARM, token="") as f:
            self.assertFarmError(C.UNAUTHENTICATED, f.job, "j0001")
        with locus.Farm(FARM, token=WORKER) as f:
            self.assertFarmError(C.PERMISSION_DENIED, f.jobs)

    def test_an_unreachable_farm_is_a_clear_error(self):
        address = f"127.0.0.1:{free_port()}"
        with locus.Farm(address, token=ANN) as f:
            start = time.monotonic()
            e = self.assertFarmError(C.UNAVAILABLE, f.jobs)
            self.assertIn(f"cannot reach the farm at {address}", str(e))
            self.assertIn("is it running", str(e))
            # A watch of a farm never reached fails at once, not after a minute.
            self.assertFarmError(C.UNAVAILABLE, lambda: list(f.watch("j0001")))
            self.assertLess(time.monotonic() - start, 8)

    def test_plaintext_only_to_loopback_unless_insecure(self):
        e = self.assertFarmError(C.FAILED_PRECONDITION, locus.Farm, "192.0.2.7:7000")
        self.assertIn("ca=", str(e))
        locus.Farm("192.0.2.7:7000", insecure=True).close()  # no call made
        for address in ("127.0.0.1:7000", "127.1.2.3:1", "localhost:7000", "[::1]:7000",
                        "ipv4:127.0.0.1:7000", "dns:///localhost:7000", "unix:/tmp/s"):
            self.assertTrue(locus.is_loopback(address), address)
        for address in ("10.0.0.5:7000", "farm.example:7000", "[2001:db8::1]:7000",
                        "128.0.0.1:7000"):
            self.assertFalse(locus.is_loopback(address), address)
        self.assertFarmError(C.FAILED_PRECONDITION, locus.Farm, FARM, ca="/nonexistent/ca.pem")

    def test_a_movie_job_follows_the_render_job_and_is_fetched(self):
        job = self.farm.submit(SPHERES, frames=(1, 3), out="mv_####.png", size=(32, 24),
                               movie="out/mv.mp4", fps=6)
        render = self.farm.wait(job)
        self.assertEqual(render.state, "succeeded")
        self.assertTrue(render.movie_job)
        self.assertEqual(render.movie, "mv.mp4")
        movie = self.farm.wait(render.movie_job)
        self.assertEqual(movie.state, "succeeded", movie.error)
        self.assertEqual((movie.kind, movie.movie, movie.fps, list(movie.after)),
                         ("movie", "mv.mp4", 6, [job]))
        out = self.tmpdir()
        self.farm.fetch(render.movie_job, out)
        probe = subprocess.run(
            ["ffprobe", "-v", "error", "-select_streams", "v:0", "-count_frames", "-show_entries",
             "stream=codec_name,width,height,nb_read_frames", "-of", "csv=p=0",
             os.path.join(out, "mv.mp4")], capture_output=True, text=True, check=True)
        self.assertEqual(probe.stdout.strip(), "h264,32,24,3")
        with self.assertRaises(locus.FarmError) as e:
            self.farm.submit(SPHERES, out="x.exr", movie="x.mp4")
        self.assertEqual(e.exception.code, C.INVALID_ARGUMENT)

    def test_cost_maps_are_written_beside_the_frames_and_fetched(self):
        # One band a frame: each map is the single process's, pixel for
        # pixel (docs/cost-map.md "On the farm").
        job = self.farm.submit(SPHERES, frames=(1, 2), out="cm_####.png", size=(40, 30), bands=1,
                               cost_map="maps/cmc_####.png")
        status = self.farm.wait(job)
        self.assertEqual(status.state, "succeeded", status.error)
        self.assertEqual(status.cost_map, "cmc_####.png")
        reference = self.tmpdir()
        render_in_process(SPHERES, reference, "cm_####.png", "--size", "40x30", "--frames", "1-2",
                          "--cost-map", os.path.join(reference, "cmc_####.png"))
        maps = self.farm.fetch(job, self.tmpdir(), cost_maps=True)
        self.assertSameFrames(maps, reference, ["cmc_0001.png", "cmc_0002.png"])
        frames = self.farm.fetch(job, self.tmpdir())
        self.assertSameFrames(frames, reference, ["cm_0001.png", "cm_0002.png"])
        # A job without cost maps has none to fetch; a bad pattern is refused.
        plain = self.farm.submit(SPHERES, out="pl_####.png", size=(16, 12))
        self.farm.wait(plain)
        self.assertFarmError(C.FAILED_PRECONDITION, self.farm.fetch, plain, self.tmpdir(),
                             cost_maps=True)
        self.assertFarmError(C.INVALID_ARGUMENT, self.farm.submit, SPHERES, out="x_####.png",
                             cost_map="x_####.jpg")

    def test_tls_with_the_farms_ca(self):
        ca = os.path.join(TLS, "ca.pem")
        with locus.Farm(TLS_FARM, token=ANN, ca=ca) as f:
            self.assertEqual(f.jobs(), [])
        with locus.Farm(TLS_FARM, token=BOB + "x", ca=ca) as f:
            self.assertFarmError(C.UNAUTHENTICATED, f.jobs)
        with locus.Farm(TLS_FARM, token=ANN, ca=ca, cert=os.path.join(TLS, "client.pem"),
                        key=os.path.join(TLS, "client.key")) as f:
            self.assertEqual(f.workers(), [])
        with locus.Farm(TLS_FARM, token=ANN) as f:  # plaintext to a TLS port
            e = self.assertFarmError(C.UNAVAILABLE, f.jobs)
            self.assertIn("give ca=", str(e))
        with locus.Farm(TLS_FARM, token=ANN, ca=os.path.join(TLS, "other-ca.pem")) as f:
            self.assertFarmError(C.UNAVAILABLE, f.jobs)  # a certificate it cannot verify
        not_pem = os.path.join(self.tmpdir(), "ca.pem")
        with open(not_pem, "w") as f:
            f.write("not a certificate\n")
        self.assertFarmError(C.INVALID_ARGUMENT, locus.Farm, TLS_FARM, ca=not_pem)
        self.assertFarmError(C.INVALID_ARGUMENT, locus.Farm, TLS_FARM, ca=ca,
                             cert=os.path.join(TLS, "client.pem"))  # no key

    def test_tokens_come_from_the_argument_the_file_or_the_environment(self):
        path = os.path.join(self.tmpdir(), "token")
        with open(path, "w") as f:
            f.write(f"# my token\n\n  {ANN}  \n")
        os.chmod(path, 0o600)
        with locus.Farm(FARM, token_file=path) as f:
            self.assertIsInstance(f.jobs(), list)
        os.environ["LOCUS_TOKEN"] = BOB
        try:
            with locus.Farm(FARM) as f:
                job = self.farm.submit(SPHERES, out="t.png", size=(16, 12), require=["py-never"])
                self.assertFarmError(C.PERMISSION_DENIED, f.cancel, job)  # bob's token
            with locus.Farm(FARM, token=ANN) as f:  # the argument comes first
                self.assertEqual(f.cancel(job).state, "cancelled")
        finally:
            del os.environ["LOCUS_TOKEN"]
        with open(path, "w") as f:
            f.write("# nothing\n")
        self.assertFarmError(C.INVALID_ARGUMENT, locus.Farm, FARM, token_file=path)
        self.assertFarmError(C.FAILED_PRECONDITION, locus.Farm, FARM, token_file=path + ".no")
        self.assertFarmError(C.INVALID_ARGUMENT, locus.Farm, FARM, token="two words")

    def test_scene_problems_name_the_file_and_the_field(self):
        d = self.tmpdir()

        def scene_file(name, text):
            path = os.path.join(d, name)
            with open(path, "w") as f:
                f.write(text)
            return path

        e = self.assertFarmError(C.INVALID_ARGUMENT, locus.load_scene,
                                 scene_file("typo.json", '{"camera": {"fov": 40}}'))
        self.assertIn("typo.json: camera.fov: unknown field", str(e))
        e = self.assertFarmError(C.INVALID_ARGUMENT, locus.load_scene,
                                 scene_file("syntax.json", '{\n  "camera": {,}\n}'))
        self.assertIn("syntax.json:2:", str(e))
        e = self.assertFarmError(C.INVALID_ARGUMENT, locus.load_scene,
                                 scene_file("twice.json", '{"ambient": 0.1, "ambient": 0.2}'))
        self.assertIn("twice", str(e))
        self.assertFarmError(C.INVALID_ARGUMENT, locus.load_scene,
                             scene_file("nan.json", '{"ambient": NaN}'))
        e = self.assertFarmError(
            C.INVALID_ARGUMENT, locus.load_scene,
            scene_file("mesh.json", '{"objects": [{"mesh": {"obj": "a.obj"}}]}'))
        self.assertIn("objects[0].mesh.obj", str(e))
        self.assertFarmError(C.INVALID_ARGUMENT, locus.load_scene, scene_file("s.nff", "v\n"))
        self.assertFarmError(C.FAILED_PRECONDITION, locus.load_scene, os.path.join(d, "no.json"))
        self.assertFarmError(C.INVALID_ARGUMENT, locus.scene_from_dict, {"objects": [{"cube": 1}]})
        e = self.assertFarmError(C.INVALID_ARGUMENT, locus.scene_from_dict,
                                 {"objects": [{"cone": {"base_radius": 1, "baseRadius": 2}}]})
        self.assertIn("objects[0].cone", str(e))
        # Values are the coordinator's to check, with the JSON path.
        bad = locus.load_scene(SPHERES)
        bad.objects[1].sphere.radius = -1
        e = self.assertFarmError(C.INVALID_ARGUMENT, self.farm.submit, bad, out="bad.png")
        self.assertIn("objects[1].sphere.radius", str(e))
        self.assertFarmError(C.INVALID_ARGUMENT, self.farm.submit, SPHERES, frames=(1, 3),
                             out="no_frame_field.png")
        with self.assertRaises(TypeError):
            self.farm.submit(42)

    def test_fetched_names_must_be_plain_file_names(self):
        for name in ("shot_0001.png", "a b.png", ".hidden"):
            locus.check_plain_file_name(name, "test")
        for name in ("", ".", "..", "../x.png", "/etc/passwd", "a/b.png", "x\n.png", "x\x7f"):
            with self.assertRaises(locus.FarmError, msg=repr(name)) as cm:
                locus.check_plain_file_name(name, "the farm sent a file")
            self.assertEqual(cm.exception.code, C.INVALID_ARGUMENT)


if __name__ == "__main__":
    unittest.main(verbosity=2)

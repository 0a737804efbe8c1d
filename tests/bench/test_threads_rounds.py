"""bench/peers/threads.py judges its 2-against-1 targets on the runs during
which the machine gave two cores (its `capacity` probe): these tests hold
that selection, the report's line about it, and the probe's reading."""
import math
import os
import sys
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "bench", "peers"))
import threads  # noqa: E402


def run(rnd, cap, **fig):
    r = {"round": rnd, "capacity": cap, "cpu": 0.0}
    r.update(fig)
    return r


def scene(caps, t1, t2, w1, w2):
    """Rounds with the given probe readings and figures, one per round."""
    runs = {"t1": [], "t2": [], "w1": [], "w2": []}
    for i, c in enumerate(caps):
        runs["t1"].append(run(i, c, prepare=0.1, render=t1[i], frame=0.1 + t1[i], load=0.0))
        runs["t2"].append(run(i, c, prepare=0.1, render=t2[i], frame=0.1 + t2[i], load=0.0))
        runs["w1"].append(run(i, c, wall=w1[i]))
        runs["w2"].append(run(i, c, wall=w2[i]))
    return {"runs": runs, "same": {}, "notes": {}}


class RoundsOnTwoCores(unittest.TestCase):
    def test_a_round_on_one_core_does_not_count(self):
        # Round 1 ran while the host took the second core: its --threads 2
        # render was as slow as --threads 1 but its --threads 1 the fastest.
        sc = scene([1.95, 1.05, 1.90, 1.97], t1=[1.00, 0.90, 1.02, 1.08],
                   t2=[0.52, 0.90, 0.53, 0.54], w1=[1.10, 1.00, 1.12, 1.11],
                   w2=[0.60, 0.98, 0.61, 0.62])
        s = threads.summary(sc)
        self.assertAlmostEqual(s["t1_render"], 1.00)
        self.assertAlmostEqual(s["t2_render"], 0.52)
        self.assertAlmostEqual(s["render_x"], 1.00 / 0.52)
        self.assertAlmostEqual(s["farm_x"], 1.10 / 0.60)
        # The median of the rounds' own ratios pairs runs by their round
        # (1.92, 1.92, 2.0 from rounds 0, 2 and 3).
        self.assertAlmostEqual(s["render_med"], 1.02 / 0.53)
        every = threads.summary(sc, every_round=True)
        self.assertAlmostEqual(every["render_x"], 0.90 / 0.52)
        self.assertIn("12 of 16 runs on two cores", threads.probe_line(sc))
        self.assertEqual(threads.rounds_taken({"d": sc, "balls": sc}), "d 4, balls 4")

    def test_fewer_than_three_runs_on_two_cores_are_not_measured(self):
        # Two good runs of each job: a best of two is not a best of several.
        sc = scene([1.95, 1.05, 1.90], t1=[1.00, 0.90, 1.02], t2=[0.52, 0.90, 0.53],
                   w1=[1.10, 1.00, 1.12], w2=[0.60, 0.98, 0.61])
        s = threads.summary(sc)
        self.assertTrue(math.isnan(s["render_x"]))
        self.assertTrue(math.isnan(s["farm_x"]))
        self.assertIn("too few for t1, t2, w1, w2", threads.probe_line(sc))

    def test_no_round_on_two_cores_is_not_measured(self):
        sc = scene([1.2, 1.4], t1=[1.0, 1.0], t2=[0.9, 0.8], w1=[1.1, 1.1], w2=[1.0, 0.9])
        s = threads.summary(sc)
        self.assertTrue(math.isnan(s["render_x"]))
        self.assertEqual(threads.verdict(s["render_x"], threads.TARGETS["render"]),
                         "not measured")
        self.assertIn("too few for t1, t2, w1, w2", threads.probe_line(sc))
        lines = threads.target_lines({"d": sc})
        self.assertTrue(any("render --threads 2" in l and l.endswith("not measured")
                            for l in lines), lines)

    def test_a_raw_file_without_probes_counts_every_round(self):
        sc = scene([1.0, 1.0], t1=[1.0, 0.8], t2=[0.5, 0.45], w1=[1.1, 1.0], w2=[0.6, 0.55])
        for runs in sc["runs"].values():
            for r in runs:
                del r["capacity"]
        s = threads.summary(sc)
        self.assertAlmostEqual(s["t1_render"], 0.8)
        self.assertIn("no core probe", threads.probe_line(sc))

    def test_more_rounds_while_a_job_has_too_few_runs_on_two_cores(self):
        # The probe reads one core's worth for the first 8 probes, then two:
        # after the 2 rounds asked for, rounds go on until each job has 3
        # runs between two good probes, and no further.
        readings = iter([1.0] * 8 + [2.0] * 1000)
        calls = []

        def rounds(jobs, repeat, tag, tmp, prefix):
            key = jobs[0][0]
            calls.append(key)
            return {key: [{"cpu": 0.0, "render": 1.0, "prepare": 0.0, "frame": 1.0,
                           "load": 0.0, "wall": 1.0}]}, {key: f"{key}.exr"}, {}

        saved = (threads.capacity, threads.H.rounds, threads.identical)
        threads.capacity = lambda n=0: next(readings)
        threads.H.rounds = rounds
        threads.identical = lambda a, b: True
        try:
            got = threads.measure("d", "d.json", 64, 2, None, "locus", "/tmp", True,
                                  max_rounds=30)
        finally:
            threads.capacity, threads.H.rounds, threads.identical = saved
        # One probe, then one after each job: probes 1-8 are low, so rounds
        # 1-2 (9 probes) count for nothing; rounds 3-5 give each job its 3
        # runs; then it stops.
        self.assertEqual(len(calls), 5 * 4)
        for key in ("t1", "t2", "w1", "w2"):
            self.assertEqual(len(got["runs"][key]), 5)
            self.assertEqual(len(threads.two_core_runs(got["runs"])[key]), 3)
        # And it stops at max_rounds when the machine never gives two cores.
        calls.clear()
        threads.capacity = lambda n=0: 1.0
        threads.H.rounds = rounds
        threads.identical = lambda a, b: True
        try:
            threads.measure("d", "d.json", 64, 2, None, "locus", "/tmp", True, max_rounds=6)
        finally:
            threads.capacity, threads.H.rounds, threads.identical = saved
        self.assertEqual(len(calls), 6 * 4)

    def test_the_probe_reads_a_number_of_cores(self):
        # Whatever this machine gives now: between one core's worth (both
        # copies on one) and two, with room for timing noise.
        c = threads.capacity(200_000)
        self.assertTrue(0.5 < c < 2.6, c)


if __name__ == "__main__":
    unittest.main()

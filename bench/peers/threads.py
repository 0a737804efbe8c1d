#!/usr/bin/python3
"""Threads (issue #27 item 4): `--threads 2` against `--threads 1` on the
paper's scene (d) and SPD balls and gears at 512x512, configuration IV
--aa 4 (the default), in process (--workers 0), prepare and render apart;
and the embedded farm (`locus render --workers 2` against `--workers 1`,
one thread per worker), wall clock of the whole command.

Every measurement is taken side by side in rounds (each job once per round,
the order reversed every other round, so a change of load on the machine
falls on all alike), best of the rounds:
the smallest prepare, render and prepare + render of the --stats JSON
(wall seconds), the smallest wall of a farm run. Each --threads 2 image and
each farm image is compared with the --threads 1 image: they must be
bit-identical. The load average is recorded at the start and the end; on a
loaded machine (the farm benchmarks share it) --wait-load waits first.

Between every two jobs a probe measures how many cores the machine gives
two CPU-bound processes at that moment (`capacity`: one alone, two side by
side, one alone again; 2.0 on two free cores). A virtual machine's second
core can be taken by its host for seconds at a time (this bench's host gave
1.03 to 1.95 cores' worth from one probe to the next, with nothing else
running in it); a 2-against-1 ratio measured then says nothing about
Locus. The targets are judged on the runs whose probes (before and after)
both read at least CAPACITY_MIN, a job's best of at least
MIN_TWO_CORE_RUNS such runs (else its lines are "not measured"); the
report gives every run with its probe, and the figures over every run
beside.

Targets: render --threads 2 >= 1.9x --threads 1; whole frame (prepare +
render) >= 1.7x; embedded farm 2 workers >= 1.85x 1 worker.

--big adds SPD tetra level 9 (262,144 triangles, written by spdgen.py), for
information: where the scene is large, prepare is as long as the render,
and how much of it the second thread takes (the issue's "parallelise it
where it dominates"); its scene file's load (`seconds.load`, one thread
whatever --threads) is printed beside it.

Usage: bench/peers/threads.py [--quick] [--repeat N] [--scenes d,balls,gears]
Writes bench/results/threads.md and its raw measurements threads-raw.json
(--quick: a temporary directory); --report-only RAW rewrites the report.
"""
import json
import multiprocessing
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import harness as H  # noqa: E402
import spdgen  # noqa: E402

SCENES = [("d", os.path.join(H.ROOT, "scenes", "paper", "d_spheres_2lights.json")),
          ("balls", os.path.join(H.SPD, "def", "balls.nff")),
          ("gears", os.path.join(H.SPD, "def", "gears.nff"))]
# Information only (--big): no target applies.
BIG = [("tetra9", ("tetra", 9))]
IV = ["--method", "local", "--boxes", "eye+shadow", "--aa", "4"]
TARGETS = {"render": 1.9, "frame": 1.7, "farm": 1.85}
# A run counts for the targets when the machine gave at least this many
# cores' worth just before and just after it (the probe reads 1.93-2.0 on
# two idle cores of this bench's host).
CAPACITY_MIN = 1.85
# A job's figure on two cores is its best of at least this many such runs
# (best-of-1 is one sample of the host's drift); fewer: not measured.
MIN_TWO_CORE_RUNS = 3
# The probe's work: about 0.15 s of one core in CPython on this host.
SPIN = 3_000_000


def _spin(n):
    s = 0
    for i in range(n):
        s += i * i
    return s


def capacity(n=SPIN):
    """Cores' worth the machine gives two CPU-bound processes now: 2 x the
    wall clock of the work alone over that of two copies side by side (two
    processes of one pool, started before either clock)."""
    def alone():
        t0 = time.perf_counter()
        pool.apply(_spin, (n,))
        return time.perf_counter() - t0

    with multiprocessing.get_context("fork").Pool(2) as pool:
        pool.map(_spin, [1000, 1000])  # both workers up
        one = alone()
        t0 = time.perf_counter()
        pool.map(_spin, [n, n], chunksize=1)
        pair = time.perf_counter() - t0
        # The faster of two lone runs (before and after the pair): a lone run
        # slowed by something else would read as more than two cores.
        one = min(one, alone())
    return 2 * one / pair


def cpu_children():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def in_process(locus, path, size, threads, out):
    """One render in process: prepare and render (wall) from --stats."""
    st = locus.stats(path, size, IV, out, threads=threads)["seconds"]
    return {"cpu": st["render_cpu"], "prepare": st["prepare"], "render": st["render"],
            "frame": st["prepare"] + st["render"], "load": st.get("load", float("nan"))}


def on_farm(binary, path, size, workers, out):
    """`locus render` on its embedded farm: the whole command's wall clock
    (the farm's start, the cost preview, every worker's prepare, the bands,
    the stitched image) and the CPU of it and its workers."""
    cmd = [binary, "render", path, "-o", out, "--size", f"{size}x{size}", "--workers",
           str(workers), "--threads", "1"] + IV
    cpu0, t0 = cpu_children(), time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        lines = r.stderr.strip().splitlines()
        raise RuntimeError(lines[-1] if lines else f"exit {r.returncode}")
    return {"cpu": cpu_children() - cpu0, "wall": wall}


def identical(a, b):
    """The pixels of two EXR files, bit for bit (oiiotool --diff with no
    tolerance; the files' headers differ by their dates)."""
    r = subprocess.run(["oiiotool", "--fail", "0", "--warn", "0", "--diff", a, b],
                       capture_output=True, text=True)
    return r.returncode == 0


def measure(name, path, size, repeat, locus, binary, tmp, farm, max_rounds=0):
    """`repeat` rounds of the scene's jobs, then more (up to `max_rounds` in
    all) while a job has fewer than MIN_TWO_CORE_RUNS runs on two cores."""
    jobs = [("t1", "--threads 1", "locus",
             lambda out: in_process(locus, path, size, 1, out)),
            ("t2", "--threads 2", "locus",
             lambda out: in_process(locus, path, size, 2, out))]
    if farm:
        jobs += [("w1", "farm, 1 worker", "locus",
                  lambda out: on_farm(binary, path, size, 1, out)),
                 ("w2", "farm, 2 workers", "locus",
                  lambda out: on_farm(binary, path, size, 2, out))]
    # Rounds of harness.rounds, the order reversed every other round: the
    # host's speed drifts over seconds (other machines' work), and a job
    # always run first or last would meet that drift alike every time.
    runs, images, notes = {key: [] for key, *_ in jobs}, {}, {}

    # A probe between every two jobs (across rounds too): the host takes
    # and gives back its second core within seconds, so a round's two ends
    # do not tell.
    before = capacity()
    rnd = 0
    while rnd < repeat or (rnd < max_rounds and set(short_jobs(runs)) - set(notes)):
        order = jobs if rnd % 2 == 0 else jobs[::-1]
        of = f"{rnd + 1}/{repeat}" if rnd < repeat else f"{rnd + 1} (more: too few on two cores)"
        for job in [j for j in order if j[0] not in notes]:
            r, im, nt = H.rounds([job], 1, f"{name} round {of}", tmp, name)
            after = capacity()
            H.log(f"{name} round {of} {job[0]}: the machine gave {before:.2f} "
                  f"cores before, {after:.2f} after")
            for key, rec in r.items():
                for x in rec:
                    x["round"] = rnd
                    x["capacity"] = min(before, after)
                runs[key] += rec
            for key, image in im.items():
                images.setdefault(key, image)
            notes.update(nt)
            before = after
        rnd += 1
    same = {k: identical(images["t1"], images[k]) for k in images if k != "t1"}
    return {"runs": runs, "same": same, "notes": notes}


def best(runs, key):
    vals = [r[key] for r in runs if key in r]
    return min(vals) if vals else float("nan")


def two_core_runs(runs):
    """The runs whose probes (before and after each) both read CAPACITY_MIN
    or more (raw files from before the probe: every run); a job with fewer
    than MIN_TWO_CORE_RUNS of them keeps none."""
    if not any("capacity" in x for v in runs.values() for x in v):
        return runs
    kept = {k: [x for x in v if x.get("capacity", 0.0) >= CAPACITY_MIN] for k, v in runs.items()}
    return {k: v if len(v) >= MIN_TWO_CORE_RUNS else [] for k, v in kept.items()}


def short_jobs(runs):
    """The jobs that ran but have too few runs on two cores to be judged."""
    kept = two_core_runs(runs)
    return sorted(k for k, v in runs.items() if v and not kept[k])


def summary(scene, every_round=False):
    """Best-of figures and the three ratios of one scene, over its runs on
    two cores (two_core_runs), or over all of them."""
    r = scene["runs"] if every_round else two_core_runs(scene["runs"])
    s = {f"{k}_{m}": best(r.get(k, []), m)
         for k in ("t1", "t2") for m in ("prepare", "render", "frame", "load")}
    s.update({f"{k}_wall": best(r.get(k, []), "wall") for k in ("w1", "w2")})
    s["render_x"] = s["t1_render"] / s["t2_render"]
    s["prepare_x"] = s["t1_prepare"] / s["t2_prepare"]
    s["frame_x"] = s["t1_frame"] / s["t2_frame"]
    s["farm_x"] = s["w1_wall"] / s["w2_wall"]
    # The same ratios round by round (1 and 2 side by side in one round),
    # their median: a check of the best-of ratios against the drift.
    for key, a, b, m in (("render_med", "t1", "t2", "render"), ("frame_med", "t1", "t2", "frame"),
                         ("farm_med", "w1", "w2", "wall")):
        by_round = {y.get("round", i): y for i, y in enumerate(r.get(b, []))}
        pairs = [x[m] / by_round[x.get("round", i)][m] for i, x in enumerate(r.get(a, []))
                 if x.get("round", i) in by_round]
        s[key] = statistics.median(pairs) if pairs else float("nan")
    return s


def rounds_taken(scenes):
    """The rounds each scene took, "d 7, balls 30, ..." ("?" in raw files
    without round numbers)."""
    def taken(sc):
        rnds = [x["round"] for runs in sc["runs"].values() for x in runs if "round" in x]
        return str(max(rnds) + 1) if rnds else "?"
    return ", ".join(f"{name} {taken(sc)}" for name, sc in scenes.items())


def probe_line(scene):
    """How many of a scene's runs count for the targets, and what the
    probes read."""
    caps = [x["capacity"] for runs in scene["runs"].values() for x in runs if "capacity" in x]
    if not caps:
        return "runs: every one counts (no core probe in this raw file)"
    good = sum(1 for c in caps if c >= CAPACITY_MIN)
    short = short_jobs(scene["runs"])
    return (f"{good} of {len(caps)} runs on two cores (probes >= {CAPACITY_MIN}; read "
            f"{min(caps):.2f}-{max(caps):.2f}); the targets are judged on those, at least "
            f"{MIN_TWO_CORE_RUNS} a job" +
            (f": too few for {', '.join(short)}, whose lines are not measured" if short else ""))


def verdict(x, target):
    if not H.finite(x):
        return "not measured"
    return "PASS" if x >= target else "FAIL"


def target_lines(scenes):
    lines = []
    for name, sc in scenes.items():
        s = summary(sc)
        if sc.get("information"):
            lines.append(f"{name} (information, no target): prepare --threads 2 "
                         f"{s['prepare_x']:.2f}x ({s['t1_prepare']:.3f} -> {s['t2_prepare']:.3f} s), "
                         f"render {s['render_x']:.2f}x ({s['t1_render']:.3f} -> "
                         f"{s['t2_render']:.3f} s), whole frame {s['frame_x']:.2f}x "
                         f"({s['t1_frame']:.3f} -> {s['t2_frame']:.3f} s); the scene file's load "
                         f"{s['t1_load']:.3f} s before it; embedded farm 2 workers "
                         f"{s['farm_x']:.2f}x 1 worker ({s['w1_wall']:.3f} -> {s['w2_wall']:.3f} s)")
            for k, ok in sorted(sc["same"].items()):
                lines.append(f"{name}: {k} image bit-identical to --threads 1: "
                             f"{'PASS' if ok else 'FAIL'}")
            continue
        every = summary(sc, every_round=True)
        lines.append(f"{name}: {probe_line(sc)}")
        lines.append(f"{name}: render --threads 2 {s['render_x']:.2f}x --threads 1 "
                     f"({s['t1_render']:.3f} -> {s['t2_render']:.3f} s; target >= "
                     f"{TARGETS['render']}; median of rounds {s['render_med']:.2f}x; every "
                     f"round {every['render_x']:.2f}x): {verdict(s['render_x'], TARGETS['render'])}")
        lines.append(f"{name}: whole frame (prepare + render) {s['frame_x']:.2f}x "
                     f"({s['t1_frame']:.3f} -> {s['t2_frame']:.3f} s; prepare "
                     f"{s['t1_prepare']:.3f} -> {s['t2_prepare']:.3f} s, {s['prepare_x']:.2f}x; "
                     f"target >= {TARGETS['frame']}; median of rounds {s['frame_med']:.2f}x; "
                     f"every round {every['frame_x']:.2f}x): "
                     f"{verdict(s['frame_x'], TARGETS['frame'])}")
        lines.append(f"{name}: embedded farm 2 workers {s['farm_x']:.2f}x 1 worker "
                     f"({s['w1_wall']:.3f} -> {s['w2_wall']:.3f} s wall; target >= "
                     f"{TARGETS['farm']}; median of rounds {s['farm_med']:.2f}x; every round "
                     f"{every['farm_x']:.2f}x): {verdict(s['farm_x'], TARGETS['farm'])}")
        for k, ok in sorted(sc["same"].items()):
            lines.append(f"{name}: {k} image bit-identical to --threads 1: "
                         f"{'PASS' if ok else 'FAIL'}")
    return lines


def report(out_dir, info, scenes):
    lines = target_lines(scenes)
    md = [f"# Threads (issue #27 item 4)", "",
          f"{info['date']}, commit {info['commit']}, locus {info.get('locus', '?')}, "
          f"{H.host(info)}; {info['size']}x{info['size']}, configuration IV --aa 4; "
          f"{info['repeat']} rounds asked (each job once per round, side by side), "
          f"{rounds_taken(scenes)} taken (more while a job had too few runs on two cores); "
          f"best of the runs on which the machine gave two cores (below).", "",
          f"Load average (1, 5, 15 min): {info['load_start']} at the start, "
          f"{info.get('load_end', '?')} at the end.", "",
          "In process (`--workers 0`): `seconds.prepare` and `seconds.render` of `--stats` "
          "(wall), each the best of the rounds; the frame is prepare + render. Embedded farm: "
          "the wall clock of `locus render --workers N --threads 1` (the farm's start, the "
          "cost preview, each worker's prepare of the frame, the bands, the stitched image).",
          "",
          "| scene | prepare 1 | prepare 2 | x | render 1 | render 2 | x | frame 1 | frame 2 "
          "| x | farm 1 worker | farm 2 workers | x |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for every in (False, True):
        for name, sc in scenes.items():
            s = summary(sc, every_round=every)
            if every:
                name += " (every round)"
            md.append(f"| {name} | {s['t1_prepare']:.3f} | {s['t2_prepare']:.3f} | "
                      f"{s['prepare_x']:.2f} | {s['t1_render']:.3f} | {s['t2_render']:.3f} | "
                      f"{s['render_x']:.2f} | {s['t1_frame']:.3f} | {s['t2_frame']:.3f} | "
                      f"{s['frame_x']:.2f} | {s['w1_wall']:.3f} | {s['w2_wall']:.3f} | "
                      f"{s['farm_x']:.2f} |")
    md += ["", "Seconds; x: the speed-up (1 over 2), from the best of the rounds on two cores "
        "(nan: no run on two cores), and below them the same over every round. The lines below also "
        "give the median of the rounds' own ratios (1 and 2 side by side in one round): the "
        "host's speed drifts by up to 20-30% over seconds on this shared machine (the CPU "
        "time of one and the same --threads 1 render varies so), which the best-of figures "
        "only partly remove. Each run's `cores (probe)` is the lower of the two probes "
        "around it (`capacity`: two CPU-bound processes side by side against one alone, "
        f"2.0 on two free cores); the figures above and the targets take the runs that read "
        f"at least {CAPACITY_MIN}, and each line also gives the ratio over every round.", "", "## Targets", "", "```"] + lines + [
        "```", "", "## Every round", "",
        "| scene | job | round | cores (probe) | prepare | render | farm wall | CPU |",
        "|---|---|---|---|---|---|---|---|"]
    for name, sc in scenes.items():
        for key, runs in sc["runs"].items():
            for r in runs:
                md.append(f"| {name} | {key} | {r.get('round', -1) + 1} | "
                          f"{r.get('capacity', float('nan')):.2f} | "
                          f"{r.get('prepare', float('nan')):.3f} | "
                          f"{r.get('render', float('nan')):.3f} | "
                          f"{r.get('wall', float('nan')):.3f} | {r['cpu']:.3f} |")
        for key, note in sc["notes"].items():
            md.append(f"\n{name} {key}: FAILED: {note}")
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, "threads.md")
    with open(path, "w") as f:
        f.write("\n".join(md) + "\n")
    print("\n".join(lines))
    H.log(f"wrote {path}")


def wait_for_load(limit, max_wait):
    """Wait (up to max_wait s) until the 1-minute load average is below limit."""
    deadline = time.time() + max_wait
    while True:
        one = float(H.loadavg().split()[0])
        if one < limit or time.time() > deadline:
            return one
        H.log(f"load {one:.2f} >= {limit}: waiting")
        time.sleep(30)


def main():
    ap = H.parser(__doc__, "smoke test: 128x128, one round (temporary directory)")
    ap.add_argument("--scenes", help="comma-separated subset of d,balls,gears")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=5, help="rounds, best of N (default 5)")
    ap.add_argument("--no-farm", action="store_true", help="in process only")
    ap.add_argument("--big", action="store_true",
                    help="also SPD tetra level 9, for information (spdgen.py)")
    ap.add_argument("--wait-load", type=float, default=0.6,
                    help="first wait until the 1-minute load is below this (default 0.6)")
    ap.add_argument("--max-wait", type=float, default=600, help="seconds (default 600)")
    ap.add_argument("--max-rounds", type=int, default=30,
                    help="after --repeat rounds, more rounds of a scene (up to this many in "
                         f"all) while a job has fewer than {MIN_TWO_CORE_RUNS} runs on two cores "
                         "(default 30)")
    ap.add_argument("--out", help="output directory (default bench/results; quick: a temp dir)")
    ap.add_argument("--cache", default="/var/tmp/locus-bench-accuracy",
                    help="where a full run's raw measurements go (threads-raw.json)")
    ap.add_argument("--raw", help="save the measurements here instead")
    ap.add_argument("--report-only", metavar="RAW", help="rewrite the report from a raw file")
    args = ap.parse_args()
    if args.report_only:
        raw = H.load_raw(args.report_only)
        report(args.out or os.path.join(H.ROOT, "bench", "results"), **raw)
        return
    size = 128 if args.quick else args.size
    repeat = 1 if args.quick else args.repeat
    scenes = SCENES
    if args.scenes:
        want = args.scenes.split(",")
        scenes = [s for s in SCENES if s[0] in want]
        if len(scenes) != len(want):
            ap.error(f"unknown scene in {args.scenes}")
    tmp = tempfile.mkdtemp(prefix="locus-threads-")
    out_dir = args.out or (tmp if args.quick else os.path.join(H.ROOT, "bench", "results"))
    try:
        if not args.quick:
            wait_for_load(args.wait_load, args.max_wait)
        info = H.run_info(args.quick, repeat, size)
        # The farm's workers are the locus-worker beside the binary: both
        # copied, so that a rebuild during the run cannot mix versions.
        locus = H.Locus(H.copy_binary(args.locus, tmp), tmp)
        worker = os.path.join(os.path.dirname(args.locus), "locus-worker")
        farm = not args.no_farm and os.path.exists(worker)
        if farm:
            shutil.copy2(worker, os.path.join(os.path.dirname(locus.binary), "locus-worker"))
        info["locus"] = locus.sha[:12]
        H.log(f"locus {info['locus']} (HEAD {info['commit']}), load {info['load_start']}")
        if args.big:
            for name, (kind, level) in BIG:
                path = os.path.join(tmp, f"{kind}{level}.nff")
                with open(path, "w") as f:
                    f.write(spdgen.generate(kind, level))
                scenes = scenes + [(name, path)]
        results = {}
        for name, path in scenes:
            results[name] = measure(name, path, size, repeat, locus, locus.binary, tmp, farm,
                                    0 if args.quick else args.max_rounds)
            results[name]["information"] = name in dict(BIG)
        info["load_end"] = H.loadavg()
        raw = {"info": info, "scenes": results}
        raw_path = H.raw_path(args.raw, args.cache, args.quick, out_dir, "threads-raw.json")
        H.save_raw(raw_path, raw)
        H.log(f"raw measurements: {raw_path}")
        report(out_dir, **raw)
    finally:
        if not args.quick:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()

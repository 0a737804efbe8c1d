#!/usr/bin/python3
"""Speed against accuracy (issue #6 item 5, METHOD.md §9): every anti-aliasing
method timed and compared with a converged reference, on scenes (a), (b), (d)
and SPD balls, gears and rings at size s2, at 256x256 and 512x512.

Methods: Locus multi-scanning `--aa 1 2 4 8 16` (configuration IV), the
Whitted ray tracer `--method raytrace --spp 1 2 3 4 6 8`, and POV-Ray 3.7
`+A0.0 +AM1 +R1..4` and `+AM2 +R1..3`. Reference: `--method raytrace --spp 16`
(POV-Ray: its own `+AM1 +R8` render of the same scene). See README.md beside
this file for the definitions (timings, error metrics, edge pixels).

Usage: bench/accuracy/run.py [--quick] [--scenes a,b,...] [--sizes 256,512]
Writes bench/results/accuracy.{csv,md,png} (--quick: a temporary directory
unless --out is given).
"""
import argparse
import csv
import datetime
import hashlib
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SHARED = os.path.normpath(os.path.join(ROOT, "..", "shared"))
sys.path.insert(0, HERE)
import povscene  # noqa: E402

# name, scene file, checked-in .pov (None: translated from the NFF at run time)
SCENES = [
    ("a_glass", os.path.join(ROOT, "scenes", "paper", "a_glass.json"), "a_glass"),
    ("b_desk", os.path.join(ROOT, "scenes", "paper", "b_desk.json"), "b_desk"),
    ("d_spheres_2lights", os.path.join(ROOT, "scenes", "paper", "d_spheres_2lights.json"),
     "d_spheres_2lights"),
    ("balls", os.path.join(SHARED, "spd", "s2", "balls.nff"), None),
    ("gears", os.path.join(SHARED, "spd", "s2", "gears.nff"), None),
    ("rings", os.path.join(SHARED, "spd", "s2", "rings.nff"), None),
]
SCENE_ALIASES = {"a": "a_glass", "b": "b_desk", "d": "d_spheres_2lights"}

FULL = {"aa": [1, 2, 4, 8, 16], "spp": [1, 2, 3, 4, 6, 8], "am1": [1, 2, 3, 4], "am2": [1, 2, 3],
        "sizes": [256, 512]}
QUICK = {"aa": [1, 4], "spp": [1, 2, 4], "am1": [1, 3], "am2": [], "sizes": [256]}
REF_SPP = 16
CHECK_SPP = 32
PAIR_ROUNDS = 5  # interleaved rounds of the acceptance pair (3 for renders over 1 s)
POV_REF = ("1", 8)          # +AM1 +R8 +A0.0: 8 x 8 jittered samples per pixel
EDGE_THRESHOLD = 0.05       # Sobel magnitude of the reference's luminance (README)
CONVERGED_FACTOR = 5.0      # "far less": reference noise at least 5x below every error


# ------------------------------------------------------------------ helpers

def sha256_file(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def sha256_text(text):
    return hashlib.sha256(text.encode()).hexdigest()


def log(msg):
    sys.stderr.write(msg + "\n")
    sys.stderr.flush()


def loadavg():
    try:
        return " ".join(open("/proc/loadavg").read().split()[:3])
    except OSError:
        return "?"


def cpu_model():
    """The processor's name (/proc/cpuinfo's "model name"): the same build
    measures differently on another host, so every report names its own."""
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "?"


def host(info):
    """A report's host, from its run's info: "2 cores (AMD EPYC)" (older raw
    files, without the processor, give "?")."""
    return f"{info.get('ncpu', '?')} cores ({info.get('cpu', '?')})"


def snapshot_locus(src, dst_dir, wait_s=600):
    """Copy the locus binary once, so a rebuild under us cannot mix two
    versions in one run; wait while it is missing (being rebuilt). The copy
    is dst_dir/bin/locus, with the image plugin (EXR files) where it looks,
    dst_dir/lib/locus/ (docs/architecture.md "Image files")."""
    deadline = time.time() + wait_s
    plugin = os.path.join(os.path.dirname(os.path.abspath(src)), "..", "lib", "locus",
                          "liblocus-image-io.so")
    while True:
        if os.path.isfile(src) and os.access(src, os.X_OK) and os.path.isfile(plugin):
            os.makedirs(os.path.join(dst_dir, "bin"), exist_ok=True)
            os.makedirs(os.path.join(dst_dir, "lib", "locus"), exist_ok=True)
            shutil.copy2(plugin, os.path.join(dst_dir, "lib", "locus"))
            dst = os.path.join(dst_dir, "bin", "locus")
            shutil.copy2(src, dst)
            r = subprocess.run([dst, "render", "--help"], capture_output=True)
            if r.returncode == 0:
                return dst
        if time.time() > deadline:
            raise SystemExit(f"{src} or {plugin}: missing or not runnable after {wait_s} s "
                             "(build it first)")
        log(f"waiting for {src} ...")
        time.sleep(10)


def read_image(path):
    """Linear RGB float32: EXR unclamped (Locus), 16-bit PNG as 0..1 (POV-Ray)."""
    try:
        import OpenImageIO as oiio
        # ImageInput, not ImageBuf: ImageBuf reads through OpenImageIO's
        # image cache, which may hand back an earlier file of the same name
        # (every method's render is written to the same path).
        inp = oiio.ImageInput.open(path)
        if inp is None:
            raise RuntimeError(f"{path}: {oiio.geterror()}")
        try:
            px = inp.read_image(oiio.FLOAT)
        finally:
            inp.close()
        if px is None:
            raise RuntimeError(f"{path}: cannot read pixels")
        return np.asarray(px, dtype=np.float32)[..., :3]
    except ImportError:
        # Without python3-openimageio: oiiotool's text dump (slower, same values).
        r = subprocess.run(["oiiotool", "--dumpdata", path], check=True, capture_output=True,
                           text=True)
        lines = r.stdout.splitlines()
        m = re.search(r":\s+(\d+)\s+x\s+(\d+),\s+(\d+) channel", lines[0])
        w, h, ch = int(m.group(1)), int(m.group(2)), int(m.group(3))
        vals = np.array([float(v) for line in lines[1:] if "Pixel" in line
                         for v in line.split(":", 1)[1].split()], dtype=np.float32)
        img = vals.reshape(h, w, ch)
        return np.repeat(img, 3, axis=2) if ch == 1 else img[..., :3]


def display(img):
    """What the metrics compare: linear values clamped to [0, 1]."""
    return np.clip(img, 0.0, 1.0)


def downsample2(img):
    h, w, c = img.shape
    return img.reshape(h // 2, 2, w // 2, 2, c).mean(axis=(1, 3))


def edge_mask(ref):
    """Pixels whose reference luminance has a Sobel gradient magnitude
    (kernels normalised by 1/8, so a unit step gives 0.5) above
    EDGE_THRESHOLD: silhouettes, shadow and texture edges, reflected edges."""
    y = display(ref) @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    p = np.pad(y, 1, mode="edge")
    gx = (p[:-2, 2:] + 2 * p[1:-1, 2:] + p[2:, 2:] - p[:-2, :-2] - 2 * p[1:-1, :-2] - p[2:, :-2]) / 8
    gy = (p[2:, :-2] + 2 * p[2:, 1:-1] + p[2:, 2:] - p[:-2, :-2] - 2 * p[:-2, 1:-1] - p[:-2, 2:]) / 8
    return np.hypot(gx, gy) > EDGE_THRESHOLD


def psnr(rmse):
    return float("inf") if rmse == 0 else 20.0 * math.log10(1.0 / rmse)


def metrics(img, ref, mask):
    d = display(img) - display(ref)
    out = {}
    for key, sel in (("", d), ("edge_", d[mask])):
        if sel.size == 0:
            out.update({key + "rmse": float("nan"), key + "psnr": float("nan"),
                        key + "max_abs": float("nan")})
            continue
        rmse = float(np.sqrt(np.mean(np.square(sel, dtype=np.float64))))
        out.update({key + "rmse": rmse, key + "psnr": psnr(rmse),
                    key + "max_abs": float(np.max(np.abs(sel)))})
    return out


# ------------------------------------------------------------------ renderers

GNU_TIME = "/usr/bin/time"  # Debian's `time` (deploy/local/install-deps.sh)


def run_child(cmd, cwd=None):
    """subprocess.run(cmd, capture_output=True, text=True), and the child's
    own peak resident memory in KiB, as GNU time reports it (%M). Not this
    process's wait4: Linux carries a process's peak across exec, so a child
    started from Python would count Python's own resident memory as its
    floor (~35 MiB, ~120 MiB after a big scene was generated); GNU time is
    small, and the child it starts is measured from its own start."""
    if not os.access(GNU_TIME, os.X_OK):
        raise RuntimeError(f"{GNU_TIME} not found (Debian package `time`; "
                           "deploy/local/install-deps.sh installs it)")
    with tempfile.NamedTemporaryFile(mode="r", suffix=".maxrss") as peak:
        r = subprocess.run([GNU_TIME, "-f", "%M", "-o", peak.name] + list(cmd),
                           capture_output=True, text=True, cwd=cwd)
        text = peak.read().strip().splitlines()
    # On a failed child, GNU time writes "Command exited with non-zero
    # status N" before the figure.
    kib = int(text[-1]) if text and text[-1].isdigit() else 0
    return r, kib


class Locus:
    def __init__(self, binary, tmp):
        self.binary = binary
        self.sha = sha256_file(binary)
        self.tmp = tmp

    def render(self, scene, size, args, out, threads=1):
        stats = os.path.join(self.tmp, "stats.json")
        if os.path.exists(stats):
            os.remove(stats)
        cmd = [self.binary, "render", scene, "-o", out, "--size", f"{size}x{size}",
               "--workers", "0", "--threads", str(threads), "--stats", stats] + args
        r, self.peak_kib = run_child(cmd)
        if r.returncode != 0:
            lines = r.stderr.strip().splitlines()
            raise RuntimeError(lines[-1] if lines else f"exit {r.returncode}")
        with open(stats) as f:
            st = json.load(f)
        # CPU time of the rendering thread: a shared machine slows the wall
        # clock, not this (README "Time").
        return st["seconds"].get("render_cpu", st["seconds"]["render"]), st["seconds"].get("prepare", 0.0)


class PovRay:
    # The trace's CPU seconds (the line after "Trace Time"), like Locus's.
    TRACE = re.compile(r"Trace Time:.*?\(([0-9.]+) seconds\)\s*\n\s*using \d+ thread\(s\) with ([0-9.]+) CPU-seconds")

    def __init__(self, tmp):
        self.tmp = tmp
        r = subprocess.run(["povray", "--version"], capture_output=True, text=True)
        m = re.search(r"POV-Ray \S+", r.stdout + r.stderr)
        self.version = m.group(0) if m else "POV-Ray ?"

    def render(self, pov, size, am, depth, out, threads=1):
        # POV-Ray's startup is ~0.7 s: its own "Trace Time" is the render time.
        # 16-bit PNG with File_Gamma 1: linear, clamped to [0, 1] (which the
        # metrics do anyway), finer than the half floats of POV-Ray's EXR.
        cmd = ["povray", "-D", "-P", f"+WT{threads}", f"+W{size}", f"+H{size}", f"+I{pov}",
               f"+O{os.path.basename(out)}", "+FN16", "File_Gamma=1.0", "+A0.0", f"+AM{am}",
               f"+R{depth}"]
        r = subprocess.run(cmd, capture_output=True, text=True, cwd=os.path.dirname(out))
        m = self.TRACE.search(r.stderr)
        if r.returncode != 0 or not m:
            lines = [x for x in r.stderr.strip().splitlines() if "rror" in x] or \
                r.stderr.strip().splitlines()[-1:]
            raise RuntimeError(lines[-1] if lines else f"exit {r.returncode}")
        return float(m.group(2)), 0.0


def keep(directory, image, scene, size, label):
    if directory:
        os.makedirs(directory, exist_ok=True)
        stem = re.sub(r"[^A-Za-z0-9]+", "_", f"{scene} {size} {label}").strip("_")
        shutil.copy(image, os.path.join(directory, stem + os.path.splitext(image)[1]))


def timed(fn, repeat):
    """Best of up to `repeat` runs: short renders are the noisiest, so a run
    under 0.5 s is repeated `repeat` times, one under 3 s twice, longer ones once."""
    times = []
    prep = None
    while True:
        t, p = fn()
        times.append(t)
        prep = p if prep is None else min(prep, p)
        best = min(times)
        want = repeat if best < 0.5 else (min(2, repeat) if best < 3.0 else 1)
        if len(times) >= want:
            return best, prep, times


# ------------------------------------------------------------------ the run

class Cache:
    def __init__(self, path):
        self.path = path
        if path:
            os.makedirs(path, exist_ok=True)

    def get(self, key, produce, ext=".exr"):
        """Reference images depend only on (binary, scene, size, sampling)."""
        if not self.path:
            return produce(None)
        dst = os.path.join(self.path, key + ext)
        if os.path.exists(dst):
            return dst
        produce(dst + ".part" + ext)
        os.replace(dst + ".part" + ext, dst)
        return dst


def interp_loglog(xs, ys, x):
    lx, ly = np.log(xs), np.log(ys)
    return float(np.exp(np.interp(math.log(x), lx, ly)))


def curve_below(locus_pts, rt_pts, other="raytrace", other_first="raytrace --spp 1",
                within_time=False):
    """Is Locus's error below the other curve's (raytrace's, or POV-Ray's
    envelope) at equal time? Both curves are piecewise linear in log-log
    between their measured points (sorted by time); they are compared at
    every measured time of either curve inside the overlap of their time
    ranges, and a Locus point faster than every other point must beat the
    fastest other point (`other_first`) outright.

    With within_time, each curve stands for the error its renderer reaches
    within a time: none before its fastest point, then the curve, then flat
    after its slowest point (more time always buys its most accurate point).
    They are compared at every measured time of either curve from the other
    curve's fastest point on: Locus must reach a lower error there, so an
    other point faster than Locus's fastest fails, and a Locus point faster
    than every other point is not compared (nothing else is that fast).
    Returns (verdict, details)."""
    L = sorted((t, e) for t, e in locus_pts if t > 0 and e > 0)
    R = sorted((t, e) for t, e in rt_pts if t > 0 and e > 0)
    if len(L) < 1 or len(R) < 1:
        return None, "not enough points"
    if within_time:
        lo, hi = R[0][0], max(L[-1][0], R[-1][0])
    else:
        lo, hi = max(L[0][0], R[0][0]), min(L[-1][0], R[-1][0])
    details = []
    ok = True
    if lo <= hi:
        lt, le = zip(*L)
        rt, re_ = zip(*R)
        for t in sorted(set([t for t in lt + rt if lo <= t <= hi])):
            if t < lt[0]:
                ok = False
                details.append(f"{other} at {t:.3g} s, faster than Locus's fastest point "
                               f"({lt[0]:.3g} s)")
                continue
            el, er = interp_loglog(lt, le, t), interp_loglog(rt, re_, t)
            if el >= er:
                ok = False
                held = " (held flat)" if t > lt[-1] or t > rt[-1] else ""
                details.append(f"at {t:.3g} s Locus {el:.4g} >= {other} {er:.4g}{held}")
    else:
        details.append("time ranges do not overlap")
        ok = None
    if within_time:
        return ok, "; ".join(details)
    # Points outside the overlap: a Locus point faster than every raytrace
    # point is "below" only if it beats the fastest raytrace point outright.
    for t, e in L:
        if t < R[0][0]:
            if e >= R[0][1]:
                details.append(f"Locus at {t:.3g} s (faster than {other_first}) has RMSE "
                               f"{e:.4g} >= {other_first}'s {R[0][1]:.4g}")
                ok = False
    return ok, "; ".join(details)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true",
                    help="smoke test: 256x256 only, fewer methods, no convergence check")
    ap.add_argument("--locus", default=os.path.join(ROOT, "build", "bin", "locus"))
    ap.add_argument("--scenes", help="comma-separated subset: " +
                    ",".join(s[0] for s in SCENES) + " (a, b, d accepted)")
    ap.add_argument("--sizes", help="comma-separated image sizes (default 256,512; quick 256)")
    ap.add_argument("--repeat", type=int, default=3, help="best of at most N runs (see timed())")
    ap.add_argument("--no-pov", action="store_true", help="skip POV-Ray")
    ap.add_argument("--pov-sizes", default="256",
                    help="sizes POV-Ray is run at (default 256: POV-Ray at 512x512 adds "
                    "~20 min; with 256,512 its 256x256 reference is checked too)")
    ap.add_argument("--converge-large", action="store_true",
                    help="also check references above 256x256 against --spp 32 (slow: "
                    "4x the reference's cost)")
    ap.add_argument("--cache", default="/var/tmp/locus-bench-accuracy",
                    help="reference images, keyed by binary and scene hashes ('' disables)")
    ap.add_argument("--keep", help="also keep every method's image in this directory")
    ap.add_argument("--out", help="output directory (default bench/results; quick: a temp dir)")
    args = ap.parse_args()

    plan = dict(QUICK if args.quick else FULL)
    if args.sizes:
        plan["sizes"] = [int(s) for s in args.sizes.split(",")]
    scenes = SCENES
    if args.scenes:
        want = [SCENE_ALIASES.get(s, s) for s in args.scenes.split(",")]
        scenes = [s for s in SCENES if s[0] in want]
        if len(scenes) != len(want):
            ap.error(f"unknown scene in {args.scenes}")
    out_dir = args.out or (os.path.join(ROOT, "bench", "results") if not args.quick
                           else tempfile.mkdtemp(prefix="locus-accuracy-quick-"))
    os.makedirs(out_dir, exist_ok=True)
    have_pov = not args.no_pov and shutil.which("povray") is not None
    pov_sizes = [int(s) for s in args.pov_sizes.split(",")]
    ncpu = os.cpu_count() or 1
    started = time.time()
    load_start = loadavg()

    tmp = tempfile.mkdtemp(prefix="locus-accuracy-")
    try:
        locus = Locus(snapshot_locus(args.locus, tmp), tmp)
        pov = PovRay(tmp) if have_pov else None
        cache = Cache(args.cache)
        log(f"locus {locus.sha[:12]}  {pov.version if pov else 'no POV-Ray'}  load {load_start}")

        # .pov files: ours are checked in (bench/accuracy/pov); SPD's are
        # translated from ../shared/spd/s2 into the temp dir, never the repo.
        stale = []
        pov_files = {}
        if pov:
            for name, path, checked_in in scenes:
                if checked_in:
                    pov_files[name] = povscene.paper_pov_path(checked_in)
                    if povscene.json_to_pov(path) != open(pov_files[name]).read():
                        stale.append(name)
                else:
                    pov_files[name] = os.path.join(tmp, name + ".pov")
                    with open(pov_files[name], "w") as f:
                        f.write(povscene.nff_to_pov(path))
            for name in stale:
                log(f"warning: bench/accuracy/pov/{name}.pov differs from what povscene.py "
                    f"writes for its JSON now (run bench/accuracy/povscene.py --paper)")

        rows = []          # one per (scene, size, method)
        conv = []          # one per (scene, size, renderer): reference convergence
        cross = []         # Locus reference vs POV-Ray reference
        for name, path, _ in scenes:
            scene_hash = sha256_file(path)
            for size in plan["sizes"]:
                tag = f"{name} {size}x{size}"
                # ---- Locus reference and its convergence check
                def ref_render(spp, sz):
                    key = f"locus-{locus.sha[:16]}-{scene_hash[:16]}-{sz}-spp{spp}"

                    def produce(dst):
                        dst = dst or os.path.join(tmp, key + ".exr")
                        log(f"{name} {sz}x{sz}: reference --method raytrace --spp {spp} "
                            f"({ncpu} threads)")
                        locus.render(path, sz, ["--method", "raytrace", "--spp", str(spp)], dst,
                                     threads=ncpu)
                        return dst
                    return read_image(cache.get(key, produce))

                ref = ref_render(REF_SPP, size)
                mask = edge_mask(ref)
                check = None
                how = None
                if not args.quick:
                    if 2 * size in plan["sizes"] or 2 * size <= 512:
                        # 16 x 16 stratified samples in each pixel of a 2W x 2H
                        # image, averaged 2 x 2, are 32 x 32 stratified samples per
                        # pixel at W x H: the --spp 32 render, for free when the
                        # 2W x 2H reference is measured anyway.
                        check = downsample2(ref_render(REF_SPP, 2 * size))
                        how = f"--spp 16 at {2 * size}x{2 * size}, 2x2 box-averaged (= --spp 32)"
                    elif args.converge_large:
                        check = ref_render(CHECK_SPP, size)
                        how = "--spp 32"
                    else:
                        how = "not measured (--converge-large)"
                else:
                    how = "not measured (--quick)"
                c = {"scene": name, "size": size, "renderer": "locus",
                     "reference": f"raytrace --spp {REF_SPP}", "check": how,
                     "edge_fraction": float(mask.mean())}
                if check is not None:
                    c.update(metrics(check, ref, mask))
                conv.append(c)

                # ---- Locus methods
                methods = [("locus", f"--aa {n}", "local --aa", n,
                            ["--method", "local", "--boxes", "eye+shadow", "--aa", str(n)])
                           for n in plan["aa"]]
                methods += [("locus", f"raytrace --spp {n}", "raytrace --spp", n,
                             ["--method", "raytrace", "--boxes", "eye+shadow", "--spp", str(n)])
                            for n in plan["spp"]]
                for renderer, label, family, param, margs in methods:
                    out = os.path.join(tmp, "m.exr")
                    row = {"scene": name, "size": size, "renderer": renderer, "method": label,
                           "family": family, "param": param,
                           "reference": f"locus raytrace --spp {REF_SPP}",
                           "edge_fraction": float(mask.mean()), "binary": locus.sha[:12]}
                    try:
                        best, prep, times = timed(
                            lambda: locus.render(path, size, margs, out), args.repeat)
                        row.update({"seconds": best, "prepare": prep, "runs": len(times),
                                    "all_seconds": ";".join(f"{t:.4f}" for t in times)})
                        row.update(metrics(read_image(out), ref, mask))
                        keep(args.keep, out, name, size, label)
                        log(f"{tag} {label}: {best:.3f} s (best of {len(times)}), "
                            f"RMSE {row['rmse']:.5f}, edge RMSE {row['edge_rmse']:.5f}")
                    except RuntimeError as e:
                        row["note"] = str(e)
                        log(f"{tag} {label}: FAILED: {e}")
                    rows.append(row)

                # ---- The acceptance pair, interleaved: on a shared machine the
                # speed drifts over minutes, and best-of-N runs taken one method
                # after the other can catch the two in different states. So
                # --aa 4 and --spp 2 are timed again in alternation, and their
                # ratio comes from these rounds (`pair_seconds`).
                pair = [(r, m) for r in (find(rows, name, size, "--aa 4"),
                                         find(rows, name, size, "raytrace --spp 2"))
                        if r and "seconds" in r
                        for m in methods if m[1] == r["method"]]
                if len(pair) == 2:
                    rounds = PAIR_ROUNDS if max(r["seconds"] for r, _ in pair) < 1.0 else 3
                    got = {id(r): [] for r, _ in pair}
                    out = os.path.join(tmp, "m.exr")
                    for _ in range(rounds):
                        for r, m in pair:
                            got[id(r)].append(locus.render(path, size, m[4], out)[0])
                    for r, _ in pair:
                        r["pair_seconds"] = min(got[id(r)])
                        r["pair_all_seconds"] = ";".join(f"{t:.4f}" for t in got[id(r)])
                    log(f"{tag} interleaved x{rounds}: --aa 4 {pair[0][0]['pair_seconds']:.3f} s, "
                        f"--spp 2 {pair[1][0]['pair_seconds']:.3f} s")

                # ---- POV-Ray: measured against its own reference
                if not pov or size not in pov_sizes:
                    continue
                pfile = pov_files[name]
                pov_hash = sha256_file(pfile)

                def pov_ref(sz):
                    key = (f"pov-{sha256_text(pov.version)[:8]}-{pov_hash[:16]}-{sz}"
                           f"-am{POV_REF[0]}r{POV_REF[1]}")

                    def produce(dst):
                        dst = dst or os.path.join(tmp, key + ".png")
                        log(f"{name} {sz}x{sz}: POV-Ray reference +AM{POV_REF[0]} +R{POV_REF[1]}")
                        pov.render(pfile, sz, POV_REF[0], POV_REF[1], dst, threads=ncpu)
                        return dst
                    return read_image(cache.get(key, produce, ".png"))

                try:
                    pref = pov_ref(size)
                except RuntimeError as e:
                    log(f"{tag}: POV-Ray reference FAILED: {e}")
                    continue
                pmask = edge_mask(pref)
                c = {"scene": name, "size": size, "renderer": "povray",
                     "reference": f"+AM{POV_REF[0]} +R{POV_REF[1]} +A0.0",
                     "edge_fraction": float(pmask.mean()), "check": None}
                if not args.quick and 2 * size in pov_sizes:
                    c["check"] = (f"+AM1 +R8 at {2 * size}x{2 * size}, 2x2 box-averaged "
                                  "(16 x 16 samples)")
                    c.update(metrics(downsample2(pov_ref(2 * size)), pref, pmask))
                else:
                    c["check"] = "not measured (--pov-sizes)"
                conv.append(c)
                cross.append({"scene": name, "size": size, **metrics(pref, ref, mask)})
                pmethods = [(f"+AM1 +R{n}", "povray +AM1 +R", 1, n) for n in plan["am1"]]
                pmethods += [(f"+AM2 +R{n}", "povray +AM2 +R", 2, n) for n in plan["am2"]]
                for label, family, am, depth in pmethods:
                    out = os.path.join(tmp, "p.png")
                    row = {"scene": name, "size": size, "renderer": "povray",
                           "method": label + " +A0.0", "family": family, "param": depth,
                           "reference": f"povray +AM{POV_REF[0]} +R{POV_REF[1]}",
                           "edge_fraction": float(pmask.mean()), "binary": pov.version}
                    try:
                        best, prep, times = timed(
                            lambda: pov.render(pfile, size, am, depth, out), args.repeat)
                        row.update({"seconds": best, "prepare": prep, "runs": len(times),
                                    "all_seconds": ";".join(f"{t:.4f}" for t in times)})
                        row.update(metrics(read_image(out), pref, pmask))
                        keep(args.keep, out, name, size, "pov " + label)
                        log(f"{tag} POV-Ray {label}: {best:.3f} s (best of {len(times)}), "
                            f"RMSE {row['rmse']:.5f}")
                    except RuntimeError as e:
                        row["note"] = str(e)
                        log(f"{tag} POV-Ray {label}: FAILED: {e}")
                    rows.append(row)

        binary_after = sha256_file(args.locus) if os.path.exists(args.locus) else None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    info = {
        "date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"),
        "locus": locus.sha[:12],
        "locus_changed": binary_after is not None and binary_after != locus.sha,
        "pov": pov.version if pov else None,
        "load_start": load_start, "load_end": loadavg(),
        "minutes": (time.time() - started) / 60.0,
        "quick": args.quick, "repeat": args.repeat, "plan": plan, "stale_pov": stale,
        "ncpu": ncpu, "cpu": cpu_model(), "pov_sizes": pov_sizes if pov else [],
    }
    checks = acceptance(rows, conv, plan)
    write_csv(os.path.join(out_dir, "accuracy.csv"), rows, conv)
    write_md(os.path.join(out_dir, "accuracy.md"), rows, conv, cross, checks, info)
    chart(os.path.join(out_dir, "accuracy.png"), rows, conv, plan, "rmse")
    chart(os.path.join(out_dir, "accuracy_edges.png"), rows, conv, plan, "edge_rmse")
    print("\n".join(line for _, line in checks))
    print(f"results in {out_dir}/accuracy.{{csv,md,png}}")


# ------------------------------------------------------------------ checks

def find(rows, scene, size, method):
    for r in rows:
        if r["scene"] == scene and r["size"] == size and r["method"] == method and "rmse" in r:
            return r
    return None


def acceptance(rows, conv, plan):
    """The issue's acceptance, printed as PASS/FAIL lines, plus the
    reference convergence. Nothing here is tuned: thresholds are the issue's."""
    out = []
    keys = sorted({(r["scene"], r["size"]) for r in rows},
                  key=lambda k: ([s[0] for s in SCENES].index(k[0]), k[1]))
    for scene, size in keys:
        tag = f"{scene} {size}x{size}"
        aa4 = find(rows, scene, size, "--aa 4")
        sp2 = find(rows, scene, size, "raytrace --spp 2")
        if aa4 and sp2:
            # Times from the interleaved rounds where they were taken.
            key = "pair_seconds" if "pair_seconds" in aa4 and "pair_seconds" in sp2 else "seconds"
            ta, ts = aa4[key], sp2[key]
            ok = aa4["rmse"] < sp2["rmse"] and ta < ts
            out.append((ok, f"{'PASS' if ok else 'FAIL'} {tag}: --aa 4 RMSE {aa4['rmse']:.5f} "
                            f"{'<' if aa4['rmse'] < sp2['rmse'] else '>='} raytrace --spp 2 "
                            f"{sp2['rmse']:.5f}; time {ta:.3f} s {'<' if ta < ts else '>='} "
                            f"{ts:.3f} s"
                            f"{' (interleaved)' if key == 'pair_seconds' else ''}"))
        else:
            out.append((False, f"FAIL {tag}: --aa 4 or raytrace --spp 2 missing"))
        lp = [(r["seconds"], r["rmse"]) for r in rows if r["scene"] == scene and
              r["size"] == size and r["family"] == "local --aa" and "rmse" in r]
        rp = [(r["seconds"], r["rmse"]) for r in rows if r["scene"] == scene and
              r["size"] == size and r["family"] == "raytrace --spp" and "rmse" in r]
        ok, det = curve_below(lp, rp)
        word = {True: "PASS", False: "FAIL", None: "N/A "}[ok]
        out.append((ok, f"{word} {tag}: Locus curve below raytrace's at equal time"
                        f"{' (' + det + ')' if det else ''}"))
    for c in conv:
        if c["renderer"] != "locus" or "rmse" not in c:
            continue
        tag = f"{c['scene']} {c['size']}x{c['size']}"
        pair = [r for r in (find(rows, c["scene"], c["size"], "--aa 4"),
                            find(rows, c["scene"], c["size"], "raytrace --spp 2")) if r]
        errs = [r for r in rows if r["scene"] == c["scene"] and r["size"] == c["size"]
                and r["renderer"] == "locus" and "rmse" in r]
        if not pair or not errs:
            continue
        smallest = min(errs, key=lambda r: r["rmse"])
        ratios = [(r["method"], r["rmse"] / c["rmse"] if c["rmse"] > 0 else float("inf"))
                  for r in pair]
        ok = all(x >= CONVERGED_FACTOR for _, x in ratios)
        out.append((ok, f"{'PASS' if ok else 'FAIL'} {tag}: reference converged: spp16 vs "
                        f"spp32 RMSE {c['rmse']:.6f} is "
                        + ", ".join(f"{x:.1f}x below {m}" for m, x in ratios)
                        + f" (needs {CONVERGED_FACTOR:g}x); smallest error measured "
                        f"({smallest['method']}) {smallest['rmse']:.5f} is "
                        f"{smallest['rmse'] / c['rmse']:.1f}x above it"))
    return out


# ------------------------------------------------------------------ output

FIELDS = ["scene", "size", "renderer", "method", "family", "param", "seconds", "runs",
          "all_seconds", "prepare", "rmse", "psnr", "max_abs", "edge_rmse", "edge_psnr",
          "edge_max_abs", "edge_fraction", "reference", "binary", "pair_seconds",
          "pair_all_seconds", "note"]


def fmt(v):
    if isinstance(v, float):
        if math.isnan(v):
            return ""
        return "inf" if math.isinf(v) else f"{v:.6g}"
    return "" if v is None else str(v)


def write_csv(path, rows, conv):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(FIELDS)
        for r in rows:
            w.writerow([fmt(r.get(k)) for k in FIELDS])
        # The references' convergence, as rows of their own.
        for c in conv:
            if "rmse" not in c:
                continue
            r = dict(c, method=f"reference check: {c['check']}", family="reference check")
            w.writerow([fmt(r.get(k)) for k in FIELDS])


def write_md(path, rows, conv, cross, checks, info):
    plan = info["plan"]
    L = [f"# Speed against accuracy{' (quick smoke test)' if info['quick'] else ''}", "",
         f"`bench/accuracy/run.py{' --quick' if info['quick'] else ''}`, {info['date']}: "
         f"locus `{info['locus']}`, {info['pov'] or 'no POV-Ray'}, {host(info)}, "
         f"load average {info['load_start']} at the start and {info['load_end']} at the end, "
         f"{info['minutes']:.0f} min. Times are each renderer's own render time on one thread "
         f"(Locus `--workers 0 --threads 1`, `seconds.render_cpu` of `--stats`; POV-Ray `+WT1`, the "
         f"CPU seconds of its reported trace), best of up to {info['repeat']} runs (runs under 0.5 s: "
         f"{info['repeat']}, under 3 s: 2, longer: 1). The machine was shared with other "
         "work, so times are noisy.", "",
         "Errors are over linear RGB clamped to [0, 1] (EXR renders read with OpenImageIO): "
         "RMSE over all pixels and channels, PSNR = 20 log10(1 / RMSE), max = largest "
         "absolute channel error; `edge` = the same over the pixels where the reference's "
         f"luminance has a Sobel gradient magnitude above {EDGE_THRESHOLD} (see README). "
         f"Locus methods are measured against `--method raytrace --spp {REF_SPP}`, POV-Ray "
         f"against its own `+AM{POV_REF[0]} +R{POV_REF[1]} +A0.0` render of the same .pov "
         "(its shading differs from ours; see below), at "
         + (", ".join(f"{z}x{z}" for z in info["pov_sizes"]) or "no size") + ".", ""]
    if info["locus_changed"]:
        L += ["**Note: build/bin/locus changed during the run; every Locus figure comes from "
              "the copy taken at the start.**", ""]
    if info["stale_pov"]:
        L += ["**Note: " + ", ".join(info["stale_pov"]) + ": the checked-in .pov differs "
              "from a fresh translation of the JSON.**", ""]
    L += ["## Acceptance", "", "```"] + [line for _, line in checks] + ["```", ""]

    L += ["## References", "",
          "How far each reference is from converged: the reference against a render with "
          "4x the samples. The error any method can show is bounded below by roughly this.", "",
          "| scene | size | renderer | reference | checked against | RMSE | max | edge RMSE "
          "| edge pixels |", "|---|---|---|---|---|---|---|---|---|"]
    for c in conv:
        L.append(f"| {c['scene']} | {c['size']} | {c['renderer']} | {c['reference']} | "
                 f"{c.get('check') or 'not measured'} | {fmt(c.get('rmse'))} | "
                 f"{fmt(c.get('max_abs'))} | {fmt(c.get('edge_rmse'))} | "
                 f"{100 * c['edge_fraction']:.1f}% |")
    if cross:
        L += ["", "Shading difference of the POV-Ray translation: its reference against "
              "Locus's (RMSE, max). Large values come from the shading POV-Ray cannot "
              "match (transparent shadows, total internal reflection; see README).", "",
              "| scene | size | RMSE | max | edge RMSE |", "|---|---|---|---|---|"]
        for c in cross:
            L.append(f"| {c['scene']} | {c['size']} | {fmt(c['rmse'])} | {fmt(c['max_abs'])} | "
                     f"{fmt(c['edge_rmse'])} |")
    L += ["", "## Results", ""]
    for scene in [s[0] for s in SCENES]:
        for size in plan["sizes"]:
            sel = [r for r in rows if r["scene"] == scene and r["size"] == size]
            if not sel:
                continue
            L += [f"### {scene} {size}x{size}", "",
                  "| method | seconds | runs | RMSE | PSNR | max | edge RMSE | edge PSNR | "
                  "edge max |", "|---|---|---|---|---|---|---|---|---|"]
            for r in sel:
                name = r["method"] if r["renderer"] == "locus" else "POV-Ray " + r["method"]
                if "rmse" not in r:
                    L.append(f"| {name} | failed: {r.get('note', '')} | | | | | | | |")
                    continue
                L.append(f"| {name} | {r['seconds']:.3f} | {r['runs']} | {r['rmse']:.5f} | "
                         f"{r['psnr']:.2f} | {r['max_abs']:.3f} | {r['edge_rmse']:.5f} | "
                         f"{r['edge_psnr']:.2f} | {r['edge_max_abs']:.3f} |")
            L.append("")
    L += ["Chart: `accuracy.png` (RMSE), `accuracy_edges.png` (edge RMSE); raw figures "
          "`accuracy.csv`.", ""]
    with open(path, "w") as f:
        f.write("\n".join(L))


def log_axes(ax, title, xlabel, ylabel, size=7):
    """Log-log axes with a light grid, as every chart of the benches has."""
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_title(title, fontsize=size + 2)
    ax.tick_params(labelsize=size)
    ax.grid(True, which="both", alpha=0.25)
    ax.set_xlabel(xlabel, fontsize=size)
    ax.set_ylabel(ylabel, fontsize=size)


def chart(path, rows, conv, plan, metric):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    panels = [(s[0], z) for s in SCENES for z in plan["sizes"]
              if any(r["scene"] == s[0] and r["size"] == z for r in rows)]
    if not panels:
        return
    ncol = min(4, len(panels))
    nrow = (len(panels) + ncol - 1) // ncol
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.6 * nrow), squeeze=False)
    styles = {"local --aa": ("C0", "o", "-", "Locus --aa N (multi-scanning)"),
              "raytrace --spp": ("C1", "s", "-", "Locus raytrace --spp N"),
              "povray +AM1 +R": ("C2", "^", "--", "POV-Ray +AM1 +RN (vs its own ref.)"),
              "povray +AM2 +R": ("C3", "v", "--", "POV-Ray +AM2 +RN (vs its own ref.)")}
    handles = {}
    for ax, (scene, size) in zip(axes.flat, panels):
        for fam, (col, mk, ls, label) in styles.items():
            pts = [(r["seconds"], r[metric], r["param"]) for r in rows
                   if r["scene"] == scene and r["size"] == size and r["family"] == fam
                   and r.get(metric, 0) > 0]
            if not pts:
                continue
            pts.sort(key=lambda p: p[2])
            h, = ax.plot([p[0] for p in pts], [p[1] for p in pts], color=col, marker=mk,
                         linestyle=ls, markersize=4, linewidth=1.2)
            handles[label] = h
            for t, e, n in pts:
                ax.annotate(str(n), (t, e), textcoords="offset points", xytext=(3, 3),
                            fontsize=6, color=col)
        for c in conv:
            if c["scene"] == scene and c["size"] == size and c["renderer"] == "locus" \
                    and c.get(metric, 0) > 0:
                h = ax.axhline(c[metric], color="0.5", linestyle=":", linewidth=1)
                handles["Locus reference: spp16 vs spp32"] = h
        log_axes(ax, f"{scene} {size}x{size}", "render time, 1 thread (s)",
                 "RMSE" if metric == "rmse" else "RMSE over edge pixels")
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    fig.legend(list(handles.values()), list(handles.keys()), loc="lower center",
               ncol=min(5 if ncol > 2 else 2, len(handles)), fontsize=8, frameon=False)
    fig.suptitle("Speed against accuracy (" + ("RMSE" if metric == "rmse" else "edge-pixel RMSE")
                 + " vs reference; lower left is better)", fontsize=10)
    fig.tight_layout(rect=(0, 0.05 if ncol > 2 else 0.12, 1, 0.97))
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()

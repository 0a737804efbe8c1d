"""What bench/peers/run.py and scaling.py share: the renderers with their CPU
times, best-of-N timing, the all-diffuse "floor" copies of scenes, POV-Ray
files, callgrind instruction counts and the log-log fit.

Image reading, error metrics, the reference cache and the POV-Ray
translation are bench/accuracy's (run.py, povscene.py), imported, not copied.
"""
import argparse
import datetime
import importlib.util
import json
import math
import os
import re
import shutil
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SHARED = os.path.normpath(os.path.join(ROOT, "..", "shared"))
SPD = os.path.join(SHARED, "spd")
ACCURACY = os.path.join(ROOT, "bench", "accuracy")


def _load_accuracy():
    # Loaded under its own name: `import run` would find bench/peers/run.py.
    # Its sys.path entry (for povscene) is taken out again, so that `import
    # run` beside this file still finds bench/peers/run.py.
    spec = importlib.util.spec_from_file_location("accuracy_run", os.path.join(ACCURACY, "run.py"))
    mod = importlib.util.module_from_spec(spec)
    saved = list(sys.path)
    spec.loader.exec_module(mod)
    sys.path[:] = saved
    return mod


acc = _load_accuracy()
povscene = acc.povscene
log = acc.log
loadavg = acc.loadavg
cpu_model = acc.cpu_model
host = acc.host
read_image = acc.read_image
metrics = acc.metrics
edge_mask = acc.edge_mask
sha256_file = acc.sha256_file
sha256_text = acc.sha256_text
Cache = acc.Cache
fmt = acc.fmt

# POV-Ray's ray depth: SHADING.md "Ray tree" (common/trace/raytrace.cpp kMaxDepth = 5,
# the primary ray has depth 1) is POV-Ray's max_trace_level 5 (its primary
# ray is level 1 too). povscene.py writes it into every translated file; the
# include header sets it for files we do not write (SPD's own .pov).
POV_DEPTH_INCLUDE = "global_settings { max_trace_level 5 adc_bailout 1/512 }\n"


class Locus(acc.Locus):
    """bench/accuracy's runner; returns the whole --stats JSON."""

    def stats(self, scene, size, args, out, threads=1):
        acc.Locus.render(self, scene, size, args, out, threads)
        with open(os.path.join(self.tmp, "stats.json")) as f:
            return json.load(f)

    def timed(self, scene, size, args, out, threads=1):
        st = self.stats(scene, size, args, out, threads)
        s = st["seconds"]
        # Setup, to set beside POV-Ray's parse + bounding (which reads its
        # scene file): the scene file's load and the frame's prepare.
        return {"cpu": s["render_cpu"], "wall": s["render"],
                "prepare": s.get("prepare", 0.0) + s.get("load", 0.0), "load": s.get("load", 0.0),
                "peak_mib": self.peak_kib / 1024.0, "stats": st}


class PovRay(acc.PovRay):
    """POV-Ray with any anti-aliasing flags; its trace time and CPU-seconds."""
    CPU = re.compile(r"Trace Time:.*?\(([0-9.]+) seconds\)\s*using (\d+) thread\(s\) with "
                     r"([0-9.]+) CPU-seconds", re.S)
    SETUP = re.compile(r"(Parse|Bounding) Time:.*?\(([0-9.]+) seconds\)")

    def __init__(self, tmp):
        acc.PovRay.__init__(self, tmp)
        self.include = os.path.join(tmp, "depth5.inc")
        with open(self.include, "w") as f:
            f.write(POV_DEPTH_INCLUDE)

    def timed(self, pov, size, flags, out, threads=1, include=False):
        cmd = ["povray", "-D", "-P", f"+WT{threads}", f"+W{size}", f"+H{size}", f"+I{pov}",
               f"+O{os.path.basename(out)}", "+FN16", "File_Gamma=1.0"] + list(flags)
        if include:
            cmd.append(f"+HI{self.include}")
        r, peak_kib = acc.run_child(cmd, cwd=os.path.dirname(out))
        m = self.CPU.search(r.stderr)
        if r.returncode != 0 or not m:
            lines = [x for x in r.stderr.strip().splitlines() if "rror" in x] or \
                r.stderr.strip().splitlines()[-1:]
            raise RuntimeError(lines[-1] if lines else f"exit {r.returncode}")
        setup = sum(float(s) for _, s in self.SETUP.findall(r.stderr))
        return {"cpu": float(m.group(3)), "wall": float(m.group(1)), "prepare": setup,
                "peak_mib": peak_kib / 1024.0, "stats": None}


def best(runs):
    """The best of several runs by CPU time (robust to other work on the
    machine); the wall time reported is the smallest of the walls. Returns
    the best run's record plus every run's times."""
    b = dict(min(runs, key=lambda r: r["cpu"]))
    b["wall"] = min(r["wall"] for r in runs)
    b["prepare"] = min(r["prepare"] for r in runs)
    # Peak memory: the largest of the runs (it hardly varies).
    if all("peak_mib" in r for r in runs):
        b["peak_mib"] = max(r["peak_mib"] for r in runs)
    b["all_cpu"] = ";".join(f"{r['cpu']:.4f}" for r in runs)
    b["all_wall"] = ";".join(f"{r['wall']:.4f}" for r in runs)
    b["runs"] = len(runs)
    return b


def summarize(row, runs, image=None, ref=None, mask=None, ref_label=None):
    """Into row: the best of the runs' times (best()) and, given a reference,
    the image's error against it (bench/accuracy's metrics, edge mask).
    Returns the best run's record (with its --stats, for Locus)."""
    b = best(runs)
    row.update({k: b[k] for k in ("cpu", "wall", "prepare", "runs", "all_cpu", "all_wall",
                                  "peak_mib") if k in b})
    if ref is not None:
        row.update(metrics(read_image(image), ref, mask))
        row["reference"] = ref_label
        row["edge_fraction"] = float(mask.mean())
    return b


def best_of(fn, n):
    return best([fn() for _ in range(max(1, n))])


def rounds(jobs, repeat, tag, tmp, prefix):
    """Every job once per round, `repeat` rounds, so a change of load on the
    machine falls on all of them alike. jobs: (key, label, renderer, fn(out)
    -> record); a job that fails is noted and not run again. Returns
    (records per key, each key's image path (the last round's), notes)."""
    ext = {"locus": ".exr", "povray": ".png"}
    results = {key: [] for key, *_ in jobs}
    images, notes = {}, {}
    for rnd in range(repeat):
        for key, label, renderer, fn in jobs:
            if key in notes:
                continue
            out = os.path.join(tmp, f"{prefix}-{key}{ext[renderer]}")
            try:
                results[key].append(fn(out))
                images.setdefault(key, out)
            except RuntimeError as e:
                notes[key] = str(e)
                log(f"{tag} {label}: FAILED: {e}")
        log(f"{tag}: round {rnd + 1}/{repeat}: " + ", ".join(
            f"{k} {results[k][-1]['cpu']:.3f}" for k, *_ in jobs if results[k]))
    return results, images, notes


def references(tag, path, pfile, size, ref_spp, pov_ref, locus, pov, cache, tmp, ncpu):
    """Each renderer's own converged reference, cached under bench/accuracy's
    keys (so the benchmarks share them): Locus `--method raytrace --spp
    ref_spp`, POV-Ray its own `+AM1 +R<pov_ref> +A0.0`, both on all cores.
    Returns ({renderer: image}, {renderer: edge mask}, {renderer: label})."""
    scene_hash = sha256_file(path)
    lkey = f"locus-{locus.sha[:16]}-{scene_hash[:16]}-{size}-spp{ref_spp}"

    def lref(dst):
        dst = dst or os.path.join(tmp, lkey + ".exr")
        log(f"{tag}: reference --method raytrace --spp {ref_spp} ({ncpu} threads)")
        locus.stats(path, size, ["--method", "raytrace", "--spp", str(ref_spp)], dst,
                    threads=ncpu)
        return dst

    pkey = (f"pov-{sha256_text(pov.version)[:8]}-{sha256_file(pfile)[:16]}-{size}"
            f"-am1r{pov_ref}")

    def pref(dst):
        dst = dst or os.path.join(tmp, pkey + ".png")
        log(f"{tag}: POV-Ray reference +AM1 +R{pov_ref} +A0.0 ({ncpu} threads)")
        pov.timed(pfile, size, ["+A0.0", "+AM1", f"+R{pov_ref}"], dst, threads=ncpu)
        return dst

    refs = {}
    for renderer, key, produce, ext in (("locus", lkey, lref, ".exr"),
                                        ("povray", pkey, pref, ".png")):
        try:
            refs[renderer] = read_image(cache.get(key, produce, ext))
        except RuntimeError as e:
            log(f"{tag}: {renderer} reference FAILED: {e}")
    labels = {"locus": f"locus raytrace --spp {ref_spp}",
              "povray": f"povray +AM1 +R{pov_ref} +A0.0"}
    return refs, {k: edge_mask(v) for k, v in refs.items()}, labels


# ------------------------------------------------------------------ scenes

def count_primitives(path):
    """NFF: s, c, p and pp entities; JSON: objects."""
    if path.endswith(".json"):
        with open(path) as f:
            return len(json.load(f).get("objects", []))
    n = 0
    with open(path) as f:
        for line in f:
            tok = line.split(None, 1)
            if tok and tok[0] in ("s", "c", "p", "pp"):
                n += 1
    return n


def diffuse_copy(path, dst_dir):
    """The floor (issue #9 item 3): the same scene with every material made
    diffuse, Ks = 0 and T = 0 (NFF `f r g b Kd Ks Shine T ior`; JSON `ks`,
    `t`), so no reflected or refracted ray is spawned. Kd, colours and
    geometry are untouched; curved bodies still get their eye rays."""
    base = os.path.basename(path)
    stem, ext = os.path.splitext(base)
    dst = os.path.join(dst_dir, stem + ".diffuse" + ext)
    if ext == ".json":
        with open(path) as f:
            sc = json.load(f)
        if '"obj"' in json.dumps(sc):
            raise RuntimeError(f"{path}: refers to an OBJ file by a relative path; "
                               "the diffuse copy would not find it")
        for m in sc.get("materials", []):
            m["ks"] = 0.0
            m["t"] = 0.0
        with open(dst, "w") as f:
            json.dump(sc, f, indent=1)
        return dst
    out = []
    with open(path) as f:
        for line_no, line in enumerate(f, 1):
            tok = line.split()
            if tok and tok[0] == "f":
                if len(tok) < 9:
                    raise RuntimeError(f"{path}:{line_no}: `f` with {len(tok) - 1} fields on "
                                       "one line; expected r g b Kd Ks Shine T ior")
                tok[5] = "0"   # Ks
                tok[7] = "0"   # T
                line = " ".join(tok) + "\n"
            out.append(line)
    with open(dst, "w") as f:
        f.writelines(out)
    return dst


def pov_file(name, path, checked_in, tmp):
    """Our scenes: bench/accuracy/pov (checked in, with a staleness flag);
    NFF: translated by povscene.py into tmp. Returns (path, stale)."""
    if checked_in:
        p = povscene.paper_pov_path(checked_in)
        with open(p) as f:
            stale = povscene.json_to_pov(path) != f.read()
        return p, stale
    p = os.path.join(tmp, name + ".pov")
    with open(p, "w") as f:
        f.write(povscene.nff_to_pov(path))
    return p, False


# ------------------------------------------------------------------ callgrind

HWY_SHIM = """\
// Valgrind 3.19 cannot decode RDTSCP, which libhwy (loaded through
// OpenImageIO) runs in a static initializer, TimerResolution(). This stands in
// for it under LD_PRELOAD; nothing in Locus uses hwy's timers.
#include <cstdint>
namespace hwy { namespace platform { uint64_t TimerResolution() { return 1; } } }
"""


def hwy_shim(tmp):
    src = os.path.join(tmp, "hwyshim.cc")
    lib = os.path.join(tmp, "hwyshim.so")
    with open(src, "w") as f:
        f.write(HWY_SHIM)
    subprocess.run(["g++", "-O2", "-shared", "-fPIC", "-o", lib, src], check=True)
    return lib


# Where render_band's instructions go: inclusive costs of a few functions
# (overlapping: shading includes the secondary rays' searches and shadows).
PROFILE = [("span_shadows", "locus::SpanShadows::compute_light(int)"),
           ("shading", "locus::Tracer::shade("),
           ("ray_search", "locus::Tracer::nearest("),
           ("visibility", "visible_segments(")]


def callgrind(locus, scene, size, args, tmp, shim):
    """Instructions executed inside render_band (scene loading, prepare and
    image writing excluded), the inclusive share of the PROFILE functions,
    and the render's --stats."""
    out = os.path.join(tmp, "cg.out")
    stats = os.path.join(tmp, "cg-stats.json")
    cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
           "--toggle-collect=locus::render_band*", locus.binary, "render", scene,
           "-o", os.path.join(tmp, "cg.exr"), "--size", f"{size}x{size}", "--workers", "0",
           "--threads", "1", "--stats", stats] + list(args)
    env = dict(os.environ, LD_PRELOAD=shim)
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if r.returncode != 0:
        tail = [x for x in r.stderr.splitlines() if not x.startswith("==")][-3:]
        raise RuntimeError("callgrind: " + " / ".join(tail))
    ir = None
    with open(out) as f:
        for line in f:
            if line.startswith("summary:") or line.startswith("totals:"):
                ir = int(line.split()[1])
    shares = {}
    a = subprocess.run(["callgrind_annotate", "--inclusive=yes", "--threshold=100", out],
                       capture_output=True, text=True)
    for line in a.stdout.splitlines():
        m = re.match(r"\s*([0-9,]+) \(\s*[0-9.]+%\)\s+\S*?:(.*) \[", line)
        if not m:
            continue
        cost, fn = int(m.group(1).replace(",", "")), m.group(2)
        for key, prefix in PROFILE:
            # the outermost call only: not a lambda inside it, not a recursion ('2)
            if key not in shares and prefix in fn and "lambda" not in fn and "'" not in fn:
                shares[key] = cost / ir if ir else float("nan")
    with open(stats) as f:
        return ir, shares, json.load(f)


# ------------------------------------------------------------------ fit

def loglog_slope(xs, ys):
    """Least-squares slope of log y against log x."""
    if len(xs) < 2:
        return float("nan")
    lx, ly = np.log(np.asarray(xs, float)), np.log(np.asarray(ys, float))
    return float(np.polyfit(lx, ly, 1)[0])


def run_info(quick, repeat, size, **extra):
    """What every report's header gives: date, load average at the start, the
    commit, the number of cores and the processor, and the run's settings."""
    return dict({"date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"),
                 "load_start": loadavg(), "quick": quick, "repeat": repeat, "size": size,
                 "commit": git_head(), "ncpu": os.cpu_count() or 1,
                 "cpu": cpu_model()}, **extra)


def renderers(binary, tmp, cache_dir, info):
    """A copy of the locus binary (a rebuild during the run cannot mix
    versions), POV-Ray and the reference cache; their versions go into info."""
    locus = Locus(copy_binary(binary, tmp), tmp)
    pov = PovRay(tmp)
    info.update(locus=locus.sha[:12], pov=pov.version)
    log(f"locus {locus.sha[:12]} (HEAD {info['commit']}), {pov.version}, "
        f"load {info['load_start']}")
    return locus, pov, Cache(cache_dir)


def raw_path(given, cache_dir, quick, out_dir, name):
    """Where a run's measurements are saved: --raw, else the cache directory
    (a full run), else the output directory (quick, or no cache)."""
    return given or (os.path.join(cache_dir, name) if cache_dir and not quick
                     else os.path.join(out_dir, name))


def copy_binary(src, tmp):
    return acc.snapshot_locus(src, tmp)


def git_head():
    """HEAD, and "+ local changes" when tracked files of the renderer
    (common/, client/) differ from it: the binary may then not be HEAD's."""
    r = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True,
                       text=True)
    d = subprocess.run(["git", "-C", ROOT, "status", "--porcelain", "--untracked-files=no",
                        "common", "client"], capture_output=True, text=True)
    return (r.stdout.strip() or "?") + (" + local changes" if d.stdout.strip() else "")


def save_raw(path, obj):
    # The cache directory may not exist yet on a fresh machine: a run's
    # measurements must not be lost for want of it.
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w") as f:
        json.dump(obj, f, indent=1, default=str)


def load_raw(path):
    with open(path) as f:
        return json.load(f)


def which(name):
    return shutil.which(name) is not None


def finite(v):
    return isinstance(v, (int, float)) and math.isfinite(v)


def parser(doc, quick_help):
    """The benches' command line: their docstring, --quick (a smoke test,
    described by `quick_help`) and --locus (the binary measured)."""
    ap = argparse.ArgumentParser(description=doc,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help=quick_help)
    ap.add_argument("--locus", default=os.path.join(ROOT, "build", "bin", "locus"))
    return ap

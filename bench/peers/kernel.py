#!/usr/bin/python3
"""The per-ray kernel against Embree (issue #27 item 2): Locus's Whitted ray
tracer `locus render --method raytrace --spp 1` against
`locus-embree-whitted` (bench/peers/embree_whitted.cpp: the same rays on
Intel Embree 3) on every SPD scene of ../shared/spd/{def,s1,s2}, 512x512,
one thread.

Each scene is rendered by both in each of 3 rounds (the order alternating
from round to round), and the best CPU seconds of each are compared:
Locus's `seconds.render_cpu` of --stats, the peer's getrusage over its pixel
loop (scene loading, prepare and Embree's BVH build excluded from both).
The ray counts by kind (eye, reflected, refracted, shadow) must agree within
0.1%; the images' RMS difference (linear, clamped to [0, 1]) is reported.
Target: Locus / Embree <= 1.25 on every scene.

See README.md beside this file, "The ray kernel against Embree".

With --probes, instead: where a ray's time goes, on four one-primitive
scenes written here (every ray misses; every ray hits a polygon, without
and with one light; every ray hits a sphere), 1024x1024 by default, each
renderer's best of --repeat interleaved rounds; the differences give a
miss, a hit of each kind and an unblocked shadow ray in ns (docs/renderer.md,
"The ray kernel against Embree", session 27). Written to kernel-probes.md.

Usage: bench/peers/kernel.py [--quick] [--sets def,s1,s2] [--scenes balls,...]
       bench/peers/kernel.py --report-only bench/results/kernel-raw.json
       bench/peers/kernel.py --probes [--size 1024] [--repeat 5]
Writes bench/results/kernel.{md,csv} and the raw measurements kernel-raw.json
(--quick: a temporary directory).
"""
import csv
import datetime
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
import json

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import harness as H  # noqa: E402

SETS = ("def", "s1", "s2")
KINDS = ("eye", "reflected", "refracted", "shadow")
TARGET = 1.25         # issue #27: Locus CPU time <= 1.25x Embree's
COUNT_TOLERANCE = 1e-3  # ray counts by kind agree within 0.1%
LOCUS_ARGS = ["--method", "raytrace", "--spp", "1"]


class Peer:
    """locus-embree-whitted: its JSON on stdout."""

    def __init__(self, binary, tmp):
        self.binary = binary
        self.sha = H.sha256_file(binary)
        self.tmp = tmp

    def timed(self, scene, size, out):
        cmd = [self.binary, scene, "--size", f"{size}x{size}", "-o", out]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            lines = r.stderr.strip().splitlines()
            raise RuntimeError(lines[-1] if lines else f"exit {r.returncode}")
        # Locus's loader may log a warning on stdout first (spdlog's default).
        text = r.stdout
        st = json.loads(text[text.index("\n{") + 1:] if not text.startswith("{") else text)
        s = st["seconds"]
        return {"cpu": s["render_cpu"], "wall": s["render"], "prepare": s["build"], "stats": st}


# --probes: one primitive each, seen by a camera like the SPD scenes'. The
# sphere out of view keeps the hierarchy non-empty, so a miss walks it.
PROBE_VIEW = ("v\nfrom 0 0 10\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\n"
              "resolution 512 512\nb 0.1 0.1 0.1\n")
PROBE_SURFACE = "f 1 0 0 1 0 0 0 0\n"
PROBES = [
    ("miss", "every ray misses", PROBE_SURFACE + "s 100 100 100 0.5\n"),
    ("polygon", "every ray hits a polygon, no light",
     PROBE_SURFACE + "p 3\n-100 -100 0\n100 -100 0\n0 100 0\n"),
    ("polygon+light", "the same, one light (a shadow ray a pixel, none blocked)",
     "l 0 0 20\n" + PROBE_SURFACE + "p 3\n-100 -100 0\n100 -100 0\n0 100 0\n"),
    ("sphere", "every ray hits a sphere, no light", PROBE_SURFACE + "s 0 0 -1000 990\n"),
]


def probes(locus, peer, size, repeat, tmp, out_dir):
    """The --probes table: each scene's best render CPU, both renderers
    side by side in each round, and ns per eye ray."""
    best = {}
    for name, _, body in PROBES:
        path = os.path.join(tmp, f"probe-{name}.nff")
        with open(path, "w") as f:
            f.write(PROBE_VIEW + body)
    for rnd in range(repeat):
        for name, _, _ in (PROBES if rnd % 2 == 0 else PROBES[::-1]):
            path = os.path.join(tmp, f"probe-{name}.nff")
            pair = [("locus", lambda: locus.timed(path, size, LOCUS_ARGS,
                                                  os.path.join(tmp, "l.exr"))["cpu"]),
                    ("peer", lambda: peer.timed(path, size, os.path.join(tmp, "p.exr"))["cpu"])]
            for who, fn in (pair if rnd % 2 == 0 else pair[::-1]):
                t = fn()
                best[(name, who)] = min(best.get((name, who), math.inf), t)
    rays = float(size * size)
    ns = {k: v / rays * 1e9 for k, v in best.items()}
    lines = ["# Where a ray's time goes: Locus against Embree on one primitive",
             "",
             f"Written by `bench/peers/kernel.py --probes`; do not edit by hand. "
             f"{datetime.datetime.now().strftime('%Y-%m-%d %H:%M')}, {size}x{size}, one thread, "
             f"best of {repeat} interleaved rounds of render CPU (Locus `seconds.render_cpu`, "
             f"the peer's pixel loop). Load average {H.loadavg()}.",
             "",
             "| scene | Locus s | Embree peer s | Locus ns/ray | peer ns/ray |",
             "|---|---:|---:|---:|---:|"]
    for name, label, _ in PROBES:
        lines.append(f"| {label} | {best[(name, 'locus')]:.4f} | {best[(name, 'peer')]:.4f} | "
                     f"{ns[(name, 'locus')]:.1f} | {ns[(name, 'peer')]:.1f} |")
    lines += ["", "| what | Locus ns | peer ns |", "|---|---:|---:|"]
    for label, a, b in (("a miss", "miss", None),
                        ("a polygon hit (over a miss)", "polygon", "miss"),
                        ("a sphere hit (over a miss)", "sphere", "miss"),
                        ("an unblocked shadow ray", "polygon+light", "polygon")):
        row = [ns[(a, w)] - (ns[(b, w)] if b else 0.0) for w in ("locus", "peer")]
        lines.append(f"| {label} | {row[0]:.1f} | {row[1]:.1f} |")
    text = "\n".join(lines) + "\n"
    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, "kernel-probes.md"), "w") as f:
        f.write(text)
    print(text)


def scenes_of(sets, names):
    out = []
    for s in sets:
        d = os.path.join(H.SPD, s)
        if not os.path.isdir(d):
            continue
        for f in sorted(os.listdir(d)):
            if f.endswith(".nff") and (not names or f[:-4] in names):
                out.append((f"{s}/{f[:-4]}", os.path.join(d, f)))
    return out


def rms(a_path, b_path):
    a = np.clip(H.read_image(a_path), 0.0, 1.0)
    b = np.clip(H.read_image(b_path), 0.0, 1.0)
    d = (a - b).astype(np.float64)
    return float(np.sqrt(np.mean(d * d))), float(np.mean(np.abs(d).max(axis=2) > 1.0 / 255.0))


def measure(scenes, size, repeat, locus, peer, tmp, excluded):
    runs = {name: {"locus": [], "embree": []} for name, _ in scenes}
    images = {}
    for rnd in range(repeat):
        for name, path in scenes:
            if name in excluded:
                continue
            base = os.path.join(tmp, name.replace("/", "-"))
            order = ("locus", "embree") if rnd % 2 == 0 else ("embree", "locus")
            for who in order:
                out = f"{base}-{who}.exr"
                try:
                    if who == "locus":
                        r = locus.timed(path, size, LOCUS_ARGS, out)
                    else:
                        r = peer.timed(path, size, out)
                except RuntimeError as e:
                    excluded[name] = f"{who}: {e}"
                    H.log(f"{name}: {who} failed: {e}")
                    break
                runs[name][who].append(r)
                images[name, who] = out
            if name not in excluded:
                lc, ec = runs[name]["locus"][-1]["cpu"], runs[name]["embree"][-1]["cpu"]
                H.log(f"round {rnd + 1} {name}: locus {lc:.3f} s, embree {ec:.3f} s, "
                      f"ratio {lc / ec:.2f}")
    rows = []
    for name, path in scenes:
        if name in excluded:
            continue
        lb, eb = H.best(runs[name]["locus"]), H.best(runs[name]["embree"])
        lr = lb["stats"]["rays"]
        er = eb["stats"]["rays"]
        row = {"scene": name, "primitives": H.count_primitives(path),
               "locus_cpu": lb["cpu"], "embree_cpu": eb["cpu"],
               "locus_wall": lb["wall"], "embree_wall": eb["wall"],
               "locus_all_cpu": lb["all_cpu"], "embree_all_cpu": eb["all_cpu"],
               "locus_prepare": lb["prepare"], "embree_build": eb["prepare"],
               "tests_ray_object": lb["stats"].get("tests", {}).get("ray_object", 0)}
        worst = 0.0
        for k in KINDS:
            row[f"locus_{k}"], row[f"embree_{k}"] = lr.get(k, 0), er.get(k, 0)
            worst = max(worst, abs(lr.get(k, 0) - er.get(k, 0)) / max(lr.get(k, 0), 1))
        row["count_diff"] = worst
        row["rays_total"] = sum(lr.get(k, 0) for k in KINDS)
        row["rmse"], row["frac_diff_pixels"] = rms(images[name, "locus"], images[name, "embree"])
        rows.append(row)
    return rows


def gmean(xs):
    xs = [x for x in xs if x > 0]
    return math.exp(sum(math.log(x) for x in xs) / len(xs)) if xs else float("nan")


def summary(rows):
    ratios = [r["locus_cpu"] / r["embree_cpu"] for r in rows]
    counts_ok = all(r["count_diff"] <= COUNT_TOLERANCE for r in rows)
    passed = sum(1 for x in ratios if x <= TARGET)
    by_set = {}
    for r, x in zip(rows, ratios):
        by_set.setdefault(r["scene"].split("/")[0], []).append(x)
    return {"gmean": gmean(ratios), "passed": passed, "n": len(rows), "counts_ok": counts_ok,
            "by_set": {s: gmean(v) for s, v in by_set.items()},
            "worst": max(zip(ratios, (r["scene"] for r in rows))) if rows else (float("nan"), "")}


FIELDS = ["scene", "primitives", "locus_cpu", "embree_cpu", "ratio", "pass", "locus_wall",
          "embree_wall", "locus_all_cpu", "embree_all_cpu", "locus_prepare", "embree_build",
          "tests_ray_object"] + [f"{w}_{k}" for k in KINDS for w in ("locus", "embree")] + \
         ["count_diff", "rays_total", "locus_us_per_ray", "embree_us_per_ray", "rmse",
          "frac_diff_pixels"]


def derived(r):
    d = dict(r)
    d["ratio"] = r["locus_cpu"] / r["embree_cpu"]
    d["pass"] = "PASS" if d["ratio"] <= TARGET else "FAIL"
    d["locus_us_per_ray"] = 1e6 * r["locus_cpu"] / r["rays_total"]
    d["embree_us_per_ray"] = 1e6 * r["embree_cpu"] / r["rays_total"]
    return d


def report(out_dir, rows, excluded, info):
    os.makedirs(out_dir, exist_ok=True)
    rows = [derived(r) for r in rows]
    with open(os.path.join(out_dir, "kernel.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(FIELDS)
        for r in rows:
            w.writerow([H.fmt(r[k]) if isinstance(r[k], float) else r[k] for k in FIELDS])
    s = summary(rows)
    lines = [
        "# The per-ray kernel: Locus against Embree",
        "",
        "Written by `bench/peers/kernel.py` (README.md beside it, \"The ray kernel against "
        "Embree\"); do not edit by hand. "
        f"{info['date']}, {info['size']}x{info['size']}, one thread, best of {info['repeat']} "
        "CPU times in interleaved rounds. Locus `render --method raytrace --spp 1 --workers 0 "
        "--threads 1` (`seconds.render_cpu`) against `locus-embree-whitted` (the same rays on "
        f"Embree {info.get('embree', '?')}: getrusage over its pixel loop). Locus binary "
        f"{info['locus']} (HEAD {info['commit']}), peer {info['peer']}; {H.host(info)}; load average "
        f"{info['load_start']} at the start, {info.get('load_end', '?')} at the end, "
        f"{info.get('minutes', 0):.0f} min.",
        "",
        f"**Target** (issue #27): Locus / Embree <= {TARGET} on every scene: "
        f"**{'PASS' if s['passed'] == s['n'] and s['n'] else 'FAIL'}** "
        f"({s['passed']} of {s['n']} scenes within it; geometric mean {s['gmean']:.2f}x, "
        f"worst {s['worst'][0]:.2f}x on {s['worst'][1]}). By size: " +
        ", ".join(f"{k} {v:.2f}x" for k, v in s["by_set"].items()) + ".",
        "",
        f"**Ray counts** by kind (eye, reflected, refracted, shadow) agree within "
        f"{100 * COUNT_TOLERANCE:.1f}% on {'every scene' if s['counts_ok'] else 'NOT every scene'} "
        f"(largest difference {100 * max((r['count_diff'] for r in rows), default=0):.4f}%).",
        "",
        "| scene | prims | Locus s | Embree s | Locus/Embree | target | rays | Locus µs/ray "
        "| Embree µs/ray | Locus tests/ray | count diff | RMS diff |",
        "|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['scene']} | {r['primitives']} | {r['locus_cpu']:.3f} | {r['embree_cpu']:.3f} "
            f"| {r['ratio']:.2f} | {r['pass']} | {r['rays_total']:,} | "
            f"{r['locus_us_per_ray']:.3f} | {r['embree_us_per_ray']:.3f} | "
            f"{r['tests_ray_object'] / r['rays_total']:.2f} | {100 * r['count_diff']:.4f}% | "
            f"{r['rmse']:.2e} |")
    lines += ["", "Rays by kind (Locus; the peer's differ by the count diff above):", "",
              "| scene | eye | reflected | refracted | shadow |", "|---|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['scene']} | " +
                     " | ".join(f"{r['locus_' + k]:,}" for k in KINDS) + " |")
    if excluded:
        lines += ["", "Excluded:", ""] + [f"- {k}: {v}" for k, v in sorted(excluded.items())]
    lines += ["", "Every run's CPU seconds are in `kernel.csv` (`locus_all_cpu`, "
              "`embree_all_cpu`); `kernel.py --report-only kernel-raw.json` writes this page "
              "again without measuring.", ""]
    with open(os.path.join(out_dir, "kernel.md"), "w") as f:
        f.write("\n".join(lines))
    H.log(f"{s['passed']} of {s['n']} within {TARGET}; geometric mean {s['gmean']:.2f}; "
          f"counts {'agree' if s['counts_ok'] else 'DIFFER'}; {out_dir}/kernel.md")
    for r in rows:
        print(f"{r['scene']:16s} locus {r['locus_cpu']:7.3f} s  embree {r['embree_cpu']:7.3f} s  "
              f"ratio {r['ratio']:5.2f}  {r['pass']}  counts {100 * r['count_diff']:.4f}%  "
              f"rms {r['rmse']:.2e}")
    print(f"geometric mean {s['gmean']:.2f}  ({s['passed']}/{s['n']} PASS)")


def copies(args, tmp):
    """Both renderers copied into tmp (a rebuild during the run changes
    neither), the peer beside the copy of locus: it writes its EXRs through
    the same plugin."""
    locus = H.Locus(H.copy_binary(args.locus, tmp), tmp)
    peer_bin = os.path.join(os.path.dirname(locus.binary), "locus-embree-whitted")
    shutil.copy2(args.peer, peer_bin)
    return locus, Peer(peer_bin, tmp)


def main():
    ap = H.parser(__doc__, "smoke test: 128x128, def balls and teapot, one round, temp dir")
    ap.add_argument("--peer", default=os.path.join(H.ROOT, "build", "bin", "locus-embree-whitted"))
    ap.add_argument("--sets", default=",".join(SETS), help="SPD sizes (default def,s1,s2)")
    ap.add_argument("--scenes", help="comma-separated scene names (default: every .nff)")
    ap.add_argument("--size", type=int, help="image size (default 512; quick 128)")
    ap.add_argument("--repeat", type=int, default=3, help="best of N rounds (default 3)")
    ap.add_argument("--out", help="output directory (default bench/results; quick: a temp dir)")
    ap.add_argument("--raw", help="save every measurement as JSON here (default: "
                    "kernel-raw.json in the output directory)")
    ap.add_argument("--probes", action="store_true",
                    help="where a ray's time goes: four one-primitive scenes (kernel-probes.md)")
    ap.add_argument("--report-only", metavar="RAW",
                    help="no measuring: write kernel.{md,csv} again from a saved RAW file")
    args = ap.parse_args()
    if args.report_only:
        raw = H.load_raw(args.report_only)
        report(args.out or os.path.join(H.ROOT, "bench", "results"), **raw)
        return
    if args.probes:
        tmp = tempfile.mkdtemp(prefix="locus-kernel-probes-")
        try:
            locus, peer = copies(args, tmp)
            probes(locus, peer, args.size or 1024, 1 if args.quick else args.repeat, tmp,
                   args.out or (os.path.join(H.ROOT, "bench", "results") if not args.quick
                                else tmp))
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        return
    names = args.scenes.split(",") if args.scenes else None
    if args.quick and not names:
        names = ["balls", "teapot"]
    sets = ["def"] if args.quick else args.sets.split(",")
    scenes = scenes_of(sets, names)
    if not scenes:
        ap.error("no scene found")
    if not os.access(args.peer, os.X_OK):
        raise SystemExit(f"{args.peer} not found: build it (needs libembree-dev): "
                         "cmake --build build --target locus-embree-whitted")
    size = args.size or (128 if args.quick else 512)
    repeat = 1 if args.quick else args.repeat
    out_dir = args.out or (os.path.join(H.ROOT, "bench", "results") if not args.quick
                           else tempfile.mkdtemp(prefix="locus-kernel-quick-"))
    started = time.time()
    info = H.run_info(args.quick, repeat, size)
    tmp = tempfile.mkdtemp(prefix="locus-kernel-")
    excluded = {}
    try:
        locus, peer = copies(args, tmp)
        info.update(locus=locus.sha[:12], peer=peer.sha[:12])
        H.log(f"locus {locus.sha[:12]} (HEAD {info['commit']}), peer {peer.sha[:12]}, "
              f"{len(scenes)} scenes, load {info['load_start']}")
        rows = measure(scenes, size, repeat, locus, peer, tmp, excluded)
        if rows:
            info["embree"] = peer.timed(scenes[0][1], 8, os.path.join(tmp, "v.exr"))[
                "stats"]["embree"]["version"]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    info.update(load_end=H.loadavg(), minutes=(time.time() - started) / 60.0)
    raw = {"rows": rows, "excluded": excluded, "info": info}
    os.makedirs(out_dir, exist_ok=True)
    raw_path = args.raw or os.path.join(out_dir, "kernel-raw.json")
    H.save_raw(raw_path, raw)
    H.log(f"raw measurements in {raw_path}")
    report(out_dir, **raw)


if __name__ == "__main__":
    main()

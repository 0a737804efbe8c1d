#!/usr/bin/python3
"""Scaling with scene size (issue #9 item 5): SPD balls and tetra from size
s1 to beyond the default, rendered by Locus (configuration IV, --aa 4 and
--aa 0; for information, --aa 4 with shadow volumes forced and --aa 0 with
the paper's passes forced, scanline and volumes: both passes are chosen
per frame, docs/renderer.md "Visibility by rays", "Shadows by rays") and
POV-Ray
(-A) at 512x512 on one thread; time per frame against primitive count on
log-log axes, with the fitted slopes, and peak memory.

Target lines (issue #27 "Big scenes at POV-Ray's slope"), printed PASS or
FAIL: at the largest level of each kind (balls 5, tetra 9 in a full run),
Locus --aa 0's render CPU below POV-Ray -A's trace CPU; Locus's load +
prepare (the scene file read and checked, the frame prepared) at most 2x
POV-Ray's parse + bounding; the two together below POV-Ray's
parse + bounding + trace; Locus's peak memory at most 2x POV-Ray's. And
the slope of render CPU over the largest 3 levels at most 0.4, for Locus
--aa 0 and --aa 4 (POV-Ray's own is printed beside them).

Levels 1, 2 and the default are ../shared/spd/{s1,s2,def}; the others are
written by spdgen.py (which reproduces those three exactly, `--check`).
See README.md beside this file.

Usage: bench/peers/scaling.py [--quick] [--kinds balls,tetra] [--max-level balls=5,tetra=9]
Writes bench/results/scaling.{md,csv,png} (--quick: a temporary directory).
"""
import csv
import os
import shutil
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import harness as H  # noqa: E402
import spdgen  # noqa: E402

SHARED_LEVELS = {"balls": {1: "s1", 2: "s2", 4: "def"}, "tetra": {1: "s1", 2: "s2", 6: "def"}}
# balls level 6 (597,871 spheres) would need ~9 GB in Locus (level 5: 1.0 GB).
FULL = {"size": 512, "levels": {"balls": [1, 2, 3, 4, 5], "tetra": [1, 2, 3, 4, 5, 6, 7, 8, 9]}}
QUICK = {"size": 128, "levels": {"balls": [1, 2, 3], "tetra": [1, 2, 3, 4]}}
IV = ["--method", "local", "--boxes", "eye+shadow"]
CONFIGS = [("aa4", "Locus IV --aa 4", "locus", IV + ["--aa", "4"]),
           ("aa0", "Locus IV --aa 0", "locus", IV + ["--aa", "0"]),
           # The paper's passes forced where auto casts rays (docs/renderer.md
           # "Visibility by rays", "Shadows by rays"): information, not
           # target lines.
           ("vol4", "Locus IV --aa 4 --shadows volumes", "locus",
            IV + ["--aa", "4", "--shadows", "volumes"]),
           ("scan0", "Locus IV --aa 0 --visibility scanline --shadows volumes", "locus",
            IV + ["--aa", "0", "--visibility", "scanline", "--shadows", "volumes"]),
           ("pov_noaa", "POV-Ray -A", "povray", ["-A"]),
           # POV-Ray's adaptive anti-aliasing (a point of curve.py's best
           # curve), beside Locus's --aa 4: how an adaptive sampler's time
           # grows with the scene's edges. Information, not a target line.
           ("pov_am2", "POV-Ray +AM2 +A0.1 +R3", "povray", ["+AM2", "+A0.1", "+R3"])]
UPPER = 3   # the "large end" fit uses the largest UPPER levels
SLOPE_TARGET = 0.4   # issue #27: render time's slope over the largest UPPER levels
PREPARE_TARGET = 2.0  # Locus prepare <= 2x POV-Ray parse + bounding
MEMORY_TARGET = 2.0   # Locus peak memory <= 2x POV-Ray's


def scene_file(kind, level, tmp):
    sub = SHARED_LEVELS[kind].get(level)
    if sub:
        return os.path.join(H.SPD, sub, kind + ".nff"), sub
    path = os.path.join(tmp, f"{kind}{level}.nff")
    with open(path, "w") as f:
        f.write(spdgen.generate(kind, level))
    return path, "spdgen.py"


def main():
    ap = H.parser(__doc__, "smoke test: 128x128, small levels, one run each (temp dir)")
    ap.add_argument("--kinds", default="balls,tetra")
    ap.add_argument("--max-level", default="",
                    help="e.g. balls=4,tetra=8: leave out the larger levels")
    ap.add_argument("--size", type=int)
    ap.add_argument("--repeat", type=int, default=5, help="best of N rounds (default 5)")
    ap.add_argument("--out", help="output directory (default bench/results; quick: a temp dir)")
    ap.add_argument("--raw", help="save every measurement as JSON here")
    ap.add_argument("--report-only", metavar="RAW", help="write the outputs again from RAW")
    args = ap.parse_args()
    if args.report_only:
        report(args.out or os.path.join(H.ROOT, "bench", "results"),
               **H.load_raw(args.report_only))
        return

    plan = dict(QUICK if args.quick else FULL)
    size = args.size or plan["size"]
    repeat = 1 if args.quick else args.repeat
    caps = dict((k, int(v)) for k, v in (x.split("=") for x in args.max_level.split(",") if x))
    kinds = args.kinds.split(",")
    out_dir = args.out or (os.path.join(H.ROOT, "bench", "results") if not args.quick
                           else tempfile.mkdtemp(prefix="locus-scaling-quick-"))
    started = time.time()
    info = H.run_info(args.quick, repeat, size)
    tmp = tempfile.mkdtemp(prefix="locus-scaling-")
    rows = []
    try:
        locus = H.Locus(H.copy_binary(args.locus, tmp), tmp)
        pov = H.PovRay(tmp)
        info.update(locus=locus.sha[:12], pov=pov.version)
        for kind in kinds:
            levels = [lv for lv in plan["levels"][kind] if not (kind in caps and lv > caps[kind])]
            rows += run_kind(kind, levels, size, repeat, locus, pov, tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    info.update(load_end=H.loadavg(), minutes=(time.time() - started) / 60.0)
    raw = {"rows": rows, "info": info}
    os.makedirs(out_dir, exist_ok=True)
    H.save_raw(args.raw or os.path.join(out_dir if args.quick else
                                        "/var/tmp/locus-bench-accuracy", "scaling-raw.json"), raw)
    report(out_dir, **raw)


def run_kind(kind, levels, size, repeat, locus, pov, tmp):
    """Every level of one kind, all in the same rounds (each level's every
    configuration once per round): a slope is a ratio between levels, so
    the levels are measured side by side, as the configurations are, and a
    drift of the host's speed over the minutes of a run moves them alike."""
    setups = []
    for level in levels:
        path, source = scene_file(kind, level, tmp)
        prims = H.count_primitives(path)
        pfile = os.path.join(tmp, f"{kind}{level}.pov")
        with open(pfile, "w") as f:
            f.write(H.povscene.nff_to_pov(path))
        setups.append({"level": level, "path": path, "source": source, "prims": prims,
                       "pfile": pfile, "tag": f"{kind} level {level} ({prims} primitives)",
                       "runs": {key: [] for key, *_ in CONFIGS}, "notes": {}})
    for _ in range(repeat):
        for s in setups:
            for key, label, renderer, a in CONFIGS:
                if key in s["notes"]:
                    continue
                try:
                    if renderer == "locus":
                        r = locus.timed(s["path"], size, a, os.path.join(tmp, "s.exr"))
                    else:
                        r = pov.timed(s["pfile"], size, a, os.path.join(tmp, "s.png"))
                    s["runs"][key].append(r)
                except RuntimeError as e:
                    s["notes"][key] = str(e)
                    H.log(f"{s['tag']} {label}: FAILED: {e}")
    rows = []
    for s in setups:
        for key, label, renderer, _ in CONFIGS:
            row = {"kind": kind, "level": s["level"], "source": s["source"],
                   "primitives": s["prims"], "size": size, "config": key, "label": label,
                   "renderer": renderer}
            if key in s["notes"]:
                row["note"] = s["notes"][key]
            else:
                b = H.summarize(row, s["runs"][key])
                if b.get("stats"):
                    row["pixels_ray_traced"] = b["stats"]["pixels"]["ray_traced"]
                    row["tests_shadow_volume"] = b["stats"]["tests"]["shadow_volume"]
                    row["tests_ray_object"] = b["stats"]["tests"]["ray_object"]
                    row["visibility"] = b["stats"].get("visibility", {}).get("method", "scanline")
                    row["shadows"] = b["stats"].get("shadows", {}).get("method", "volumes")
                H.log(f"{s['tag']} {label}: {b['cpu']:.3f} s CPU ({b['wall']:.3f} s wall), "
                      f"setup {b['prepare']:.2f} s")
            rows.append(row)
    return rows


# ------------------------------------------------------------------ fits

def series(rows, kind, key, field="cpu"):
    pts = sorted((r["primitives"], r[field]) for r in rows
                 if r["kind"] == kind and r["config"] == key and field in r and r[field] > 0)
    return [p for p, _ in pts], [t for _, t in pts]


def fits(rows):
    """Slopes of log time against log primitives: over every level, and over
    the largest UPPER levels (where the per-pixel cost no longer hides it)."""
    out = []
    for kind in sorted({r["kind"] for r in rows}, key=["balls", "tetra"].index):
        for key, label, renderer, _ in CONFIGS:
            for field, what in (("cpu", "render CPU"), ("prepare", "setup (wall)")):
                xs, ys = series(rows, kind, key, field)
                if len(xs) < 2:
                    continue
                out.append({"kind": kind, "config": key, "label": label, "field": field,
                            "what": what, "levels": len(xs),
                            "slope_all": H.loglog_slope(xs, ys),
                            "slope_upper": H.loglog_slope(xs[-UPPER:], ys[-UPPER:]),
                            "range": f"{xs[0]}–{xs[-1]}",
                            "upper_range": f"{xs[-UPPER:][0]}–{xs[-1]}"})
    return out


def report(out_dir, rows, info):
    os.makedirs(out_dir, exist_ok=True)
    fit = fits(rows)
    write_csv(os.path.join(out_dir, "scaling.csv"), rows, fit)
    lines = write_md(os.path.join(out_dir, "scaling.md"), rows, fit, info)
    chart(os.path.join(out_dir, "scaling.png"), rows, fit, info)
    print("\n".join(lines))
    print(f"results in {out_dir}/scaling.{{md,csv,png}}")


FIELDS = ["kind", "level", "source", "primitives", "size", "config", "label", "renderer", "cpu",
          "wall", "prepare", "peak_mib", "runs", "all_cpu", "all_wall", "pixels_ray_traced",
          "tests_shadow_volume", "tests_ray_object", "visibility", "shadows", "note"]


def write_csv(path, rows, fit):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(FIELDS)
        for r in rows:
            w.writerow([H.fmt(r.get(k)) for k in FIELDS])
    with open(os.path.splitext(path)[0] + "_fit.csv", "w", newline="") as f:
        keys = ["kind", "config", "label", "what", "levels", "range", "slope_all", "upper_range",
                "slope_upper"]
        w = csv.writer(f)
        w.writerow(keys)
        for x in fit:
            w.writerow([H.fmt(x.get(k)) for k in keys])


def sec(v):
    return f"{v:.3f}" if H.finite(v) else "—"


def verdict(ok):
    return "PASS" if ok else "FAIL"


def target_lines(rows, fit):
    """The issue's target lines: the largest level of each kind against
    POV-Ray, and the slopes of the largest UPPER levels."""
    lines = []
    for kind in sorted({r["kind"] for r in rows}, key=["balls", "tetra"].index):
        levels = sorted({r["level"] for r in rows if r["kind"] == kind})
        level = levels[-1]
        g = {r["config"]: r for r in rows if r["kind"] == kind and r["level"] == level}
        loc, pov = g.get("aa0", {}), g.get("pov_noaa", {})
        tag = f"{kind} level {level} ({g[next(iter(g))]['primitives']} primitives)"
        if "cpu" not in loc or "cpu" not in pov:
            lines.append(f"FAIL {tag}: not measured ({loc.get('note') or pov.get('note') or '?'})")
            continue
        lines.append(f"{verdict(loc['cpu'] < pov['cpu'])} {tag}: Locus --aa 0 render "
                     f"{loc['cpu']:.3f} s CPU against POV-Ray -A trace {pov['cpu']:.3f} s "
                     f"({loc['cpu'] / pov['cpu']:.2f}x; target below it)")
        ratio = loc["prepare"] / pov["prepare"] if pov["prepare"] > 0 else float("inf")
        lines.append(f"{verdict(ratio <= PREPARE_TARGET)} {tag}: Locus load + prepare "
                     f"{loc['prepare']:.3f} s against POV-Ray parse + bounding "
                     f"{pov['prepare']:.3f} s ({ratio:.2f}x; target <= {PREPARE_TARGET:g}x)")
        lt, pt = loc["prepare"] + loc["cpu"], pov["prepare"] + pov["cpu"]
        lines.append(f"{verdict(lt < pt)} {tag}: Locus load + prepare + render {lt:.3f} s against "
                     f"POV-Ray parse + bounding + trace {pt:.3f} s ({lt / pt:.2f}x; target "
                     "below it)")
        if "peak_mib" in loc and "peak_mib" in pov:
            m = loc["peak_mib"] / pov["peak_mib"]
            lines.append(f"{verdict(m <= MEMORY_TARGET)} {tag}: peak memory Locus --aa 0 "
                         f"{loc['peak_mib']:.0f} MiB against POV-Ray {pov['peak_mib']:.0f} MiB "
                         f"({m:.2f}x; target <= {MEMORY_TARGET:g}x)")
        else:
            lines.append(f"FAIL {tag}: peak memory not measured")
    pov_slope = {x["kind"]: x["slope_upper"] for x in fit
                 if x["field"] == "cpu" and x["config"] == "pov_noaa"}
    for x in fit:
        if x["field"] != "cpu" or not x["config"].startswith("aa"):
            continue
        ok = x["levels"] >= UPPER and x["slope_upper"] <= SLOPE_TARGET
        lines.append(f"{verdict(ok)} {x['kind']} {x['label']}: slope of render CPU over the "
                     f"largest {UPPER} levels ({x['upper_range']} primitives) "
                     f"{x['slope_upper']:.2f} (target <= {SLOPE_TARGET:g}; POV-Ray -A "
                     f"{pov_slope.get(x['kind'], float('nan')):.2f}; over every level "
                     f"{x['slope_all']:.2f})")
    return lines


def write_md(path, rows, fit, info):
    size = info["size"]
    checks = target_lines(rows, fit)
    L = [f"# Scaling with scene size{' (quick smoke test)' if info['quick'] else ''}", "",
         f"`bench/peers/scaling.py{' --quick' if info['quick'] else ''}`, {info['date']}: locus "
         f"`{info['locus']}` (HEAD `{info['commit']}`), {info['pov']}, {H.host(info)}, load average "
         f"{info['load_start']} at the start and {info['load_end']} at the end, "
         f"{info['minutes']:.0f} min. SPD balls and tetra at {size}x{size}, one thread, ray "
         "depth 5; time per frame is the render's **CPU time** (Locus `seconds.render_cpu`, "
         "POV-Ray's trace CPU-seconds), best of "
         f"{info['repeat']} runs in rounds (each round runs every level of a kind once, "
         "side by side); wall times and setup (Locus `seconds.load` + `seconds.prepare`: the "
         "scene file read and checked, the frame prepared; "
         "POV-Ray parse + bounding, both wall) beside it. Levels 1, 2 and the default are "
         "`../shared/spd/{s1,s2,def}`, the others are written by `spdgen.py` (the same "
         "generator reproduces the shared files exactly). Peak memory is each process's "
         "own largest resident set (GNU time's %M). See bench/peers/README.md.", "",
         "## Targets (issue #27)", "", "```"] + checks + ["```", "", "## Slopes", "",
         "| scene | configuration | fitted on | slope, all levels | slope, largest "
         f"{UPPER} |", "|---|---|---|---|---|"]
    for x in fit:
        L.append(f"| {x['kind']} | {x['label']} | {x['what']} | {x['slope_all']:.2f} "
                 f"({x['range']}) | {x['slope_upper']:.2f} ({x['upper_range']}) |")
    for kind in sorted({r["kind"] for r in rows}, key=["balls", "tetra"].index):
        L += ["", f"## {kind}", "",
              "| level | file | primitives | Locus --aa 4 (its shadows) | Locus --aa 4 volumes | "
              "Locus --aa 0 (its pass) | Locus --aa 0 scanline + volumes | POV-Ray -A | "
              "Locus load + prepare --aa 4 / --aa 0 | POV-Ray parse + bounding | peak MiB: Locus --aa 4 / "
              "--aa 4 volumes / --aa 0 / --aa 0 scanline + volumes / POV-Ray | "
              "Locus --aa 4 shadow-volume tests |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for level in sorted({r["level"] for r in rows if r["kind"] == kind}):
            g = {r["config"]: r for r in rows if r["kind"] == kind and r["level"] == level}
            any_r = next(iter(g.values()))

            def tm(k):
                r = g.get(k)
                if not r or "cpu" not in r:
                    return "failed: " + r.get("note", "") if r else "—"
                return f"{r['cpu']:.3f} ({r['wall']:.2f})"
            a4, a0, pv = g.get("aa4", {}), g.get("aa0", {}), g.get("pov_noaa", {})
            peaks = " / ".join(f"{g[k]['peak_mib']:.0f}" if "peak_mib" in g.get(k, {}) else "—"
                               for k in ("aa4", "vol4", "aa0", "scan0", "pov_noaa"))
            L.append(f"| {level} | {any_r['source']} | {any_r['primitives']} | {tm('aa4')} "
                     f"({a4.get('shadows', '?')}) | {tm('vol4')} | "
                     f"{tm('aa0')} ({a0.get('visibility', '?')}) | {tm('scan0')} | "
                     f"{tm('pov_noaa')} | "
                     f"{sec(a4.get('prepare'))} / {sec(a0.get('prepare'))} | "
                     f"{sec(pv.get('prepare'))} | {peaks} | "
                     f"{H.fmt(a4.get('tests_shadow_volume'))} |")
    L += ["", "Chart: `scaling.png`; figures `scaling.csv`, fits `scaling_fit.csv`.", ""]
    with open(path, "w") as f:
        f.write("\n".join(L))
    return checks


def chart(path, rows, fit, info):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    kinds = sorted({r["kind"] for r in rows}, key=["balls", "tetra"].index)
    if not kinds:
        return
    fig, axes = plt.subplots(1, len(kinds), figsize=(6 * len(kinds), 4.6), squeeze=False)
    style = {"aa4": ("C0", "o"), "vol4": ("C9", "+"), "aa0": ("C4", "s"), "scan0": ("C7", "x"),
             "pov_noaa": ("C3", "^"), "pov_am2": ("C1", "v")}
    for ax, kind in zip(axes[0], kinds):
        for key, label, renderer, _ in CONFIGS:
            xs, ys = series(rows, kind, key)
            if not xs:
                continue
            s = next((x for x in fit if x["kind"] == kind and x["config"] == key
                      and x["field"] == "cpu"), None)
            lab = label + (f" (slope {s['slope_all']:.2f}; largest {UPPER}: "
                           f"{s['slope_upper']:.2f})" if s else "")
            col, mk = style[key]
            ax.plot(xs, ys, color=col, marker=mk, label=lab, linewidth=1.3)
            px, py = series(rows, kind, key, "prepare")
            if px and key not in ("scan0", "vol4"):  # information lines: render only
                ax.plot(px, py, color=col, marker=mk, linestyle=":", markersize=3,
                        linewidth=0.8, alpha=0.7,
                        label=(f"{label}: load + prepare (wall)" if renderer == "locus" else
                               "POV-Ray parse + bounding (wall)"))
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"SPD {kind}, {info['size']}x{info['size']}, one thread", fontsize=10)
        ax.set_xlabel("primitives", fontsize=8)
        ax.set_ylabel("seconds per frame (render CPU; dotted: setup)", fontsize=8)
        ax.grid(True, which="both", alpha=0.25)
        ax.tick_params(labelsize=8)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()

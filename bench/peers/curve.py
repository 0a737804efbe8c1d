#!/usr/bin/python3
"""POV-Ray's best curve (issue #27 item 3): POV-Ray 3.7's adaptive
anti-aliasing, `+AM2` at thresholds 0.3, 0.1, 0.03, 0.01 and `+AM1` at
thresholds 0.3 and 0.1, each at depths `+R2`..`+R4`, against Locus
configuration IV at `--aa 1 2 4 8 16`; CPU time of one thread against RMSE,
each renderer against its own dense reference (bench/peers/run.py's). The
lower envelope of POV-Ray's points (its best curve) and, per scene, whether
Locus's curve lies below it.

Scenes: bench/peers/run.py's ten (SPD default sizes and our (a), (b), (d))
and the big levels of scaling.py: balls level 5, tetra levels 8 and 9
(spdgen.py), all at 512x512.

See README.md beside this file ("POV-Ray's best curve") for the definitions.

Usage: bench/peers/curve.py [--quick] [--scenes d,balls,balls5,...] [--repeat N]
       bench/peers/curve.py --report-only RAW
Writes bench/results/curve.{md,csv,png} (--quick: a temporary directory).
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
import run as peers  # noqa: E402
import scaling  # noqa: E402

# The big levels: (name, SPD kind, recursion level), written by spdgen.py.
BIG = [("balls5", "balls", 5), ("tetra8", "tetra", 8), ("tetra9", "tetra", 9)]
ORDER = [s[0] for s in peers.SCENES] + [b[0] for b in BIG]

AA = [1, 2, 4, 8, 16]
# POV-Ray's adaptive anti-aliasing (the points): +A<threshold> +AM<method> +R<depth>.
POV_POINTS = ([(2, t, r) for t in ("0.3", "0.1", "0.03", "0.01") for r in (2, 3, 4)] +
              [(1, t, r) for t in ("0.3", "0.1") for r in (2, 3, 4)])

FULL = {"size": 512, "ref_spp": peers.FULL["ref_spp"], "pov_ref": peers.FULL["pov_ref"]}
QUICK = {"size": 64, "ref_spp": peers.QUICK["ref_spp"], "pov_ref": peers.QUICK["pov_ref"]}
QUICK_SCENES = ["d_spheres_2lights", "tetra"]


def configs():
    """(key, label, renderer, arguments) of every point of a scene."""
    out = [(f"aa{n}", f"Locus IV --aa {n}", "locus", peers.IV + ["--aa", str(n)]) for n in AA]
    for m, t, r in POV_POINTS:
        out.append((f"pov_am{m}_a{t}_r{r}", f"POV-Ray +A{t} +AM{m} +R{r}", "povray",
                    [f"+A{t}", f"+AM{m}", f"+R{r}"]))
    return out


def scene_list(want, quick, tmp):
    """(name, scene file, checked-in .pov or None) of the scenes asked for."""
    if want:
        names = [peers.ALIASES.get(s, s) for s in want.split(",")]
    else:
        names = QUICK_SCENES if quick else ORDER
    unknown = [n for n in names if n not in ORDER]
    if unknown:
        raise SystemExit(f"unknown scene(s) {','.join(unknown)}; known: {','.join(ORDER)}")
    paths = {n: (p, c) for n, p, c in peers.SCENES}
    for name, kind, level in BIG:
        if name in names:
            paths[name] = (scaling.scene_file(kind, level, tmp)[0], None)
    # In the order asked for (a long run can put the scenes it must have first).
    return [(n,) + paths[n] for n in dict.fromkeys(names)]


def main():
    ap = H.parser(__doc__, "smoke test: 64x64, scenes (d) and tetra, one run each, cheap "
                    "references; results in a temp dir")
    ap.add_argument("--scenes", help="comma-separated subset of " + ",".join(ORDER) +
                    " (a, b, d accepted)")
    ap.add_argument("--size", type=int, help="image size (default 512; quick 64)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="best of N runs, in interleaved rounds (default 3)")
    ap.add_argument("--cache", default="/var/tmp/locus-bench-accuracy",
                    help="reference images (shared with run.py and bench/accuracy)")
    ap.add_argument("--out", help="output directory (default bench/results; quick: a temp dir)")
    ap.add_argument("--raw", help="save every measurement as JSON here (default: "
                    "curve-raw.json in the cache directory; quick: in the output directory)")
    ap.add_argument("--report-only", metavar="RAW[,RAW...]",
                    help="no measuring: write curve.{md,csv,png} again from saved RAW files "
                    "(several: runs of other scenes, e.g. two halves run at once)")
    args = ap.parse_args()
    if args.report_only:
        report(args.out or os.path.join(H.ROOT, "bench", "results"),
               **merge_raws(args.report_only.split(",")))
        return
    if not H.which("povray"):
        raise SystemExit("povray not found (apt-get install povray): this benchmark compares "
                         "against it")
    plan = dict(QUICK if args.quick else FULL)
    if args.size:
        plan["size"] = args.size
    size = plan["size"]
    repeat = 1 if args.quick else args.repeat
    out_dir = args.out or (os.path.join(H.ROOT, "bench", "results") if not args.quick
                           else tempfile.mkdtemp(prefix="locus-curve-quick-"))
    ncpu = os.cpu_count() or 1
    started = time.time()
    info = H.run_info(args.quick, repeat, size, plan=plan)
    tmp = tempfile.mkdtemp(prefix="locus-curve-")
    rows, stale = [], []
    raw_path = H.raw_path(args.raw, args.cache, args.quick, out_dir, "curve-raw.json")
    try:
        locus, pov, cache = H.renderers(args.locus, tmp, args.cache, info)
        for name, path, checked_in in scene_list(args.scenes, args.quick, tmp):
            rows += run_scene(name, path, checked_in, plan, repeat, locus, pov, cache, tmp,
                              ncpu, stale)
            # Saved after every scene: a run cut short keeps what it measured
            # (--report-only reports it; info has no end yet).
            H.save_raw(raw_path, {"rows": rows, "info": dict(
                info, partial=True, load_end=H.loadavg(),
                minutes=(time.time() - started) / 60.0)})
        info["locus_changed"] = (os.path.exists(args.locus) and
                                 H.sha256_file(args.locus) != locus.sha)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    info.update(load_end=H.loadavg(), minutes=(time.time() - started) / 60.0, stale=stale)
    raw = {"rows": rows, "info": info}
    H.save_raw(raw_path, raw)
    H.log(f"raw measurements in {raw_path}")
    report(out_dir, **raw)


def merge_raws(paths):
    """One report from several runs' raw files: every scene from the first
    file that has it; the runs' headers are kept in info["runs"]."""
    raws = [H.load_raw(p) for p in paths]
    if len(raws) == 1:
        return raws[0]
    rows, seen = [], set()
    for raw in raws:
        scenes = {r["scene"] for r in raw["rows"]} - seen
        rows += [r for r in raw["rows"] if r["scene"] in scenes]
        seen |= scenes
    taken = []
    for raw in raws:
        taken.append(sorted({r["scene"] for r in raw["rows"]} - {t for x in taken for t in x}))
    info = dict(raws[0]["info"], runs=[dict(r["info"], scenes=t) for r, t in zip(raws, taken)
                                       if t])
    return {"rows": rows, "info": info}


def run_scene(name, path, checked_in, plan, repeat, locus, pov, cache, tmp, ncpu, stale):
    size = plan["size"]
    prims = H.count_primitives(path)
    tag = f"{name} {size}x{size}"
    pfile, is_stale = H.pov_file(name, path, checked_in, tmp)
    if is_stale:
        stale.append(name)
    jobs = []
    for key, label, renderer, a in configs():
        if renderer == "locus":
            jobs.append((key, label, renderer, lambda out, a=a: locus.timed(path, size, a, out)))
        else:
            jobs.append((key, label, renderer, lambda out, a=a: pov.timed(pfile, size, a, out)))
    results, images, notes = H.rounds(jobs, repeat, tag, tmp, name)
    refs, masks, ref_labels = H.references(tag, path, pfile, size, plan["ref_spp"],
                                           plan["pov_ref"], locus, pov, cache, tmp, ncpu)
    rows = []
    for key, label, renderer, _ in jobs:
        row = {"scene": name, "size": size, "primitives": prims, "config": key,
               "label": label, "renderer": renderer,
               "binary": locus.sha[:12] if renderer == "locus" else pov.version}
        if key in notes:
            row["note"] = notes[key]
        else:
            H.summarize(row, results[key], images[key], refs.get(renderer),
                        masks.get(renderer), ref_labels[renderer])
            H.log(f"{tag} {label}: {row['cpu']:.3f} s CPU"
                  + (f", RMSE {row['rmse']:.5f}" if "rmse" in row else ""))
        rows.append(row)
    return rows


# ------------------------------------------------------------------ the curves

def points(rows, scene, renderer, metric="rmse"):
    """(CPU seconds, error, row) of a scene's measured points of one renderer."""
    return sorted(((r["cpu"], r[metric], r) for r in rows
                   if r["scene"] == scene and r["renderer"] == renderer and "cpu" in r
                   and H.finite(r.get(metric)) and r[metric] > 0 and r["cpu"] > 0),
                  key=lambda p: (p[0], p[1]))


def envelope(pts):
    """The lower envelope of (time, error) points: those no other point beats
    in both (less or equal time and less error), sorted by time, so the error
    falls from each to the next. Joined in log-log, it lies at or below
    every point measured within its time range."""
    out = []
    for p in sorted(pts, key=lambda p: (p[0], p[1])):
        if not out or p[1] < out[-1][1]:
            out.append(p)
    return out


def time_at_error(env, err):
    """The envelope's time at a given error (log-log interpolation), or None
    outside the range of errors it spans."""
    if not env:
        return None
    es = [p[1] for p in env][::-1]   # increasing error
    ts = [p[0] for p in env][::-1]
    if err < es[0] or err > es[-1]:
        return None
    return H.acc.interp_loglog(es, ts, err)


def verdict(rows, scene, metric="rmse"):
    """(ok, line, envelope, Locus points): Locus's curve against POV-Ray's
    envelope by bench/accuracy's curve_below, each as the error it reaches
    within a time (README "POV-Ray's best curve")."""
    lp = points(rows, scene, "locus", metric)
    env = envelope(points(rows, scene, "povray", metric))
    ok, det = H.acc.curve_below([p[:2] for p in envelope(lp)], [p[:2] for p in env],
                                other="POV-Ray's envelope", within_time=True)
    gains = []
    for t, e, r in lp:
        te = time_at_error(env, e)
        if te:
            gains.append((te / t, r["config"]))
    gain = (f"; POV-Ray's envelope needs {min(gains)[0]:.2f}x ({min(gains)[1]}) to "
            f"{max(gains)[0]:.2f}x ({max(gains)[1]}) Locus's time at Locus's error"
            if gains else "; no Locus point within the envelope's RMSE range")
    det = det.split("; ")
    det = "; ".join(det[:3]) + (f"; ... ({len(det) - 3} more times)" if len(det) > 3 else "")
    size = lp[0][2]["size"] if lp else (env[0][2]["size"] if env else 0)
    word = {True: "PASS", False: "FAIL", None: "N/A "}[ok]
    what = "RMSE" if metric == "rmse" else "edge RMSE"
    line = (f"{word} {scene} {size}x{size}: Locus's curve below POV-Ray's envelope "
            f"({what}; {len(lp)} Locus points, {len(env)} of "
            f"{len(points(rows, scene, 'povray', metric))} POV-Ray points on the envelope)"
            + gain + (f"; {det}" if det else ""))
    return ok, line, env, lp


def scenes_of(rows):
    have = {r["scene"] for r in rows}
    return [s for s in ORDER if s in have]


def report(out_dir, rows, info):
    os.makedirs(out_dir, exist_ok=True)
    checks, edge_checks = [], []
    for s in scenes_of(rows):
        ok, line, env, _ = verdict(rows, s)
        checks.append((ok, line))
        on = {id(p[2]) for p in env}
        for r in rows:
            if r["scene"] == s and r["renderer"] == "povray":
                r["on_envelope"] = int(id(r) in on)
        edge_checks.append(verdict(rows, s, "edge_rmse")[:2])
    n_ok = sum(1 for ok, _ in checks if ok)
    total = f"{'PASS' if checks and n_ok == len(checks) else 'FAIL'} Locus's curve below " \
            f"POV-Ray's best (adaptive) curve on {n_ok} of {len(checks)} scenes (RMSE; " \
            "needs every scene)"
    lines = [line for _, line in checks] + [total]
    write_csv(os.path.join(out_dir, "curve.csv"), rows)
    write_md(os.path.join(out_dir, "curve.md"), rows, lines,
             [line for _, line in edge_checks], info)
    chart(os.path.join(out_dir, "curve.png"), rows, info)
    print("\n".join(lines))
    print(f"results in {out_dir}/curve.{{md,csv,png}}")


FIELDS = ["scene", "size", "primitives", "config", "label", "renderer", "cpu", "wall",
          "prepare", "runs", "all_cpu", "all_wall", "rmse", "psnr", "max_abs", "edge_rmse",
          "edge_psnr", "edge_max_abs", "edge_fraction", "on_envelope", "reference", "binary",
          "note"]


def write_csv(path, rows):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(FIELDS)
        for r in rows:
            w.writerow([H.fmt(r.get(k)) for k in FIELDS])


def write_md(path, rows, lines, edge_lines, info):
    size = info["size"]
    q = " --quick" if info["quick"] else ""
    L = [f"# POV-Ray's best curve against Locus{' (quick smoke test)' if info['quick'] else ''}",
         "",
         f"`bench/peers/curve.py{q}`, {info['date']}: locus `{info['locus']}` (HEAD "
         f"`{info['commit']}`), {info['pov']}, {H.host(info)}, load average "
         f"{info['load_start']} at the start and {info.get('load_end', '?')} at the end"
         + (f", {info['minutes']:.0f} min" if "minutes" in info else "")
         + (" (a partial run: the scenes measured before it stopped)" if info.get("partial")
            else "") +
         f". {size}x{size}, ray depth 5 (both), one thread. Time: "
         "CPU seconds of the render (Locus `seconds.render_cpu`, POV-Ray's trace "
         f"CPU-seconds), best of {info['repeat']} run(s) taken in interleaved rounds (every "
         "point of a scene once per round). Error: RMSE against each renderer's own dense "
         f"reference (Locus `--method raytrace --spp {info['plan']['ref_spp']}`, POV-Ray "
         f"`+AM1 +R{info['plan']['pov_ref']} +A0.0`). POV-Ray's envelope: the points no "
         "other POV-Ray point beats in both time and RMSE, joined in log-log. Definitions: "
         "bench/peers/README.md, \"POV-Ray's best curve\".", ""]
    for run in info.get("runs", []):
        L += [f"- run of {run['date']} ({', '.join(run['scenes'])}): locus `{run['locus']}`, "
              f"load average {run['load_start']} at the start and "
              f"{run.get('load_end', '?')} at the end"
              + (f", {run['minutes']:.0f} min" if "minutes" in run else "")
              + (", cut short" if run.get("partial") else "")]
    if info.get("runs"):
        L += ["", "The header's figures are the first run's. Each run measured its own scenes, "
              "every point of a scene (Locus's and POV-Ray's) in that one run; a scene "
              "measured in more than one run is taken from the first run listed.", ""]
    if info.get("locus_changed"):
        L += ["**The locus binary changed during the run; every figure comes from the copy "
              "taken at the start.**", ""]
    if info.get("stale"):
        L += ["**" + ", ".join(info["stale"]) + ": bench/accuracy/pov differs from a fresh "
              "translation of the JSON.**", ""]
    L += ["## Target (issue #27 item 3)", "", "```"] + lines + ["```", "",
          "Edge-pixel RMSE, the same comparison (information, not the target):", "", "```"] + \
        edge_lines + ["```", ""]
    for s in scenes_of(rows):
        env = {id(p[2]) for p in envelope(points(rows, s, "povray"))}
        env_pts = envelope(points(rows, s, "povray"))
        srows = [r for r in rows if r["scene"] == s]
        prims = srows[0]["primitives"]
        L += [f"## {s} ({prims} primitives)", "",
              "| configuration | CPU s | wall s | RMSE | edge RMSE | POV-Ray envelope | "
              "envelope's time at this RMSE ÷ Locus's |", "|---|---|---|---|---|---|---|"]
        for r in sorted(srows, key=lambda r: (r["renderer"] != "locus", r.get("cpu", 1e9))):
            if "cpu" not in r:
                L.append(f"| {r['label']} | failed: {r.get('note', '')} | | | | | |")
                continue
            mark = ("**yes**" if id(r) in env else "") if r["renderer"] == "povray" else ""
            gain = ""
            if r["renderer"] == "locus" and H.finite(r.get("rmse")):
                te = time_at_error(env_pts, r["rmse"])
                gain = f"{te / r['cpu']:.2f}" if te else "outside"
            L.append(f"| {r['label']} | {r['cpu']:.3f} | {r['wall']:.3f} | "
                     f"{peers.e(r)} | {peers.e(r, 'edge_rmse')} | {mark} | {gain} |")
        L.append("")
    L += ["Chart: `curve.png`; every figure and every run's time: `curve.csv`.", ""]
    with open(path, "w") as f:
        f.write("\n".join(L))


def chart(path, rows, info):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    scenes = scenes_of(rows)
    if not scenes:
        return
    ncol = min(4, len(scenes))
    nrow = (len(scenes) + ncol - 1) // ncol
    fig, axes = plt.subplots(nrow, ncol, figsize=(max(4.2 * ncol, 8.4), 3.6 * nrow + 0.8),
                             squeeze=False)
    handles = {}
    fam_style = {"+AM2": ("C3", "v"), "+AM1": ("C2", "^")}
    for ax, s in zip(axes.flat, scenes):
        for t, e, r in points(rows, s, "povray"):
            fam = "+AM2" if "+AM2" in r["label"] else "+AM1"
            col, mk = fam_style[fam]
            h = ax.scatter([t], [e], color=col, marker=mk, s=14, alpha=0.6, linewidths=0)
            handles[f"POV-Ray +A<t> {fam} +R<d> (vs its own ref.)"] = h
        env = envelope(points(rows, s, "povray"))
        if env:
            h, = ax.plot([p[0] for p in env], [p[1] for p in env], color="C3", linestyle="--",
                         linewidth=1.2)
            handles["POV-Ray's envelope (best curve)"] = h
            for t, e, r in env:
                ax.annotate(r["label"].replace("POV-Ray ", ""), (t, e), textcoords="offset points",
                            xytext=(3, 3), fontsize=5, color="C3")
        lp = points(rows, s, "locus")
        if lp:
            h, = ax.plot([p[0] for p in lp], [p[1] for p in lp], color="C0", marker="o",
                         markersize=4, linewidth=1.3)
            handles["Locus IV --aa N (vs its own ref.)"] = h
            for t, e, r in lp:
                ax.annotate(r["config"][2:], (t, e), textcoords="offset points", xytext=(3, 3),
                            fontsize=6, color="C0")
        ok = verdict(rows, s)[0]
        H.acc.log_axes(ax, f"{s} {info['size']}x{info['size']}: "
                       f"{ {True: 'PASS', False: 'FAIL', None: 'N/A'}[ok]}",
                       "render CPU time, 1 thread (s)", "RMSE vs own reference")
    for ax in list(axes.flat)[len(scenes):]:
        ax.axis("off")
    fig.legend(list(handles.values()), list(handles.keys()), loc="lower center",
               ncol=min(4 if ncol > 2 else 2, len(handles)), fontsize=8, frameon=False)
    fig.suptitle("Locus against POV-Ray's adaptive anti-aliasing (RMSE vs each renderer's "
                 "own reference; lower left is better)", fontsize=10)
    fig.tight_layout(rect=(0, 0.8 / (3.6 * nrow + 0.8) + (0.04 if ncol <= 2 else 0), 1, 0.95))
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()

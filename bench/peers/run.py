#!/usr/bin/python3
"""Locus against POV-Ray 3.7 (issue #9 items 1, 3 and the instruction counts
of item 2): SPD balls, rings, gears, teapot, tetra, mount, tree at their
default size and our scenes (a), (b), (d), at 512x512, ray depth 5, one
thread.

- Locus configuration IV (`--method local --boxes eye+shadow`) at `--aa 4`
  and `--aa 0`, and its own BVH ray tracer at `--spp 2` (the same 4 samples
  per pixel as --aa 4 and POV-Ray +R2);
- POV-Ray `+A0.0 +AM1 +R2` and `-A`;
- the floor: Locus --aa 4 on a copy with every material diffuse (Ks = T = 0);
- errors against each renderer's own converged reference;
- the issue's acceptance figures, side by side on scene (d);
- instructions per pixel (callgrind) at 128x128.

See README.md beside this file for the definitions.

Usage: bench/peers/run.py [--quick] [--scenes d,balls,...] [--no-callgrind]
Writes bench/results/peers.{md,csv,png} (--quick: a temporary directory).
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

DEF = os.path.join(H.SPD, "def")
PAPER = os.path.join(H.ROOT, "scenes", "paper")
# name, scene file, checked-in .pov of bench/accuracy (None: translated from the NFF)
SCENES = [(n, os.path.join(DEF, n + ".nff"), None)
          for n in ("balls", "rings", "gears", "teapot", "tetra", "mount", "tree")]
SCENES += [(n, os.path.join(PAPER, n + ".json"), n)
           for n in ("a_glass", "b_desk", "d_spheres_2lights")]
SPD_NAMES = [s[0] for s in SCENES[:7]]
ALIASES = {"a": "a_glass", "b": "b_desk", "d": "d_spheres_2lights"}
ACCEPT_SCENE = "d_spheres_2lights"

IV = ["--method", "local", "--boxes", "eye+shadow"]
# key, label, renderer, arguments; the floor is "aa4" on the diffuse copy.
LOCUS = [("aa4", "Locus IV --aa 4", IV + ["--aa", "4"]),
         ("aa0", "Locus IV --aa 0", IV + ["--aa", "0"]),
         ("spp2", "Locus raytrace --spp 2 (BVH)",
          ["--method", "raytrace", "--boxes", "eye+shadow", "--spp", "2"])]
# Only on the acceptance scene: configuration I (plain ray tracer, no boxes)
# at the same 4 samples per pixel, and configuration II at --aa 4.
LOCUS_ACCEPT = [("conf1", "Locus I: raytrace --boxes none --spp 2",
                 ["--method", "raytrace", "--boxes", "none", "--spp", "2"]),
                ("conf2aa4", "Locus II: local --boxes none --aa 4",
                 ["--method", "local", "--boxes", "none", "--aa", "4"])]
POV = [("pov_r2", "POV-Ray +A0.0 +AM1 +R2", ["+A0.0", "+AM1", "+R2"]),
       ("pov_noaa", "POV-Ray -A", ["-A"])]
# scene, --aa values (gears: the largest share of span shadows; 10 min a run)
CALLGRIND = [("d_spheres_2lights", ("4", "0")), ("a_glass", ("4", "0")), ("b_desk", ("4", "0")),
             ("tetra", ("4", "0")), ("gears", ("4",))]

FULL = {"size": 512, "ref_spp": 16, "pov_ref": 8, "cg_size": 128}
QUICK = {"size": 128, "ref_spp": 4, "pov_ref": 3, "cg_size": 48}


def main():
    ap = H.parser(__doc__, "smoke test: 128x128, scenes d and teapot, one run each, cheap "
                    "references, callgrind at 48x48 on (d); results in a temp dir")
    ap.add_argument("--scenes", help="comma-separated subset of " +
                    ",".join(s[0] for s in SCENES) + " (a, b, d accepted)")
    ap.add_argument("--size", type=int, help="image size (default 512; quick 128)")
    ap.add_argument("--repeat", type=int, default=3, help="best of N runs (default 3)")
    ap.add_argument("--no-callgrind", action="store_true", help="skip instruction counts")
    ap.add_argument("--no-spd-pov", action="store_true",
                    help="skip timing POV-Ray -A on SPD's own ../shared/spd/pov files")
    ap.add_argument("--cache", default="/var/tmp/locus-bench-accuracy",
                    help="reference images (shared with bench/accuracy, same keys); '' disables")
    ap.add_argument("--keep", help="also keep every image in this directory")
    ap.add_argument("--out", help="output directory (default bench/results; quick: a temp dir)")
    ap.add_argument("--raw", help="also save every measurement as JSON here (default: "
                    "peers-raw.json in the cache directory)")
    ap.add_argument("--report-only", metavar="RAW",
                    help="no measuring: write peers.{md,csv,png} again from a saved RAW file")
    ap.add_argument("--redo-callgrind", metavar="RAW",
                    help="measure only the instruction counts again, into a saved RAW file "
                    "(with its locus binary: give --locus the same one), and report")
    args = ap.parse_args()
    if args.report_only:
        raw = H.load_raw(args.report_only)
        report(args.out or os.path.join(H.ROOT, "bench", "results"), **raw)
        return
    if args.redo_callgrind:
        raw = H.load_raw(args.redo_callgrind)
        tmp = tempfile.mkdtemp(prefix="locus-peers-")
        try:
            locus = H.Locus(H.copy_binary(args.locus, tmp), tmp)
            if locus.sha[:12] != raw["info"].get("locus"):
                raise SystemExit(f"{args.locus} is {locus.sha[:12]}, the run was made with "
                                 f"{raw['info'].get('locus')}")
            raw["cg_rows"] = instructions(CALLGRIND, FULL["cg_size"], locus, tmp)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        H.save_raw(args.redo_callgrind, raw)
        report(args.out or os.path.join(H.ROOT, "bench", "results"), **raw)
        return

    plan = dict(QUICK if args.quick else FULL)
    if args.size:
        plan["size"] = args.size
    repeat = 1 if args.quick else args.repeat
    scenes = SCENES
    if args.scenes:
        want = [ALIASES.get(s, s) for s in args.scenes.split(",")]
        scenes = [s for s in SCENES if s[0] in want]
        if len(scenes) != len(want):
            ap.error(f"unknown scene in {args.scenes}")
    elif args.quick:
        scenes = [s for s in SCENES if s[0] in ("teapot", ACCEPT_SCENE)]
    out_dir = args.out or (os.path.join(H.ROOT, "bench", "results") if not args.quick
                           else tempfile.mkdtemp(prefix="locus-peers-quick-"))
    os.makedirs(out_dir, exist_ok=True)
    if not H.which("povray"):
        raise SystemExit("povray not found (apt-get install povray): this benchmark compares "
                         "against it")
    size = plan["size"]
    ncpu = os.cpu_count() or 1
    started = time.time()
    info = H.run_info(args.quick, repeat, size, plan=plan)

    tmp = tempfile.mkdtemp(prefix="locus-peers-")
    rows, excluded, stale, cg_rows = [], [], [], []
    try:
        locus, pov, cache = H.renderers(args.locus, tmp, args.cache, info)

        for name, path, checked_in in scenes:
            rows += run_scene(name, path, checked_in, size, plan, repeat, locus, pov, cache,
                              tmp, ncpu, args, excluded, stale)

        if not args.no_callgrind:
            if H.which("valgrind"):
                cg_rows = instructions(CALLGRIND[:1] if args.quick else CALLGRIND,
                                       plan["cg_size"], locus, tmp)
            else:
                H.log("valgrind not found: no instruction counts")
        info["locus_changed"] = (os.path.exists(args.locus) and
                                 H.sha256_file(args.locus) != locus.sha)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    info.update(load_end=H.loadavg(), minutes=(time.time() - started) / 60.0, stale=stale)
    raw = {"rows": rows, "cg_rows": cg_rows, "excluded": excluded, "info": info}
    raw_path = H.raw_path(args.raw, args.cache, args.quick, out_dir, "peers-raw.json")
    H.save_raw(raw_path, raw)
    H.log(f"raw measurements in {raw_path}")
    report(out_dir, **raw)


def report(out_dir, rows, cg_rows, excluded, info):
    os.makedirs(out_dir, exist_ok=True)
    checks = acceptance(rows)
    write_csv(os.path.join(out_dir, "peers.csv"), rows, cg_rows)
    write_md(os.path.join(out_dir, "peers.md"), rows, cg_rows, excluded, checks, info)
    chart(os.path.join(out_dir, "peers.png"), rows, info)
    print("\n".join(checks))
    print(f"results in {out_dir}/peers.{{md,csv,png}}")


# ------------------------------------------------------------------ one scene

def run_scene(name, path, checked_in, size, plan, repeat, locus, pov, cache, tmp, ncpu, args,
              excluded, stale):
    prims = H.count_primitives(path)
    tag = f"{name} {size}x{size}"
    # A scene Locus cannot load or render is reported and left out, not hidden.
    probe = os.path.join(tmp, "probe.exr")
    try:
        locus.stats(path, 8, IV + ["--aa", "0"], probe)
    except RuntimeError as e:
        H.log(f"{tag}: Locus cannot render it: {e} (excluded)")
        excluded.append((name, str(e)))
        return []

    floor_path = H.diffuse_copy(path, tmp)
    pfile, is_stale = H.pov_file(name, path, checked_in, tmp)
    if is_stale:
        stale.append(name)
    spd_pov = os.path.join(H.SPD, "pov", name + ".pov")

    jobs = []   # (key, label, renderer, fn(out) -> record)
    configs = LOCUS + (LOCUS_ACCEPT if name == ACCEPT_SCENE else [])
    for key, label, margs in configs:
        jobs.append((key, label, "locus",
                     lambda out, a=margs: locus.timed(path, size, a, out)))
    jobs.append(("floor", "Locus IV --aa 4, all diffuse (floor)", "locus",
                 lambda out: locus.timed(floor_path, size, IV + ["--aa", "4"], out)))
    for key, label, flags in POV:
        jobs.append((key, label, "povray", lambda out, f=flags: pov.timed(pfile, size, f, out)))
    if not args.no_spd_pov and os.path.exists(spd_pov) and name in SPD_NAMES:
        jobs.append(("spdpov_noaa", "POV-Ray -A on SPD's own .pov", "povray",
                     lambda out: pov.timed(spd_pov, size, ["-A"], out, include=True)))

    results, images, notes = H.rounds(jobs, repeat, tag, tmp, name)
    # References, cached: Locus raytrace --spp 16 on all cores; POV-Ray its own
    # +AM1 +R8 +A0.0 (bench/accuracy's keys, so the two benchmarks share them).
    refs, masks, ref_labels = H.references(tag, path, pfile, size, plan["ref_spp"],
                                           plan["pov_ref"], locus, pov, cache, tmp, ncpu)
    cross = (H.metrics(refs["povray"], refs["locus"], masks["locus"])
             if len(refs) == 2 else {})

    rows = []
    for key, label, renderer, _ in jobs:
        row = {"scene": name, "size": size, "primitives": prims, "config": key,
               "label": label, "renderer": renderer,
               "binary": locus.sha[:12] if renderer == "locus" else pov.version}
        if key in notes:
            row["note"] = notes[key]
            rows.append(row)
            continue
        ref_of = renderer if key not in ("floor", "spdpov_noaa") else None
        best = H.summarize(row, results[key], images[key], refs.get(ref_of), masks.get(ref_of),
                           ref_labels[renderer])
        st = best.get("stats")
        if st:
            row.update({"rays_eye": st["rays"]["eye"], "rays_reflected": st["rays"]["reflected"],
                        "rays_refracted": st["rays"]["refracted"],
                        "rays_shadow": st["rays"]["shadow"],
                        "pixels_ray_traced": st["pixels"]["ray_traced"],
                        "pixels_total": st["pixels"]["total"]})
        if key == "pov_r2" and cross:
            row["refs_rmse"] = cross["rmse"]
        if args.keep:
            H.acc.keep(args.keep, images[key], name, size, key)
        rows.append(row)
    full = next((r for r in rows if r["config"] == "aa4" and "cpu" in r), None)
    floor = next((r for r in rows if r["config"] == "floor" and "cpu" in r), None)
    if full and floor:
        full["floor_ratio"] = full["cpu"] / floor["cpu"]
        full["floor_ratio_wall"] = full["wall"] / floor["wall"]
    for r in rows:
        if "cpu" in r:
            H.log(f"{tag} {r['label']}: {r['cpu']:.3f} s CPU ({r['wall']:.3f} s wall)"
                  + (f", RMSE {r['rmse']:.5f}" if "rmse" in r else ""))
    return rows


# ------------------------------------------------------------------ callgrind

def instructions(plan, size, locus, tmp):
    """Instructions in render_band per pixel: full and floor, at the given
    --aa values (callgrind; independent of load)."""
    shim = H.hwy_shim(tmp)
    out = []
    paths = {s[0]: s[1] for s in SCENES}
    for name, aas in plan:
        path = paths[name]
        floor_path = H.diffuse_copy(path, tmp)
        for aa in aas:
            rec = {"scene": name, "size": size, "aa": int(aa)}
            try:
                for which, scene in (("full", path), ("floor", floor_path)):
                    ir, shares, st = H.callgrind(locus, scene, size, IV + ["--aa", aa], tmp,
                                                 shim)
                    rec[which + "_ir"] = ir
                    rec[which + "_shares"] = shares
                    rec[which + "_traced"] = st["pixels"]["ray_traced"]
                    rays = st["rays"]
                    rec[which + "_secondary"] = rays["reflected"] + rays["refracted"]
                    rec["pixels"] = st["pixels"]["total"]
                H.log(f"callgrind {name} {size}x{size} --aa {aa}: full {rec['full_ir']:,} "
                      f"floor {rec['floor_ir']:,} instructions")
            except RuntimeError as e:
                rec["note"] = str(e)
                H.log(f"callgrind {name} --aa {aa}: FAILED: {e}")
            out.append(rec)
    return out


# ------------------------------------------------------------------ checks

def get(rows, scene, key):
    return next((r for r in rows if r["scene"] == scene and r["config"] == key and "cpu" in r),
                None)


def acceptance(rows):
    """The issue's acceptance figures; thresholds are the issue's, not tuned."""
    out = []
    d = ACCEPT_SCENE
    iv, c1, c2 = get(rows, d, "aa4"), get(rows, d, "conf1"), get(rows, d, "conf2aa4")
    p2, fl, rt = get(rows, d, "pov_r2"), get(rows, d, "floor"), get(rows, d, "spp2")
    if iv:
        size = iv["size"]
        tag = f"(d) {size}x{size}"
        for other, what in ((c1, "configuration I (raytrace --boxes none --spp 2)"),
                            (c2, "configuration II (local --boxes none --aa 4)"),
                            (rt, "raytrace --boxes eye+shadow --spp 2")):
            if other:
                x = other["cpu"] / iv["cpu"]
                # The issue asks at least 15x against configuration I; the
                # others are context (faster at all).
                need = 15.0 if other is c1 else 1.0
                out.append(f"{'PASS' if x >= need and x > 1 else 'FAIL'} {tag}: IV --aa 4 {iv['cpu']:.3f} s "
                           f"vs {what} {other['cpu']:.3f} s CPU: {x:.2f}x faster"
                           f"{' (needs >= 15)' if other is c1 else ''} "
                           f"(wall {other['wall'] / iv['wall']:.2f}x); RMSE "
                           f"{iv.get('rmse', float('nan')):.5f} vs "
                           f"{other.get('rmse', float('nan')):.5f}")
        if p2:
            x = p2["cpu"] / iv["cpu"]
            out.append(f"{'PASS' if x >= 2 else 'FAIL'} {tag}: IV --aa 4 {iv['cpu']:.3f} s vs "
                       f"POV-Ray +A0.0 +AM1 +R2 {p2['cpu']:.3f} s CPU: {x:.2f}x faster "
                       f"(needs >= 2; trace time / wall {p2['wall'] / iv['wall']:.2f}x)")
            if "rmse" in iv and "rmse" in p2:
                ok = iv["rmse"] < p2["rmse"]
                out.append(f"{'PASS' if ok else 'FAIL'} {tag}: RMSE IV --aa 4 vs its reference "
                           f"{iv['rmse']:.5f} {'<' if ok else '>='} POV-Ray +R2 vs its own "
                           f"{p2['rmse']:.5f}")
        if fl:
            x = iv["cpu"] / fl["cpu"]
            out.append(f"{'PASS' if x <= 3 else 'FAIL'} {tag}: full / floor {x:.2f} (CPU; "
                       f"wall {iv['wall'] / fl['wall']:.2f}; needs <= 3)")
    faster, total, names = 0, 0, []
    for s in SPD_NAMES:
        a, p = get(rows, s, "aa4"), get(rows, s, "pov_r2")
        if a and p:
            total += 1
            if a["cpu"] < p["cpu"]:
                faster += 1
                names.append(s)
    if total:
        walls = sum(1 for s in SPD_NAMES if get(rows, s, "aa4") and get(rows, s, "pov_r2")
                    and get(rows, s, "aa4")["wall"] < get(rows, s, "pov_r2")["wall"])
        # The issue: faster on at least 5 of the 7 SPD scenes.
        need = 5 if total == 7 else (5 * total + 6) // 7
        out.append(f"{'PASS' if faster >= need else 'FAIL'} SPD: Locus IV --aa 4 faster than "
                   f"POV-Ray +A0.0 +AM1 +R2 on {faster} of {total} scenes by CPU time (needs "
                   f">= {need}; {', '.join(names) or 'none'}); {walls} of {total} by wall time")
    return out


# ------------------------------------------------------------------ output

FIELDS = ["scene", "size", "primitives", "config", "label", "renderer", "cpu", "wall", "prepare",
          "runs", "all_cpu", "all_wall", "floor_ratio", "floor_ratio_wall", "rmse", "psnr",
          "max_abs", "edge_rmse", "edge_psnr", "edge_max_abs", "edge_fraction", "reference",
          "refs_rmse", "rays_eye", "rays_reflected", "rays_refracted", "rays_shadow",
          "pixels_ray_traced", "pixels_total", "instructions", "binary", "note"]


def write_csv(path, rows, cg_rows):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(FIELDS)
        for r in rows:
            w.writerow([H.fmt(r.get(k)) for k in FIELDS])
        # callgrind: one row per scene, --aa and full/floor
        for c in cg_rows:
            for which in ("full", "floor"):
                if which + "_ir" not in c:
                    continue
                r = {"scene": c["scene"], "size": c["size"], "renderer": "locus",
                     "config": f"callgrind aa{c['aa']} {which}",
                     "label": f"Locus IV --aa {c['aa']}" + (", all diffuse" if which == "floor"
                                                            else ""),
                     "instructions": c[which + "_ir"],
                     "pixels_ray_traced": c[which + "_traced"], "pixels_total": c["pixels"],
                     "note": c.get("note")}
                w.writerow([H.fmt(r.get(k)) for k in FIELDS])


def t(r):
    return f"{r['cpu']:.3f} ({r['wall']:.2f})" if r and "cpu" in r else "—"


def e(r, k="rmse"):
    return f"{r[k]:.5f}" if r and k in r and H.finite(r[k]) else "—"


def ratio(a, b):
    return f"{a['cpu'] / b['cpu']:.2f}" if a and b and "cpu" in a and "cpu" in b else "—"


def write_md(path, rows, cg_rows, excluded, checks, info):
    size = info["size"]
    scenes = [s[0] for s in SCENES if any(r["scene"] == s[0] for r in rows)]
    L = [f"# Locus against POV-Ray{' (quick smoke test)' if info['quick'] else ''}", "",
         f"`bench/peers/run.py{' --quick' if info['quick'] else ''}`, {info['date']}: locus "
         f"`{info['locus']}` (HEAD `{info['commit']}`), {info['pov']}, {H.host(info)}, "
         f"load average {info['load_start']} at the start and {info['load_end']} at the end, "
         f"{info['minutes']:.0f} min. {size}x{size}, ray depth 5 (both), one thread: Locus "
         "`--workers 0 --threads 1`, POV-Ray `+WT1`. Times are seconds, **CPU time of the "
         "rendering thread** (Locus `seconds.render_cpu`, POV-Ray's trace CPU-seconds) and in "
         "brackets wall time (Locus `seconds.render`, POV-Ray's reported trace time); best of "
         f"{info['repeat']} runs taken in rounds (every configuration once per round). "
         "Scene loading, Locus's prepare and POV-Ray's parsing and bounding are excluded "
         "(in the CSV). The machine was shared with other builds: CPU times are the ones "
         "to compare. Definitions and shading differences: bench/peers/README.md.", ""]
    if info.get("locus_changed"):
        L += ["**build/bin/locus changed during the run; every figure comes from the copy "
              "taken at the start.**", ""]
    if info["stale"]:
        L += ["**" + ", ".join(info["stale"]) + ": bench/accuracy/pov differs from a fresh "
              "translation of the JSON.**", ""]
    if excluded:
        L += ["## Excluded", ""] + [f"- {n}: Locus failed: `{m}`" for n, m in excluded] + [""]
    L += ["## Acceptance (issue #9)", "", "```"] + checks + ["```", ""]

    L += ["## Time", "",
          "POV÷Locus > 1: Locus faster. `raytrace --spp 2` is Locus's own Whitted ray tracer "
          "with its BVH and shadow-volume hierarchy (same 4 samples per pixel as `--aa 4` "
          "and `+R2`). The last column is POV-Ray on SPD's own converted file "
          "(`../shared/spd/pov`, its lights and finishes, `+HI` setting max_trace_level 5) "
          "instead of our translation: a check that the translation is not what sets "
          "POV-Ray's speed.", "",
          "| scene | primitives | Locus IV --aa 4 | POV-Ray +A0.0 +AM1 +R2 | POV÷Locus | "
          "Locus IV --aa 0 | POV-Ray -A | POV÷Locus | Locus raytrace --spp 2 | "
          "POV-Ray -A, SPD's .pov |", "|---|---|---|---|---|---|---|---|---|---|"]
    for s in scenes:
        g = {k: get(rows, s, k) for k in ("aa4", "pov_r2", "aa0", "pov_noaa", "spp2",
                                          "spdpov_noaa")}
        prims = next(r["primitives"] for r in rows if r["scene"] == s)
        L.append(f"| {s} | {prims} | {t(g['aa4'])} | {t(g['pov_r2'])} | "
                 f"{ratio(g['pov_r2'], g['aa4'])} | {t(g['aa0'])} | {t(g['pov_noaa'])} | "
                 f"{ratio(g['pov_noaa'], g['aa0'])} | {t(g['spp2'])} | {t(g['spdpov_noaa'])} |")

    L += ["", "## Error against each renderer's own reference", "",
          f"RMSE over linear RGB clamped to [0, 1] (bench/accuracy's metrics). Locus against "
          f"`--method raytrace --spp {info['plan']['ref_spp']}` ({info['plan']['ref_spp']}² "
          f"stratified samples per pixel), POV-Ray against its own `+AM1 "
          f"+R{info['plan']['pov_ref']} +A0.0`. Edge RMSE: over pixels where the reference's "
          "luminance has a Sobel magnitude above 0.05. The last column is the two references "
          "against each other: the shading difference of the translation, which enters "
          "neither renderer's error.", "",
          "| scene | Locus --aa 4 | POV-Ray +R2 | Locus --aa 0 | POV-Ray -A | Locus raytrace "
          "--spp 2 | edge: Locus --aa 4 | edge: POV-Ray +R2 | POV-Ray ref. vs Locus ref. |",
          "|---|---|---|---|---|---|---|---|---|"]
    for s in scenes:
        g = {k: get(rows, s, k) for k in ("aa4", "pov_r2", "aa0", "pov_noaa", "spp2")}
        L.append(f"| {s} | {e(g['aa4'])} | {e(g['pov_r2'])} | {e(g['aa0'])} | "
                 f"{e(g['pov_noaa'])} | {e(g['spp2'])} | {e(g['aa4'], 'edge_rmse')} | "
                 f"{e(g['pov_r2'], 'edge_rmse')} | {e(g['pov_r2'], 'refs_rmse')} |")

    L += ["", "## The floor: every material diffuse", "",
          "The same --aa 4 render of a copy of the scene with Ks = 0 and T = 0 in every "
          "material (NFF `f` lines; JSON `ks`, `t`): no reflected or refracted ray. Curved "
          "bodies are still ray traced (their eye rays), so the floor's traced pixels are "
          "not zero where a scene has spheres, cylinders or cones. full / floor is the cost "
          "of mirrors and glass.", "",
          "| scene | full | floor | full / floor (CPU) | full / floor (wall) | traced pixels, "
          "full | traced pixels, floor | reflected + refracted rays, full |",
          "|---|---|---|---|---|---|---|---|"]
    for s in scenes:
        a, f = get(rows, s, "aa4"), get(rows, s, "floor")
        if not a or not f:
            continue
        px = a.get("pixels_total", 1)
        L.append(f"| {s} | {t(a)} | {t(f)} | **{a['floor_ratio']:.2f}** | "
                 f"{a['floor_ratio_wall']:.2f} | {100 * a['pixels_ray_traced'] / px:.1f}% | "
                 f"{100 * f['pixels_ray_traced'] / px:.1f}% | "
                 f"{a['rays_reflected'] + a['rays_refracted']:,} |")

    acc_rows = [r for r in rows if r["scene"] == ACCEPT_SCENE and "cpu" in r]
    if acc_rows:
        L += ["", f"## Scene (d), every configuration side by side ({size}x{size})", "",
              "| configuration | CPU s | wall s | RMSE | edge RMSE | traced pixels | eye rays | "
              "reflected rays | shadow rays |", "|---|---|---|---|---|---|---|---|---|"]
        for r in acc_rows:
            L.append(f"| {r['label']} | {r['cpu']:.3f} | {r['wall']:.3f} | {e(r)} | "
                     f"{e(r, 'edge_rmse')} | {H.fmt(r.get('pixels_ray_traced'))} | "
                     f"{H.fmt(r.get('rays_eye'))} | {H.fmt(r.get('rays_reflected'))} | "
                     f"{H.fmt(r.get('rays_shadow'))} |")

    L += ["", "## Instructions per pixel", ""]
    if not cg_rows:
        L += ["Not measured (--no-callgrind or no valgrind).", ""]
    else:
        cs = cg_rows[0]["size"]
        L += [f"`valgrind --tool=callgrind --toggle-collect='locus::render_band*'`: "
              f"instructions executed inside render_band (loading, prepare and image output "
              f"excluded), {cs}x{cs}, one thread, configuration IV; counts do not depend on "
              "load. *floor*: every material diffuse (above). Per traced pixel: the full "
              "render's instructions divided by `pixels.ray_traced`; *mirrors and glass, per "
              "traced pixel*: (full − floor) / traced pixels of the full render, what "
              "reflection and refraction add to a traced pixel; *per secondary ray*: "
              "(full − floor) / (reflected + refracted rays). A scene without curved "
              "bodies, mirrors or glass (tetra) shows the diffuse-span path alone. Negative: "
              "the floor costs more than the full render (gears: its glass faces, traced in "
              "the full render, become diffuse faces whose spans need shadow volumes).", "",
              "| scene | --aa | instr./pixel, full | instr./pixel, floor | traced pixels, full "
              "| traced pixels, floor | instr. per traced pixel (full) | mirrors and glass, "
              "per traced pixel | per secondary ray |", "|---|---|---|---|---|---|---|---|---|"]
        for c in cg_rows:
            if "note" in c:
                L.append(f"| {c['scene']} | {c['aa']} | failed: {c['note']} | | | | | | |")
                continue
            px = c["pixels"]
            d_ir = c["full_ir"] - c["floor_ir"]
            # Without reflected or refracted rays (tetra: its few traced pixels are
            # faces cut by hither) the per-traced-pixel figures mean nothing.
            sec = c.get("full_secondary")
            extra = f"{d_ir / c['full_traced']:,.0f}" if sec and c["full_traced"] else "—"
            per_ray = f"{d_ir / sec:,.0f}" if sec else "—"
            per_traced = (f"{c['full_ir'] / c['full_traced']:,.0f}" if sec and
                          c["full_traced"] else "—")
            L.append(f"| {c['scene']} | {c['aa']} | {c['full_ir'] / px:,.0f} | "
                     f"{c['floor_ir'] / px:,.0f} | {100 * c['full_traced'] / px:.1f}% | "
                     f"{100 * c['floor_traced'] / px:.1f}% | {per_traced} | {extra} | {per_ray} |")
        L += ["", "Where they go: the share of render_band's instructions spent inside "
              "(inclusive, so the columns overlap: shading includes the secondary rays' "
              "searches and shadows, and at --aa 0 the span shadows too, which point sampling "
              "computes from inside shading) the span shadows of the scanline pass "
              "(`SpanShadows::compute_light`, shadow volumes against the spans of a "
              "sub-scanline), shading "
              "(`Tracer::shade`), ray searches (`Tracer::nearest`) and the scanline visibility "
              "(`visible_segments`).", "",
              "| scene | --aa | render | total instructions | span shadows | shading | "
              "ray search | visibility |", "|---|---|---|---|---|---|---|---|"]
        for c in cg_rows:
            for which in ("full", "floor"):
                sh = c.get(which + "_shares")
                if sh is None:
                    continue

                def pc(k):
                    return f"{100 * sh[k]:.0f}%" if k in sh else "—"
                L.append(f"| {c['scene']} | {c['aa']} | {which} | {c[which + '_ir']:,} | "
                         f"{pc('span_shadows')} | {pc('shading')} | {pc('ray_search')} | "
                         f"{pc('visibility')} |")
        L.append("")
    L += ["Chart: `peers.png`; every figure and every run's time: `peers.csv`.", ""]
    with open(path, "w") as f:
        f.write("\n".join(L))


def chart(path, rows, info):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    scenes = [s[0] for s in SCENES if any(r["scene"] == s[0] and "cpu" in r for r in rows)]
    if not scenes:
        return
    series = [("aa4", "Locus IV --aa 4", "C0"), ("floor", "Locus --aa 4, all diffuse", "C9"),
              ("aa0", "Locus IV --aa 0", "C4"), ("spp2", "Locus raytrace --spp 2", "C1"),
              ("pov_r2", "POV-Ray +A0.0 +AM1 +R2", "C2"), ("pov_noaa", "POV-Ray -A", "C3")]
    markers = {"aa4": "o", "floor": "o", "aa0": "s", "spp2": "D", "pov_r2": "^",
               "pov_noaa": "v"}
    fig, axes = plt.subplots(2, 1, figsize=(11, 7.5))
    x = np.arange(len(scenes))
    for ax, metric, ylabel in ((axes[0], "cpu", "render CPU time, 1 thread (s)"),
                               (axes[1], "rmse", "RMSE vs own reference")):
        ser = [s for s in series if not (metric == "rmse" and s[0] == "floor")]
        step = 0.7 / len(ser)
        for i, (key, label, col) in enumerate(ser):
            vals = []
            for s in scenes:
                r = get(rows, s, key)
                vals.append(r[metric] if r and metric in r and H.finite(r[metric]) else np.nan)
            ax.plot(x + (i - (len(ser) - 1) / 2) * step, vals, linestyle="none",
                    marker=markers[key], color=col, label=label, markersize=6,
                    fillstyle="none" if key == "floor" else "full")
        for b in x[:-1]:
            ax.axvline(b + 0.5, color="0.85", linewidth=0.8)
        ax.set_yscale("log")
        ax.set_xticks(x)
        ax.set_xticklabels(scenes, fontsize=8)
        ax.set_xlim(-0.5, len(scenes) - 0.5)
        ax.set_ylabel(ylabel, fontsize=8)
        ax.grid(True, axis="y", which="both", alpha=0.25)
        ax.tick_params(labelsize=8)
    h, lab = axes[0].get_legend_handles_labels()
    fig.legend(h, lab, loc="lower center", ncol=6, fontsize=7, frameon=False)
    axes[0].set_title(f"Locus vs POV-Ray 3.7, {info['size']}x{info['size']}, one thread "
                      f"(best of {info['repeat']}; lower is better)", fontsize=10)
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()

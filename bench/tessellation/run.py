#!/usr/bin/python3
"""Tessellation against accuracy (issue #10 item 5): the Utah teapot
(scenes/teapot.json), close up and 4x farther away, rendered by configuration
IV with multi-scanning (`--method local --aa 4`, the default) at
`--tess-tol` 4, 1, 0.5, 0.25, 0.1 and 0.05 pixels. Each is compared with the
same method at `--tess-tol 0.01` (the reference tessellation), and the
anti-aliasing error at the same tessellation is measured for comparison:
`--aa 1 2 4 8` against `--method raytrace --spp 16`, all at the default
tolerance (so both sample the same triangles).

Usage: bench/tessellation/run.py [--size 256] [--quick] [--out DIR]
Writes bench/results/tessellation.{csv,md,png} (--quick: a temporary directory
unless --out is given). See README.md beside this file.
"""
import argparse
import csv
import datetime
import importlib.util
import json
import math
import os
import shutil
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
TEAPOT = os.path.join(ROOT, "scenes", "teapot.json")

# The accuracy bench's helpers (binary snapshot, image reading, metrics).
_spec = importlib.util.spec_from_file_location(
    "accuracy_run", os.path.join(ROOT, "bench", "accuracy", "run.py"))
acc = importlib.util.module_from_spec(_spec)
sys.path.insert(0, os.path.join(ROOT, "bench", "accuracy"))
_spec.loader.exec_module(acc)

TOLERANCES = [4, 1, 0.5, 0.25, 0.1, 0.05]
REF_TOL = 0.01
DEFAULT_TOL = 0.25
AA = [1, 2, 4, 8]
REF_SPP = 16
# Camera distance from `at` along the scene's own view direction: the close
# view has the teapot fill the frame, the far one is 4x farther.
VIEWS = [("close", 8.0), ("far", 32.0)]
QUICK = {"tolerances": [4, 0.25], "aa": [4], "size": 96}


def render(binary, scene, size, args, out, tmp, threads):
    """Renders once; returns the --stats JSON."""
    stats = os.path.join(tmp, "stats.json")
    if os.path.exists(stats):
        os.remove(stats)
    cmd = [binary, "render", scene, "-o", out, "--size", f"{size}x{size}", "--workers", "0",
           "--threads", str(threads), "--stats", stats] + args
    r = acc.subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        lines = r.stderr.strip().splitlines()
        raise RuntimeError(lines[-1] if lines else f"exit {r.returncode}")
    with open(stats) as f:
        return json.load(f)


def timed(binary, scene, size, args, out, tmp, repeat):
    """Best of up to `repeat` one-thread runs (short runs are repeated, as in
    bench/accuracy): prepare and render times of the best run."""
    best = None
    runs = 0
    while True:
        st = render(binary, scene, size, args, out, tmp, 1)
        runs += 1
        total = st["seconds"]["prepare"] + st["seconds"]["render"]
        if best is None or total < best[0]:
            best = (total, st)
        want = repeat if best[0] < 0.5 else (min(2, repeat) if best[0] < 3.0 else 1)
        if runs >= want:
            return best[1], runs


def background_leaks(img, ref, bg, tol):
    """Pixels that show exactly the background where the reference shows
    none within ceil(tol) + 1 pixels (a crack, not a moved silhouette)."""
    is_bg = lambda a: np.all(np.abs(a - bg) < 1e-6, axis=2)
    b, rb = is_bg(img), is_bg(ref)
    r = int(math.ceil(tol)) + 1
    h, w = rb.shape
    pad = np.pad(rb, r, constant_values=True)
    near = np.zeros_like(rb)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            near |= pad[r + dy:r + dy + h, r + dx:r + dx + w]
    return int(np.sum(b & ~near))


def view_scene(tmp, name, distance):
    with open(TEAPOT) as f:
        s = json.load(f)
    at = np.array(s["camera"]["at"], dtype=float)
    d = np.array(s["camera"]["from"], dtype=float) - at
    s["camera"]["from"] = list(at + distance * d / np.linalg.norm(d))
    path = os.path.join(tmp, f"teapot_{name}.json")
    with open(path, "w") as f:
        json.dump(s, f)
    return path, np.array(s["background"], dtype=np.float32)


FIELDS = ["view", "distance", "size", "kind", "method", "tess_tol", "aa", "triangles",
          "prepare", "tessellate", "render", "total", "runs", "rmse", "psnr", "max_abs",
          "edge_rmse", "background_leaks", "reference"]


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--locus", default=os.path.join(ROOT, "build", "bin", "locus"))
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="smoke test: 96x96, two tolerances")
    ap.add_argument("--out", help="output directory (default bench/results; quick: a temp dir)")
    args = ap.parse_args()
    tolerances = QUICK["tolerances"] if args.quick else TOLERANCES
    aas = QUICK["aa"] if args.quick else AA
    size = QUICK["size"] if args.quick else args.size
    out_dir = args.out or (os.path.join(ROOT, "bench", "results") if not args.quick
                           else tempfile.mkdtemp(prefix="locus-tess-quick-"))
    os.makedirs(out_dir, exist_ok=True)
    ncpu = os.cpu_count() or 1
    started = time.time()
    load_start = acc.loadavg()
    tmp = tempfile.mkdtemp(prefix="locus-tess-")
    rows = []
    try:
        binary = acc.snapshot_locus(args.locus, tmp)
        sha = acc.sha256_file(binary)[:12]
        for view, distance in VIEWS:
            scene, bg = view_scene(tmp, view, distance)
            tag = f"{view} ({distance:g} from the teapot)"
            # Reference tessellation, same method and aa, all cores.
            acc.log(f"{tag}: reference --tess-tol {REF_TOL}")
            ref_path = os.path.join(tmp, f"{view}_ref.exr")
            ref_st = render(binary, scene, size, ["--tess-tol", str(REF_TOL)], ref_path, tmp, ncpu)
            ref = acc.read_image(ref_path)
            mask = acc.edge_mask(ref)
            rows.append({"view": view, "distance": distance, "size": size, "kind": "reference",
                         "method": f"local --aa 4 --tess-tol {REF_TOL}", "tess_tol": REF_TOL,
                         "aa": 4, "triangles": ref_st["geometry"]["triangles"],
                         "prepare": ref_st["seconds"]["prepare"],
                         "tessellate": ref_st["seconds"]["tessellate"],
                         "render": ref_st["seconds"]["render"], "reference": "",
                         "note": f"{ncpu} threads"})
            for tol in tolerances:
                acc.log(f"{tag}: --tess-tol {tol}")
                path = os.path.join(tmp, f"{view}_{tol}.exr")
                st, runs = timed(binary, scene, size, ["--tess-tol", str(tol)], path, tmp,
                                 args.repeat)
                img = acc.read_image(path)
                row = {"view": view, "distance": distance, "size": size, "kind": "tessellation",
                       "method": f"local --aa 4 --tess-tol {tol}", "tess_tol": tol, "aa": 4,
                       "triangles": st["geometry"]["triangles"],
                       "prepare": st["seconds"]["prepare"],
                       "tessellate": st["seconds"]["tessellate"],
                       "render": st["seconds"]["render"], "runs": runs,
                       "background_leaks": background_leaks(img, ref, bg, tol),
                       "reference": f"local --aa 4 --tess-tol {REF_TOL}"}
                row.update(acc.metrics(img, ref, mask))
                rows.append(row)
            # Anti-aliasing error at the default tessellation, for scale.
            acc.log(f"{tag}: raytrace --spp {REF_SPP} (default tolerance)")
            spp_path = os.path.join(tmp, f"{view}_spp.exr")
            render(binary, scene, size, ["--method", "raytrace", "--spp", str(REF_SPP)], spp_path,
                   tmp, ncpu)
            spp = acc.read_image(spp_path)
            spp_mask = acc.edge_mask(spp)
            for aa in aas:
                acc.log(f"{tag}: --aa {aa} (default tolerance)")
                path = os.path.join(tmp, f"{view}_aa{aa}.exr")
                st, runs = timed(binary, scene, size, ["--aa", str(aa)], path, tmp, args.repeat)
                row = {"view": view, "distance": distance, "size": size, "kind": "anti-aliasing",
                       "method": f"local --aa {aa} --tess-tol {DEFAULT_TOL}",
                       "tess_tol": DEFAULT_TOL, "aa": aa,
                       "triangles": st["geometry"]["triangles"],
                       "prepare": st["seconds"]["prepare"],
                       "tessellate": st["seconds"]["tessellate"],
                       "render": st["seconds"]["render"], "runs": runs,
                       "reference": f"raytrace --spp {REF_SPP} --tess-tol {DEFAULT_TOL}"}
                row.update(acc.metrics(acc.read_image(path), spp, spp_mask))
                rows.append(row)
        for r in rows:
            r["total"] = r["prepare"] + r["render"]
        info = {"date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"), "locus": sha,
                "ncpu": ncpu, "load_start": load_start, "load_end": acc.loadavg(),
                "minutes": (time.time() - started) / 60, "size": size, "quick": args.quick,
                "repeat": args.repeat}
        checks = acceptance(rows)
        write_csv(os.path.join(out_dir, "tessellation.csv"), rows)
        write_md(os.path.join(out_dir, "tessellation.md"), rows, checks, info)
        chart(os.path.join(out_dir, "tessellation.png"), rows, size)
        for _, line in checks:
            print(line)
        acc.log(f"wrote {out_dir}/tessellation.{{csv,md,png}}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def pick(rows, view, kind, **kw):
    for r in rows:
        if r["view"] == view and r["kind"] == kind and all(r[k] == v for k, v in kw.items()):
            return r
    return None


def acceptance(rows):
    out = []
    for view, _ in VIEWS:
        tess = pick(rows, view, "tessellation", tess_tol=DEFAULT_TOL)
        aa4 = pick(rows, view, "anti-aliasing", aa=4)
        if tess and aa4:
            ok = tess["rmse"] < aa4["rmse"]
            out.append((ok, f"{'PASS' if ok else 'FAIL'} {view}: --tess-tol {DEFAULT_TOL} RMSE "
                            f"{tess['rmse']:.5f} against --tess-tol {REF_TOL} is below --aa 4's "
                            f"{aa4['rmse']:.5f} against --spp {REF_SPP}"))
        leaks = sum(r.get("background_leaks", 0) for r in rows
                    if r["view"] == view and r["kind"] == "tessellation")
        out.append((leaks == 0, f"{'PASS' if leaks == 0 else 'FAIL'} {view}: no background "
                                f"pixel inside the reference's teapot at any tolerance ({leaks})"))
    # Issue #10: at the default tolerance, 4x farther must mean at least 4x
    # fewer triangles. The other tolerances are listed for information: at
    # coarse ones the rates reach their floor (2 steps a side) far away.
    for tol in TOLERANCES + [REF_TOL]:
        near = pick(rows, "close", "tessellation" if tol != REF_TOL else "reference",
                    tess_tol=tol)
        far = pick(rows, "far", "tessellation" if tol != REF_TOL else "reference", tess_tol=tol)
        if near and far:
            ratio = near["triangles"] / far["triangles"]
            ok = ratio >= 4 if tol == DEFAULT_TOL else None
            verdict = {True: "PASS", False: "FAIL", None: "info"}[ok]
            out.append((ok, f"{verdict} --tess-tol {tol}: 4x farther, {ratio:.2f}x fewer "
                            f"triangles ({near['triangles']} -> {far['triangles']})"
                            + ("; needs 4x" if ok is not None else "")))
    return out


def write_csv(path, rows):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(FIELDS)
        for r in rows:
            w.writerow([acc.fmt(r.get(k)) for k in FIELDS])


def write_md(path, rows, checks, info):
    L = [f"# Tessellation against accuracy{' (quick smoke test)' if info['quick'] else ''}", "",
         f"`bench/tessellation/run.py{' --quick' if info['quick'] else ''}`, {info['date']}: "
         f"locus `{info['locus']}`, {info['ncpu']} cores, load average {info['load_start']} at "
         f"the start and {info['load_end']} at the end, {info['minutes']:.0f} min. "
         f"`scenes/teapot.json` at {info['size']}x{info['size']}, configuration IV with "
         "multi-scanning (`--method local --aa 4`, the default). Times on one thread "
         "(`--workers 0 --threads 1`): `prepare` (tessellation, primitives, scanline faces, "
         "shadow volumes), of which `tessellate`, and `render`; best of up to "
         f"{info['repeat']} runs for runs under 3 s. The machine was shared with other work, "
         "so times are noisy.", "",
         f"Tessellation error: each tolerance against `--tess-tol {REF_TOL}` rendered the same "
         "way. Anti-aliasing error, for scale: `--aa N` against `--method raytrace --spp "
         f"{REF_SPP}`, both at the default `--tess-tol {DEFAULT_TOL}` (the same triangles, so "
         "only the sampling differs). RMSE over linear RGB clamped to [0, 1], all pixels and "
         "channels; `edge RMSE` over the reference's edge pixels (bench/accuracy/README.md). "
         "`leaks`: pixels showing exactly the background where the reference shows none within "
         "ceil(tol) + 1 pixels (cracks).", "",
         "## Acceptance", "", "```"] + [line for _, line in checks] + ["```", ""]
    for view, distance in VIEWS:
        sel = [r for r in rows if r["view"] == view]
        if not sel:
            continue
        L += [f"## {view}: camera {distance:g} from `at`", "",
              "| method | triangles | prepare s | tessellate s | render s | RMSE | PSNR | max | "
              "edge RMSE | leaks | against |", "|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in sel:
            if r["kind"] == "reference":
                L.append(f"| {r['method']} (reference, {r['note']}) | {r['triangles']} | "
                         f"{r['prepare']:.3f} | {r['tessellate']:.3f} | {r['render']:.3f} | | | "
                         "| | | |")
                continue
            L.append(f"| {r['method']} | {r['triangles']} | {r['prepare']:.3f} | "
                     f"{r['tessellate']:.3f} | {r['render']:.3f} | {r['rmse']:.5f} | "
                     f"{r['psnr']:.2f} | {r['max_abs']:.3f} | {r['edge_rmse']:.5f} | "
                     f"{acc.fmt(r.get('background_leaks'))} | {r['reference']} |")
        L.append("")
    L += ["Chart: `tessellation.png` (RMSE against prepare + render time, and triangles "
          "against tolerance); raw figures `tessellation.csv`. The scheme and its bound: "
          "docs/tessellation.md.", ""]
    with open(path, "w") as f:
        f.write("\n".join(L))


def chart(path, rows, size):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    for ax, (view, _) in zip(axes, VIEWS):
        for kind, col, mk, label, key in (
                ("tessellation", "C2", "D", f"--tess-tol T (vs --tess-tol {REF_TOL})", "tess_tol"),
                ("anti-aliasing", "C0", "o", f"--aa N (vs raytrace --spp {REF_SPP})", "aa")):
            pts = sorted(((r["total"], r["rmse"], r[key]) for r in rows
                          if r["view"] == view and r["kind"] == kind and r.get("rmse", 0) > 0),
                         key=lambda p: p[0])
            if not pts:
                continue
            ax.plot([p[0] for p in pts], [p[1] for p in pts], color=col, marker=mk,
                    markersize=4, linewidth=1.2, label=label)
            for t, e, n in pts:
                ax.annotate(f"{n:g}", (t, e), textcoords="offset points", xytext=(3, 3),
                            fontsize=7, color=col)
        acc.log_axes(ax, f"teapot, {view}, {size}x{size}", "prepare + render, 1 thread (s)",
                     "RMSE")
        ax.legend(fontsize=7)
    ax = axes[2]
    for view, col in zip([v for v, _ in VIEWS], ["C3", "C4"]):
        pts = sorted((r["tess_tol"], r["triangles"]) for r in rows
                     if r["view"] == view and r["kind"] in ("tessellation", "reference"))
        if pts:
            ax.plot([p[0] for p in pts], [p[1] for p in pts], color=col, marker="s",
                    markersize=4, label=view)
    acc.log_axes(ax, "triangles after tessellation", "--tess-tol (pixels)", "geometry.triangles")
    ax.legend(fontsize=7)
    fig.suptitle("Tessellation against accuracy (lower left is better)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""The paper's Table 1 (METHOD.md §8): scene (d) at 512x512 with 1, 2 and 3
lights, every configuration measured side by side in one run, times
normalised to configuration II. Writes bench/results/table1.csv and .md.

Configurations: I = raytrace/none, II = local/none, III = local/eye,
IV = local/eye+shadow (shadow volumes, docs/shadow-volumes.md), and the
modern baseline raytrace/eye+shadow. One thread, no farm, so the figures
are the renderer's own.

Usage: bench/table1/run.py [--locus build/bin/locus] [--size 512] [--repeat 3]
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CONFIGS = [
    ("I", "raytrace", "none"),
    ("II", "local", "none"),
    ("III", "local", "eye"),
    ("IV", "local", "eye+shadow"),
    ("BVH", "raytrace", "eye+shadow"),
]


def render(locus, scene, method, boxes, size, tmp):
    stats = os.path.join(tmp, "stats.json")
    cmd = [locus, "render", scene, "-o", os.path.join(tmp, "out.png"), "--size", f"{size}x{size}",
           "--method", method, "--boxes", boxes, "--threads", "1", "--workers", "0",
           "--stats", stats]
    # One sample per pixel in every configuration, as the ray tracer's:
    # Table 1 compares visibility and shadow search, not anti-aliasing.
    if method == "local":
        cmd += ["--aa", "0"]
    # IV as the paper has it: every shadow from the volumes, the points of
    # secondary rays searched too (auto casts rays from those points:
    # docs/renderer.md "Points by rays").
    if method == "local" and boxes == "eye+shadow":
        cmd += ["--shadows", "volumes"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        return None, r.stderr.strip().splitlines()[-1] if r.stderr.strip() else "failed"
    with open(stats) as f:
        return json.load(f), None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--locus", default=os.path.join(ROOT, "build", "bin", "locus"))
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=3, help="best of N runs per cell")
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results"))
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for lights in (1, 2, 3):
            scene = os.path.join(ROOT, "scenes", "paper",
                                 f"d_spheres_{lights}light{'s' if lights > 1 else ''}.json")
            for name, method, boxes in CONFIGS:
                best, note = None, None
                for _ in range(args.repeat):
                    st, note = render(args.locus, scene, method, boxes, args.size, tmp)
                    if st is None:
                        break
                    if best is None or st["seconds"]["render"] < best["seconds"]["render"]:
                        best = st
                rows.append({"lights": lights, "config": name, "method": method, "boxes": boxes,
                             "stats": best, "note": note})
                sys.stderr.write(f"{lights} light(s) {name}: "
                                 f"{best['seconds']['render']:.3f} s\n" if best else
                                 f"{lights} light(s) {name}: unavailable ({note})\n")
    # CSV with raw figures.
    csv_path = os.path.join(args.out, "table1.csv")
    with open(csv_path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["lights", "config", "method", "boxes", "seconds_render", "seconds_prepare",
                    "rays_eye", "rays_reflected", "rays_shadow", "tests_ray_object",
                    "tests_shadow_volume", "pixels_ray_traced", "relative_to_II"])
        for r in rows:
            st = r["stats"]
            if st is None:
                w.writerow([r["lights"], r["config"], r["method"], r["boxes"]] + [""] * 9)
                continue
            ii = next(x["stats"] for x in rows if x["lights"] == r["lights"] and x["config"] == "II")
            rel = st["seconds"]["render"] / ii["seconds"]["render"] if ii else ""
            w.writerow([r["lights"], r["config"], r["method"], r["boxes"],
                        f"{st['seconds']['render']:.4f}", f"{st['seconds']['prepare']:.4f}",
                        st["rays"]["eye"], st["rays"]["reflected"], st["rays"]["shadow"],
                        st["tests"]["ray_object"], st["tests"].get("shadow_volume", 0),
                        st["pixels"]["ray_traced"],
                        f"{rel:.3f}" if rel != "" else ""])
    # Markdown, shaped like the paper's Table 1.
    md = [f"# Table 1: scene (d), {args.size}x{args.size}, 1 thread, best of {args.repeat}",
          "", "Render time relative to configuration II (paper: I 2.50/2.51/2.36, III "
          "0.65/0.85/0.89, IV 0.18/0.16/0.12 for 1/2/3 lights).", "",
          "| lights | " + " | ".join(c[0] for c in CONFIGS) + " |",
          "|---|" + "---|" * len(CONFIGS)]
    for lights in (1, 2, 3):
        ii = next(x["stats"] for x in rows if x["lights"] == lights and x["config"] == "II")
        cells = []
        for name, _, _ in CONFIGS:
            st = next(x["stats"] for x in rows if x["lights"] == lights and x["config"] == name)
            cells.append(f"{st['seconds']['render'] / ii['seconds']['render']:.2f}" if st and ii
                         else "n/a")
        md.append(f"| {lights} | " + " | ".join(cells) + " |")
    md += ["", "Seconds (render; prepare), rays and tests:", "",
           "| lights | config | seconds | prepare | eye rays | shadow rays | ray-object tests "
           "| shadow-volume tests |",
           "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        st = r["stats"]
        if st is None:
            md.append(f"| {r['lights']} | {r['config']} | n/a ({r['note']}) | | | | | |")
        else:
            md.append(f"| {r['lights']} | {r['config']} | {st['seconds']['render']:.3f} | "
                      f"{st['seconds']['prepare']:.4f} | {st['rays']['eye']} | "
                      f"{st['rays']['shadow']} | {st['tests']['ray_object']} | "
                      f"{st['tests'].get('shadow_volume', 0)} |")
    with open(os.path.join(args.out, "table1.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()

#!/usr/bin/python3
"""Animations whose geometry stands still (issue #27 item 1, big scenes;
docs/renderer.md "Frames that share their geometry"): a turntable of F
frames (`--orbit 30`, in process, one thread, configuration IV --aa 4)
against one frame of it, side by side.

Where only the camera moves, the frames after the first are prepared on
the first's geometry (primitives, hierarchy, solids, leaf copies): each
takes only what the camera changes. The one-frame run prepares as every
frame did before (from scratch); F times its prepare is what the animation's
prepare would be without the sharing. Reported per scene, best of the rounds
(each round runs both jobs, the order reversed every other round): the
one frame's prepare; the animation's prepare in all and per shared frame
((all - first) / (F - 1)); and a frame's time, prepare + render (`--stats`,
wall), the animation's mean against the one frame's.

Scenes: SPD tetra level 9 and balls level 5 (spdgen.py), and SPD def balls.

Usage: bench/peers/animation.py [--quick] [--repeat N] [--frames F]
Writes bench/results/animation.md (--quick: a temporary directory).
"""
import os
import shutil
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import harness as H  # noqa: E402
import spdgen  # noqa: E402

GENERATED = [("tetra level 9", ("tetra", 9)), ("balls level 5", ("balls", 5))]
SHIPPED = [("SPD def balls", os.path.join(H.SPD, "def", "balls.nff"))]
IV = ["--method", "local", "--boxes", "eye+shadow", "--aa", "4"]


def job(locus, path, size, frames, tmp, tag):
    out = os.path.join(tmp, f"{tag}_####.exr")
    args = IV + ["--frames", f"1-{frames}", "--orbit", "30"]
    s = locus.stats(path, size, args, out)["seconds"]
    return {"prepare": s["prepare"], "render": s["render"], "load": s.get("load", 0.0)}


def measure(locus, path, size, frames, repeat, tmp):
    best = {}
    for r in range(repeat):
        order = [1, frames] if r % 2 == 0 else [frames, 1]
        for f in order:
            got = job(locus, path, size, f, tmp, f"f{f}")
            cur = best.setdefault(f, got)
            for k, v in got.items():
                cur[k] = min(cur[k], v)
    one, all_ = best[1], best[frames]
    shared = (all_["prepare"] - one["prepare"]) / max(1, frames - 1)
    return {"one_prepare": one["prepare"], "one_render": one["render"],
            "anim_prepare": all_["prepare"], "anim_render": all_["render"],
            "shared_prepare": shared, "frames": frames,
            "prepare_x": frames * one["prepare"] / all_["prepare"],
            "frame_one": one["prepare"] + one["render"],
            "frame_anim": (all_["prepare"] + all_["render"]) / frames}


def report(out_dir, info, results):
    lines = ["# Animations that share their geometry", "",
             f"`bench/peers/animation.py`, {info['date']}: locus `{info['locus']}` (HEAD "
             f"`{info['commit']}`), {info['size']}x{info['size']}, one thread, configuration IV "
             f"`--aa 4`, a turntable of {info['frames']} frames (`--orbit 30`) against its first "
             f"frame alone, best of {info['repeat']} rounds; load average {info['load_start']} at "
             "the start. Times are `--stats` seconds (wall, one thread). The one frame is "
             "prepared from scratch, as every frame was before the frames shared their geometry; "
             "F x its prepare is the animation's prepare without the sharing.", "",
             "| scene | one frame: prepare | animation: prepare in all | per shared frame | "
             "F x one frame's prepare / animation's | a frame (prepare + render): one frame | "
             "animation's mean | x |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for name, r in results.items():
        lines.append(f"| {name} | {r['one_prepare']:.3f} | {r['anim_prepare']:.3f} | "
                     f"{r['shared_prepare']:.3f} | {r['prepare_x']:.2f}x | {r['frame_one']:.3f} | "
                     f"{r['frame_anim']:.3f} | {r['frame_one'] / r['frame_anim']:.2f}x |")
    lines.append("")
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, "animation.md")
    with open(path, "w") as f:
        f.write("\n".join(lines))
    print("\n".join(lines))
    H.log(f"wrote {path}")


def main():
    ap = H.parser(__doc__, "smoke test: 128x128, tetra level 5 and balls level 3, one round")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=3, help="rounds, best of N (default 3)")
    ap.add_argument("--out", help="output directory (default bench/results; quick: a temp dir)")
    args = ap.parse_args()
    if args.frames < 2:
        ap.error("--frames must be at least 2")
    size = 128 if args.quick else args.size
    repeat = 1 if args.quick else args.repeat
    tmp = tempfile.mkdtemp(prefix="locus-animation-")
    out_dir = args.out or (tmp if args.quick else os.path.join(H.ROOT, "bench", "results"))
    try:
        info = H.run_info(args.quick, repeat, size, frames=args.frames)
        locus = H.Locus(H.copy_binary(args.locus, tmp), tmp)
        info["locus"] = locus.sha[:12]
        scenes = []
        for name, (kind, level) in GENERATED:
            if args.quick:
                level = 5 if kind == "tetra" else 3
                name = f"{kind} level {level}"
            path = os.path.join(tmp, f"{kind}{level}.nff")
            with open(path, "w") as f:
                f.write(spdgen.generate(kind, level))
            scenes.append((name, path))
        scenes += SHIPPED
        results = {}
        for name, path in scenes:
            H.log(f"{name} ...")
            results[name] = measure(locus, path, size, args.frames, repeat, tmp)
        info["load_end"] = H.loadavg()
        report(out_dir, info, results)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()

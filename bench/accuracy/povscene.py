#!/usr/bin/env python3
"""Scenes for POV-Ray 3.7: Locus JSON and NFF translated to .pov.

The shading of ../../shared/SHADING.md is followed as closely as POV-Ray's
model allows (see DIFFERENCES below, also written into every file's header):

- camera: `direction` = w, `right` = 2 tan(angle/2) (W/H) u, `up` =
  2 tan(angle/2) v, the vectors SPD's own converter writes (angle is edge to
  edge of the image). POV-Ray has no hither plane.
- lights: point lights, no distance attenuation; colour E_j (SPD default
  sqrt(L)/(2L)). Ambient A enters as `finish { ambient A*Kd }` with
  `ambient_light 1`.
- materials: pigment C with `transmit T`; `diffuse Kd`, `phong Ks
  phong_size Shine`, `reflection Ks`; `interior { ior }`; Lambert-Beer
  absorption q as `fade_power 1001` (exp(-(1 - fade_color) d /
  fade_distance)). POV-Ray scales ambient and diffuse of a surface by its
  opacity 1 - T, so both are divided by 1 - T here to give Kd*C.
- `max_trace_level 5`, `adc_bailout 1/512` (the ray-tree rule), linear
  output (`assumed_gamma 1`).

Usage:
  povscene.py SCENE.json|SCENE.nff -o OUT.pov
  povscene.py --paper   # regenerate bench/accuracy/pov/*.pov from scenes/paper
"""
import argparse
import json
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))

# The scenes whose .pov lives in bench/accuracy/pov/ (our own scenes).
PAPER_SCENES = ["a_glass", "b_desk", "d_spheres_2lights"]

DIFFERENCES = """\
Shading that POV-Ray 3.7 cannot match exactly (SHADING.md vs this file):
- transparent shadows: POV-Ray multiplies a shadow ray by the pigment's
  transmit T at every surface it crosses (T^2 through a solid) and never cuts
  it off; Locus uses the Fresnel factors (1-r_a)(1-r_b) of eq. (3), with
  r = 1 beyond the critical angle. Lambert-Beer absorption matches.
- total internal reflection: POV-Ray adds the internally reflected ray
  unweighted; Locus weights it by T.
- no hither plane in POV-Ray; Locus ignores eye-ray hits nearer than hither.
- pixel sampling and anti-aliasing are POV-Ray's own (+AM1/+AM2, jitter).
"""


# ---------------------------------------------------------------- vectors

def sub(a, b):
    return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]


def add(a, b):
    return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]


def mul(a, s):
    return [a[0] * s, a[1] * s, a[2] * s]


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def normalize(a):
    n = math.sqrt(dot(a, a))
    return [a[0] / n, a[1] / n, a[2] / n]


def any_perpendicular(n):
    """The same choice as common/base/math.h, so prisms get the same vertices."""
    a = [1, 0, 0] if abs(n[0]) < 0.6 else ([0, 1, 0] if abs(n[1]) < 0.6 else [0, 0, 1])
    return normalize(cross(n, a))


def vec(v):
    return "<%.9g, %.9g, %.9g>" % tuple(v)


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def rotation(axis, degrees):
    x, y, z = normalize(axis)
    t = math.radians(degrees)
    c, s, C = math.cos(t), math.sin(t), 1 - math.cos(t)
    return [[c + x * x * C, x * y * C - z * s, x * z * C + y * s, 0],
            [y * x * C + z * s, c + y * y * C, y * z * C - x * s, 0],
            [z * x * C - y * s, z * y * C + x * s, c + z * z * C, 0],
            [0, 0, 0, 1]]


def world_from_object(tr):
    """docs/scene-format.md: translate * rotate[n-1] * ... * rotate[0] * scale."""
    if not tr:
        return None
    if "matrix" in tr:
        m = [float(x) for x in tr["matrix"]]
        return [m[0:4], m[4:8], m[8:12], m[12:16]]
    s = tr.get("scale", [1])
    s = [s, s, s] if not isinstance(s, list) else (s * 3 if len(s) == 1 else s)
    m = [[s[0], 0, 0, 0], [0, s[1], 0, 0], [0, 0, s[2], 0], [0, 0, 0, 1]]
    for r in tr.get("rotate", []):
        m = matmul(rotation(r["axis"], r["degrees"]), m)
    t = tr.get("translate", [0, 0, 0])
    m = matmul([[1, 0, 0, t[0]], [0, 1, 0, t[1]], [0, 0, 1, t[2]], [0, 0, 0, 1]], m)
    return m


def pov_matrix(m):
    # POV-Ray's matrix <a..l> maps (x,y,z) to (ax+dy+gz+j, bx+ey+hz+k, cx+fy+iz+l):
    # its rows are the columns of our column-vector matrix.
    vals = [m[0][0], m[1][0], m[2][0], m[0][1], m[1][1], m[2][1],
            m[0][2], m[1][2], m[2][2], m[0][3], m[1][3], m[2][3]]
    return "matrix <" + ", ".join("%.12g" % v for v in vals) + ">"


# ---------------------------------------------------------------- common parts

def header(source, note=""):
    return [
        "// POV-Ray 3.7 translation of %s, written by bench/accuracy/povscene.py." % source,
        "// Conventions of ../../shared/SHADING.md as far as POV-Ray allows.",
    ] + ["// " + line for line in DIFFERENCES.splitlines()] + (
        ["// " + line for line in note.splitlines()] if note else []) + [
        "#version 3.7;",
        "global_settings { assumed_gamma 1.0 ambient_light rgb <1, 1, 1>"
        " max_trace_level 5 adc_bailout 1/512 }",
    ]


def camera(frm, at, up, angle):
    w = normalize(sub(at, frm))
    u = normalize(cross(w, up))
    v = cross(u, w)
    k = 2.0 * math.tan(math.radians(angle) / 2.0)
    return ["camera {", "  perspective", "  location " + vec(frm), "  direction " + vec(w),
            "  right %s * image_width / image_height" % vec(mul(u, k)),
            "  up " + vec(mul(v, k)), "}"]


def texture_decl(name, color, kd, ks, shine, t, ior, ambient, absorption=None):
    """One #declare'd material: a texture and, for T > 0, an interior."""
    opacity = 1.0 - t
    scale = 1.0 / opacity if opacity > 1e-9 else 0.0  # T = 1: no diffuse in POV-Ray
    fin = ["ambient %.9g" % (ambient * kd * scale), "diffuse %.9g" % (kd * scale)]
    if ks > 0:
        fin.append("phong %.9g phong_size %.9g" % (ks, shine))
        fin.append("reflection { %.9g }" % ks)
    out = ["#declare %s_tex = texture {" % name,
           "  pigment { rgbt <%.9g, %.9g, %.9g, %.9g> }" % (color[0], color[1], color[2], t),
           "  finish { " + " ".join(fin) + " }", "}"]
    interior = ["ior %.9g" % ior]
    if absorption and max(absorption) > 0:
        qmax = max(absorption)
        # exp(-(1 - fade_color) d / fade_distance) = exp(-q d) per channel.
        interior.append("fade_power 1001 fade_distance %.9g fade_color <%.9g, %.9g, %.9g>" % (
            1.0 / qmax, 1 - absorption[0] / qmax, 1 - absorption[1] / qmax,
            1 - absorption[2] / qmax))
    if t > 0:
        out.append("#declare %s_int = interior { %s }" % (name, " ".join(interior)))
    return out


def material_ref(name, t):
    s = "texture { %s_tex }" % name
    if t > 0:
        s += " interior { %s_int }" % name
    return s


# ---------------------------------------------------------------- JSON

def prism_vertices(p):
    base, apex = p["base"], p["apex"]
    w = normalize(sub(apex, base))
    u = any_perpendicular(w)
    v = cross(w, u)
    n, r = p["sides"], p["radius"]
    tw = p.get("twistDegrees", p.get("twist_degrees", 0.0))
    verts = []
    for c in (base, apex):
        for i in range(n):
            a = math.radians(tw) + 2.0 * math.pi * i / n
            verts.append(add(c, add(mul(u, r * math.cos(a)), mul(v, r * math.sin(a)))))
    faces = []
    for i in range(n):
        j = (i + 1) % n
        faces.append([i, j, n + j, n + i])
    faces.append([n - 1 - i for i in range(n)])
    faces.append([n + i for i in range(n)])
    return verts, faces


def mesh_of(verts, faces):
    tris = []
    for f in faces:
        for k in range(1, len(f) - 1):
            tris.append("  triangle { %s, %s, %s }" % (vec(verts[f[0]]), vec(verts[f[k]]),
                                                        vec(verts[f[k + 1]])))
    # inside_vector makes the mesh a solid (needed for refraction and shadows).
    return ["mesh {"] + tris + ["  inside_vector <0.123, 0.456, 0.789>"]


def json_to_pov(path):
    with open(path) as f:
        sc = json.load(f)
    cam = sc["camera"]
    lights = sc.get("lights", [])
    nl = len(lights)
    default_e = math.sqrt(nl) / (2 * nl) if nl else 0.0
    ambient = sc.get("ambient", default_e)
    out = header(os.path.relpath(path, ROOT))
    out += camera(cam["from"], cam["at"], cam.get("up", [0, 1, 0]), cam.get("angle", 45))
    bg = sc.get("background", [0, 0, 0])
    out.append("background { rgb %s }" % vec(bg))
    for li in lights:
        col = li.get("color")
        inten = li.get("intensity", 1.0)
        if col:
            col = mul(col, inten)
        else:  # no colour: white of the given intensity, else the SPD default
            col = [inten if "intensity" in li else default_e] * 3
        out.append("light_source { %s rgb %s }" % (vec(li["position"]), vec(col)))
    mats = sc.get("materials", [])
    for i, m in enumerate(mats):
        out += texture_decl("m%d" % i, m.get("color", [1, 1, 1]), m.get("kd", 1.0),
                            m.get("ks", 0.0), m.get("shine", 0.0), m.get("t", 0.0),
                            m.get("ior", 1.0), ambient, m.get("absorption"))
    for o in sc.get("objects", []):
        mi = o.get("material", 0)
        t = mats[mi].get("t", 0.0) if mi < len(mats) else 0.0
        body = []
        if "sphere" in o:
            s = o["sphere"]
            body = ["sphere { %s, %.9g" % (vec(s.get("center", [0, 0, 0])), s["radius"])]
        elif "cylinder" in o:
            c = o["cylinder"]
            body = ["cylinder { %s, %s, %.9g%s" % (vec(c["base"]), vec(c["apex"]), c["radius"],
                                                  "" if c.get("capped") else " open")]
        elif "cone" in o:
            c = o["cone"]
            r0 = c.get("baseRadius", c.get("base_radius", 0.0))
            r1 = c.get("apexRadius", c.get("apex_radius", 0.0))
            body = ["cone { %s, %.9g, %s, %.9g%s" % (vec(c["base"]), r0, vec(c["apex"]), r1,
                                                    "" if c.get("capped") else " open")]
        elif "box" in o:
            b = o["box"]
            body = ["box { %s, %s" % (vec(b["min"]), vec(b["max"]))]
        elif "prism" in o:
            body = mesh_of(*prism_vertices(o["prism"]))
        elif "polyhedron" in o and "faces" in o["polyhedron"]:
            p = o["polyhedron"]
            v = p["vertices"]
            verts = [v[i:i + 3] for i in range(0, len(v), 3)]
            body = mesh_of(verts, [f["vertices"] for f in p["faces"]])
        elif "polygon" in o:
            v = o["polygon"]["vertices"]
            verts = [v[i:i + 3] for i in range(0, len(v), 3)]
            body = ["polygon { %d, %s" % (len(verts) + 1, ", ".join(vec(x) for x in verts + verts[:1]))]
        else:
            raise SystemExit("%s: object %s: shape not supported by povscene.py" %
                             (path, o.get("name", "?")))
        m = world_from_object(o.get("transform"))
        name = o.get("name", "")
        out.append("// " + name if name else "//")
        out += body
        if m is not None:
            out.append("  " + pov_matrix(m))
        out.append("  " + material_ref("m%d" % mi, t))
        out.append("}")
    return "\n".join(out) + "\n"


# ---------------------------------------------------------------- NFF

def nff_to_pov(path):
    """NFF (SPD) to POV-Ray. Consecutive transparent polygons of one material
    become one union sharing an interior, so refraction sees closed solids."""
    toks = []
    with open(path) as f:
        for line in f:
            line = line.split("#", 1)[0]
            toks.append(line.split())
    # Flatten into a token stream but keep line structure for `l` colours.
    cam = {}
    lights = []
    bg = [0, 0, 0]
    mats = []      # (color, kd, ks, shine, t, ior)
    prims = []     # (material index, pov text)
    cur = -1
    stream = [(li, t) for li, line in enumerate(toks) for t in line]
    pos = 0

    def nxt():
        nonlocal pos
        t = stream[pos][1]
        pos += 1
        return t

    def num():
        return float(nxt())

    def vec3():
        return [num(), num(), num()]

    while pos < len(stream):
        line_no, t = stream[pos]
        pos += 1
        if t == "v":
            continue
        if t in ("from", "at", "up"):
            cam[t] = vec3()
        elif t == "angle":
            cam["angle"] = num()
        elif t == "hither":
            cam["hither"] = num()
        elif t == "resolution":
            num(), num()
        elif t == "b":
            bg = vec3()
        elif t == "l":
            p = vec3()
            col = None
            if pos + 2 < len(stream) and stream[pos][0] == line_no:
                col = vec3()
            lights.append((p, col))
        elif t == "f":
            vals = [num() for _ in range(8)]
            mats.append((vals[0:3], vals[3], vals[4], vals[5], vals[6], vals[7]))
            cur = len(mats) - 1
        elif t == "s":
            c = vec3()
            r = num()
            prims.append((cur, "sphere { %s, %.9g" % (vec(c), r)))
        elif t == "c":
            b = vec3()
            r0 = num()
            a = vec3()
            r1 = num()
            if r0 == r1:
                prims.append((cur, "cylinder { %s, %s, %.9g open" % (vec(b), vec(a), r0)))
            else:
                prims.append((cur, "cone { %s, %.9g, %s, %.9g open" % (vec(b), r0, vec(a), r1)))
        elif t == "p":
            n = int(nxt())
            vs = [vec3() for _ in range(n)]
            prims.append((cur, "polygon { %d, %s" % (n + 1, ", ".join(vec(x) for x in vs + vs[:1]))))
        elif t == "pp":
            n = int(nxt())
            vs, ns = [], []
            for _ in range(n):
                vs.append(vec3())
                ns.append(vec3())
            tris = ["smooth_triangle { %s, %s, %s, %s, %s, %s }" % (
                vec(vs[0]), vec(ns[0]), vec(vs[k]), vec(ns[k]), vec(vs[k + 1]), vec(ns[k + 1]))
                for k in range(1, n - 1)]
            prims.append((cur, "mesh { " + " ".join(tris)))
        else:
            raise SystemExit("%s:%d: unknown NFF token %r" % (path, line_no + 1, t))
    nl = len(lights)
    e = math.sqrt(nl) / (2 * nl) if nl else 0.0
    out = header(os.path.basename(path),
                 "NFF hither %.9g is not represented." % cam.get("hither", 0.001))
    out += camera(cam["from"], cam["at"], cam["up"], cam["angle"])
    out.append("background { rgb %s }" % vec(bg))
    for p, col in lights:
        out.append("light_source { %s rgb %s }" % (vec(p), vec(col if col else [e, e, e])))
    for k, (c, kd, ks, sh, t, ior) in enumerate(mats):
        out += texture_decl("m%d" % k, c, kd, ks, sh, t, ior, e)
    k = 0
    while k < len(prims):
        mi, text = prims[k]
        t = mats[mi][4]
        if t > 0 and text.startswith("polygon"):
            group = []
            while k < len(prims) and prims[k][0] == mi and prims[k][1].startswith("polygon"):
                group.append(prims[k][1] + " }")
                k += 1
            out.append("union {")
            out += ["  " + g for g in group]
            out.append("  " + material_ref("m%d" % mi, t))
            out.append("}")
            continue
        out.append(text + " " + material_ref("m%d" % mi, t) + " }")
        k += 1
    return "\n".join(out) + "\n"


def convert(path):
    return json_to_pov(path) if path.endswith(".json") else nff_to_pov(path)


def paper_pov_path(name):
    return os.path.join(HERE, "pov", name + ".pov")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene", nargs="?")
    ap.add_argument("-o", "--output")
    ap.add_argument("--paper", action="store_true",
                    help="regenerate bench/accuracy/pov/*.pov from scenes/paper/*.json")
    args = ap.parse_args()
    if args.paper:
        os.makedirs(os.path.join(HERE, "pov"), exist_ok=True)
        for name in PAPER_SCENES:
            text = json_to_pov(os.path.join(ROOT, "scenes", "paper", name + ".json"))
            with open(paper_pov_path(name), "w") as f:
                f.write(text)
            print("wrote", os.path.relpath(paper_pov_path(name), ROOT))
        return
    if not args.scene:
        ap.error("give a scene or --paper")
    text = convert(args.scene)
    if args.output:
        with open(args.output, "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()

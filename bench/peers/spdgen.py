#!/usr/bin/python3
"""SPD `balls` (sphereflake) and `tetra` (Sierpinski tetrahedron) in NFF at any
recursion level, for the scaling benchmark (issue #9 item 5).

Written from the SPD definitions (Haines, "A Proposal for Standard Graphics
Environments", and ../../../shared/spd/NFF.TXT) and checked against the
shared files: level 1, 2 and the default level reproduce ../shared/spd/s1,
s2 and def (`--check`), so the larger levels are the same scenes, grown.

- balls: a sphere of radius 0.5 at the origin; each sphere of radius r gets
  9 children of radius r/3 on its surface's directions, at distance
  r (1 + 1/3) from its centre: a trio at 45 degrees rotated three times by
  120 degrees about the parent's axis, the whole set turned from +Z onto the
  parent's direction. Level n (`s1` = 1, `s2` = 2, default = 4) has
  (9^(n+1) - 1) / 8 spheres, depth first, plus the floor polygon.
- tetra: a tetrahedron of half-size 1 at the origin, replaced recursively by
  4 half-size tetrahedra at its corners; level n (`s1` = 1, `s2` = 2,
  default = 6) has 4^n triangles.

Usage: spdgen.py balls|tetra LEVEL [-o OUT.nff]
       spdgen.py --check        # compare levels 1, 2 and default with ../shared/spd
"""
import argparse
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
SPD = os.path.normpath(os.path.join(HERE, "..", "..", "..", "shared", "spd"))

# Viewing, lights and materials: as in every size of the shared files.
BALLS_HEADER = """\
b 0.078 0.361 0.753
v
from 2.1 1.3 1.7
at 0 0 0
up 0 0 1
angle 45
hither 0.01
resolution 512 512
l 4 3 2
l 1 -4 4
l -3 1 5
f 1 0.75 0.33 0.8 0 100000 0 1
p 4
12 12 -0.5
-12 12 -0.5
-12 -12 -0.5
12 -12 -0.5
f 1 0.9 0.7 0.5 0.5 3.0827 0 1
"""

TETRA_HEADER = """\
b 0.078 0.361 0.753
v
from 1.02285 -3.17715 -2.17451
at -0.004103 -0.004103 0.216539
up -0.816497 -0.816497 0.816497
angle 45
hither 1
resolution 512 512
l 2 -18 -5
f 1 0.2 0.2 1 0 100000 0 0
"""

DEFAULT_LEVEL = {"balls": 4, "tetra": 6}


def count(kind, level):
    """Primitives of the generated scene (the floor polygon included)."""
    return (9 ** (level + 1) - 1) // 8 + 1 if kind == "balls" else 4 ** level


def axis_rotation(axis, angle):
    x, y, z = axis
    c, s, C = math.cos(angle), math.sin(angle), 1.0 - math.cos(angle)
    return [[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
            [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
            [z * x * C - y * s, z * y * C + x * s, c + z * z * C]]


def apply(m, v):
    return [sum(m[i][k] * v[k] for k in range(3)) for i in range(3)]


def normalize(v):
    n = math.sqrt(sum(x * x for x in v))
    return [x / n for x in v]


def sphereflake_directions():
    """The 9 child directions about +Z: a trio tilted so that it sits at
    asin(2/sqrt(6)) about (1, -1, 0), then turned by 0, 120, 240 degrees."""
    d = 1.0 / math.sqrt(2.0)
    trio = [[d, d, 0.0], [d, 0.0, -d], [0.0, d, -d]]
    tilt = axis_rotation(normalize([1.0, -1.0, 0.0]), math.asin(2.0 / math.sqrt(6.0)))
    trio = [apply(tilt, v) for v in trio]
    out = []
    for k in range(3):
        turn = axis_rotation([0.0, 0.0, 1.0], k * 2.0 * math.pi / 3.0)
        out += [apply(turn, v) for v in trio]
    return out


def balls(level, write):
    objset = sphereflake_directions()

    def sphere(depth, c, r, direction):
        write("s %g %g %g %g\n" % (c[0], c[1], c[2], r))
        if depth == 0:
            return
        # Straight up or down (to rounding: a child's direction is computed,
        # so "down" comes out as -1 + 1e-16): SPD's special cases, since the
        # axis z x direction is then undefined.
        if direction[2] >= 1.0 - 1e-12:
            m = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
        elif direction[2] <= -1.0 + 1e-12:
            m = axis_rotation([0.0, 1.0, 0.0], math.pi)
        else:  # the rotation taking +Z onto the parent's direction
            axis = normalize([-direction[1], direction[0], 0.0])  # z x direction
            m = axis_rotation(axis, math.acos(direction[2]))
        dist = r * (1.0 + 1.0 / 3.0)
        for v in objset:
            u = apply(m, v)
            child = [c[i] + dist * u[i] for i in range(3)]
            sphere(depth - 1, child, r / 3.0, u)

    write(BALLS_HEADER)
    sphere(level, [0.0, 0.0, 0.0], 0.5, [0.0, 0.0, 1.0])


def tetra(level, write):
    # Corners in SPD's loop order (x, then y, then z, with x y z = 1) and the
    # faces' vertex order, as in the shared files (outward faces).
    dirs = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1) if x * y * z == 1]
    faces = [(0, 1, 2), (3, 2, 1), (2, 3, 0), (1, 0, 3)]

    def node(depth, c, size):
        if depth > 1:
            for d in dirs:
                half = size / 2.0
                node(depth - 1, [c[i] + d[i] * half for i in range(3)], half)
            return
        v = [[c[i] + d[i] * size for i in range(3)] for d in dirs]
        for f in faces:
            write("p 3\n" + "".join("%g %g %g\n" % tuple(v[k]) for k in f))

    write(TETRA_HEADER)
    node(level, [0.0, 0.0, 0.0], 1.0)


def generate(kind, level):
    parts = []
    {"balls": balls, "tetra": tetra}[kind](level, parts.append)
    return "".join(parts)


def numbers(text):
    out = []
    for tok in text.split():
        try:
            out.append(float(tok))
        except ValueError:
            out.append(tok)
    return out


def same(a, b, tol=2e-5):
    """Token by token; numbers within tol (the files print 6 digits)."""
    if len(a) != len(b):
        return False, "%d tokens vs %d" % (len(a), len(b))
    for i, (x, y) in enumerate(zip(a, b)):
        if isinstance(x, float) and isinstance(y, float):
            if abs(x - y) > tol * max(1.0, abs(y)):
                return False, "token %d: %g vs %g" % (i, x, y)
        elif x != y:
            return False, "token %d: %r vs %r" % (i, x, y)
    return True, ""


def check():
    ok = True
    for kind in ("balls", "tetra"):
        for sub, level in (("s1", 1), ("s2", 2), ("def", DEFAULT_LEVEL[kind])):
            path = os.path.join(SPD, sub, kind + ".nff")
            with open(path) as f:
                good, why = same(numbers(generate(kind, level)), numbers(f.read()))
            print("%s %s level %d (%d primitives): %s %s" % (
                "OK  " if good else "FAIL", path, level, count(kind, level),
                "same" if good else "differs:", why))
            ok &= good
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("kind", nargs="?", choices=["balls", "tetra"])
    ap.add_argument("level", nargs="?", type=int)
    ap.add_argument("-o", "--output")
    ap.add_argument("--check", action="store_true",
                    help="compare levels 1, 2 and the default with ../shared/spd")
    args = ap.parse_args()
    if args.check:
        sys.exit(0 if check() else 1)
    if args.kind is None or args.level is None or args.level < 1:
        ap.error("give balls|tetra and a level >= 1, or --check")
    text = generate(args.kind, args.level)
    if args.output:
        with open(args.output, "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()

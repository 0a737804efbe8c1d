#!/usr/bin/python3
"""Writes the example scenes of Nakamae, Tadamura, Nishita 1986 (Fig. 8) in
Locus's native JSON scene format (proto/scene.proto), next to this script.

    /usr/bin/python3 scenes/paper/make_paper_scenes.py

Standard library only and deterministic: running it again rewrites the same
bytes. The world is right-handed with y up; floors and desk tops have their
top face at y = 0. See scenes/README.md for what each scene shows.

Scenes:
  a_glass.json             Fig. 8(a): glass cylinder (n = 1.52) on a 10-faced
                           glass stand; its shadow shows the dark cores of
                           total internal reflection.
  b_desk.json              Fig. 8(b): transparent clock, green absorbing ink
                           bottle, opaque book and pencil; two lights.
  c_thermometer.json       Fig. 8(c): thermometer and other objects, 12 in
                           all, with CSG bodies and a mirror.
  d_spheres_{1,2,3}light(s).json
                           Fig. 8(d) / Table 1: four groups of a mirror sphere
                           ringed by 16 prisms; 1, 2 and 3 lights.
"""

import json
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))
SIZE = 512  # the paper's display: 512 x 512 pixels


# ---------------------------------------------------------------- building --

class Scene:
    """Collects materials and objects; objects refer to materials by index."""

    def __init__(self, camera, background, ambient=None):
        self.data = {"camera": camera, "background": background}
        if ambient is not None:
            self.data["ambient"] = ambient
        self.data["lights"] = []
        self.data["materials"] = []
        self.data["objects"] = []
        self._material_index = {}

    def light(self, position, color=None):
        light = {"position": position}
        if color is not None:
            light["color"] = color
        self.data["lights"].append(light)

    def material(self, name, color, kd=1.0, ks=0.0, shine=0.0, t=0.0,
                 ior=None, absorption=None):
        """Adds a material (NFF "f r g b Kd Ks Shine T ior" + absorption)."""
        m = {"name": name, "color": color, "kd": kd}
        if ks:
            m["ks"] = ks
            # A highlight exponent is always given with ks > 0: Shine 0 would
            # make the Phong term max(0, R.V)^0 = 1 over the lit side.
            m["shine"] = shine
        if t:
            m["t"] = t
        if ior is not None:
            m["ior"] = ior
        if absorption is not None:
            m["absorption"] = absorption
        self._material_index[name] = len(self.data["materials"])
        self.data["materials"].append(m)

    def add(self, name, material, shape, transform=None):
        """Adds an object; shape is e.g. {"sphere": {...}}. Returns its index."""
        obj = {"name": name}
        obj.update(shape)
        obj["material"] = self._material_index[material]
        if transform:
            obj["transform"] = transform
        self.data["objects"].append(obj)
        return len(self.data["objects"]) - 1

    def write(self, filename):
        path = os.path.join(HERE, filename)
        with open(path, "w", encoding="utf-8") as f:
            f.write(to_json(self.data) + "\n")
        print("wrote", os.path.relpath(path))


def camera(eye, at, angle, up=(0, 1, 0)):
    return {"from": list(eye), "at": list(at), "up": list(up),
            "angle": angle, "hither": 0.01, "width": SIZE, "height": SIZE}


# Shapes. All points are [x, y, z] lists.

def sphere(center, radius):
    return {"sphere": {"center": list(center), "radius": radius}}


def cylinder(base, apex, radius, capped=True):
    return {"cylinder": {"base": list(base), "apex": list(apex),
                         "radius": radius, "capped": capped}}


def cone(base, base_radius, apex, apex_radius=0.0, capped=True):
    c = {"base": list(base), "baseRadius": base_radius, "apex": list(apex),
         "capped": capped}
    if apex_radius:
        c["apexRadius"] = apex_radius
    return {"cone": c}


def box(lo, hi):
    return {"box": {"min": list(lo), "max": list(hi)}}


def prism(sides, radius, base, apex, twist=0.0):
    p = {"sides": sides, "radius": radius, "base": list(base),
         "apex": list(apex)}
    if twist:
        p["twistDegrees"] = twist
    return {"prism": p}


def polygon(points):
    return {"polygon": {"vertices": [c for p in points for c in p]}}


def csg(op, left, right):
    return {"csg": {"op": op, "left": left, "right": right}}


def placed(translate, y_degrees=0.0):
    """Transform: turn about the vertical axis, then move to `translate`."""
    t = {"translate": list(translate)}
    if y_degrees:
        t["rotate"] = [{"axis": [0, 1, 0], "degrees": y_degrees}]
    return t


# ------------------------------------------------------------ JSON output --

def _number(x):
    if isinstance(x, bool) or isinstance(x, int):
        return json.dumps(x)
    x = round(float(x), 6)
    if x == 0:
        x = 0.0  # no "-0.0"
    if x == int(x) and abs(x) < 1e15:
        return str(int(x)) + ".0"
    return repr(x)


def to_json(value, indent=""):
    """JSON with numeric lists (vectors, vertex lists) kept on one line."""
    inner = indent + "  "
    if isinstance(value, dict):
        items = [inner + json.dumps(k) + ": " + to_json(v, inner)
                 for k, v in value.items()]
        return "{\n" + ",\n".join(items) + "\n" + indent + "}"
    if isinstance(value, (list, tuple)):
        if all(isinstance(v, (int, float)) for v in value):
            # Every numeric list of the schema used here is `repeated double`.
            return "[" + ", ".join(_number(float(v)) for v in value) + "]"
        items = [inner + to_json(v, inner) for v in value]
        return "[\n" + ",\n".join(items) + "\n" + indent + "]"
    if isinstance(value, str):
        return json.dumps(value)
    return _number(value)


# Glass: almost all transmission, a little mirror reflection, no diffuse.
def add_glass(scene, name="glass", ior=1.52, absorption=None, t=0.92,
              ks=0.08):
    scene.material(name, [1.0, 1.0, 1.0], kd=0.0, ks=ks, shine=200.0, t=t,
                   ior=ior, absorption=absorption)


# ----------------------------------------------------------------- (a) ------

def scene_a_glass():
    """Fig. 8(a): a glass cylinder (n = 1.52) on a 10-faced glass stand.

    The light is low (about 22 degrees above the horizon at the cylinder) so
    that straight light paths through the middle of the cylinder's side meet
    its surface below the critical angle (41.1 degrees for n = 1.52) and pass,
    while paths near its silhouette exceed it: the long shadow on the floor
    has a light centre and dark cores along both edges (paper eq. (3)).
    """
    s = Scene(camera([6.5, 5.0, 10.0], [0.6, 1.1, 0.6], 40.0),
              background=[0.08, 0.09, 0.12], ambient=0.18)
    s.light([-10.0, 6.0, -4.0], [1.0, 1.0, 1.0])

    s.material("floor", [0.86, 0.83, 0.76], kd=0.9)
    s.material("wall", [0.55, 0.62, 0.7], kd=0.8)
    s.material("red", [0.85, 0.15, 0.12], kd=0.9)
    s.material("blue", [0.15, 0.3, 0.85], kd=0.9)
    s.material("yellow", [0.9, 0.75, 0.15], kd=0.9)
    add_glass(s, "glass")
    # The stand is slightly tinted so that it reads apart from the cylinder.
    add_glass(s, "stand glass", absorption=[0.25, 0.08, 0.04])

    s.add("floor", "floor", box([-25, -0.2, -25], [25, 0, 25]))
    s.add("back wall", "wall", box([-25, 0, -9.5], [25, 9, -9]))
    # 10 faces: an octagonal prism (8 sides + 2 caps). Transparent bodies
    # float 0.01 above what they stand on, so no two surfaces coincide.
    stand_top = 0.41
    s.add("stand", "stand glass",
          prism(8, 1.7, [0, 0.01, 0], [0, stand_top, 0], twist=22.5))
    s.add("glass cylinder", "glass",
          cylinder([0, stand_top + 0.01, 0], [0, stand_top + 2.61, 0], 0.8))
    # Background objects, seen through the glass from the camera.
    s.add("red box", "red", box([-4.8, 0, -4.4], [-3.2, 1.6, -2.8]))
    s.add("blue box", "blue", box([-0.6, 0, -1.0], [0.6, 2.4, 0.2]),
          placed([-1.2, 0, -4.6], 30.0))
    s.add("yellow ball", "yellow", sphere([1.8, 0.7, -3.2], 0.7))
    s.write("a_glass.json")


# ----------------------------------------------------------------- (b) ------

def scene_b_desk():
    """Fig. 8(b): a transparent clock, a green strongly absorbing ink bottle,
    an opaque book and a pencil on a desk top, lit by two point lights."""
    s = Scene(camera([0.6, 5.6, 10.5], [0.5, 0.9, 0.1], 44.0),
              background=[0.12, 0.12, 0.14], ambient=0.15)
    # Both lights in front of the clock: the shadow model ignores refraction,
    # so light meeting the flat clock glass beyond the critical angle
    # (41.8 degrees for n = 1.5) would leave the dial in total shadow.
    s.light([-5.0, 7.0, 10.0], [0.75, 0.75, 0.72])
    s.light([7.0, 8.0, 9.0], [0.4, 0.4, 0.45])

    s.material("desk", [0.55, 0.36, 0.2], kd=0.9)
    s.material("brass", [0.75, 0.58, 0.25], kd=0.7, ks=0.25, shine=40.0)
    s.material("dial", [0.95, 0.94, 0.9], kd=0.9)
    s.material("black", [0.05, 0.05, 0.05], kd=0.8, ks=0.1, shine=60.0)
    add_glass(s, "clock glass", ior=1.5, t=0.9, ks=0.1)
    # Ink: a green, strongly absorbing glass body (q per channel, 1/unit).
    s.material("green ink", [1.0, 1.0, 1.0], kd=0.0, ks=0.08, shine=200.0,
               t=0.92, ior=1.5, absorption=[2.0, 0.3, 2.0])
    s.material("cover", [0.55, 0.08, 0.1], kd=0.85)
    s.material("pages", [0.93, 0.91, 0.84], kd=0.9)
    s.material("pencil", [0.95, 0.75, 0.1], kd=0.85, ks=0.05, shine=30.0)
    s.material("wood", [0.9, 0.72, 0.5], kd=0.9)
    s.material("graphite", [0.12, 0.12, 0.13], kd=0.8, ks=0.15, shine=40.0)
    s.material("ferrule", [0.8, 0.8, 0.82], kd=0.5, ks=0.4, shine=80.0)
    s.material("eraser", [0.9, 0.45, 0.5], kd=0.9)

    s.add("desk top", "desk", box([-12, -0.4, -10], [12, 0, 10]))

    # The clock, built facing +z around its centre, then turned toward the
    # camera: body, dial, 12 hour marks, two hands, a glass cover, a foot.
    at = placed([-2.6, 0, -1.6], 20.0)
    cy = 1.6                       # height of the clock's centre
    s.add("clock foot", "brass", box([-0.9, 0, -0.45], [0.9, 0.25, 0.15]), at)
    s.add("clock body", "brass",
          cylinder([0, cy, -0.4], [0, cy, 0.05], 1.45), at)
    s.add("clock dial", "dial",
          cylinder([0, cy, 0.0], [0, cy, 0.08], 1.3), at)

    def on_dial(clockwise_degrees):
        """Turned clockwise about the dial centre, then placed with the clock:
        object-to-world = translate * rotate_y * rotate_z."""
        return {"translate": [at["translate"][0], cy, at["translate"][2]],
                "rotate": [{"axis": [0, 0, 1], "degrees": -clockwise_degrees},
                           at["rotate"][0]]}

    for hour in range(12):
        long = 0.28 if hour % 3 == 0 else 0.16
        s.add("hour mark %d" % (hour or 12), "black",
              box([-0.04, 1.12 - long, 0.07], [0.04, 1.12, 0.1]),
              on_dial(30.0 * hour))
    # 10:10, in front of the marks; the minute hand above the hour hand.
    # Parts are sunk into each other or kept apart: no coincident faces.
    s.add("hour hand", "black", box([-0.06, -0.15, 0.105], [0.06, 0.7, 0.125]),
          on_dial(30.0 * (10 + 10 / 60.0)))
    s.add("minute hand", "black", box([-0.04, -0.15, 0.13], [0.04, 1.05, 0.15]),
          on_dial(6.0 * 10))
    s.add("clock glass", "clock glass",
          cylinder([0, cy, 0.17], [0, cy, 0.3], 1.35), at)

    # The ink bottle: a squat glass cylinder of green ink, with a black cap.
    s.add("ink bottle", "green ink",
          cylinder([0.7, 0.01, -1.4], [0.7, 1.2, -1.4], 0.8))
    s.add("ink cap", "black",
          cylinder([0.7, 1.21, -1.4], [0.7, 1.6, -1.4], 0.38))

    # The book: two boards and a spine around a block of pages, closed and
    # lying flat, turned on the desk.
    at = placed([3.3, 0, 0.4], -25.0)
    s.add("book back board", "cover", box([-1.6, 0, -1.15], [1.6, 0.07, 1.15]),
          at)
    s.add("book front board", "cover",
          box([-1.6, 0.5, -1.15], [1.6, 0.57, 1.15]), at)
    s.add("book spine", "cover", box([-1.6, 0, -1.15], [-1.5, 0.57, 1.15]), at)
    s.add("book pages", "pages", box([-1.51, 0.06, -1.1], [1.55, 0.51, 1.1]),
          at)

    # The pencil, lying on the desk along local +x: a hexagonal body, a
    # sharpened wooden truncated cone and a graphite cone (ray traced for
    # their exact curved surfaces), a metal ferrule and an eraser.
    r = 0.16                       # circumradius of the hexagon
    # Resting on a flat side: with the axis along x, Locus's prism (twist 0)
    # has two of its corners at the same lowest height r * cos(30 deg).
    y = r * math.cos(math.pi / 6)
    at = placed([-0.4, 0, 2.3], 12.0)
    s.add("pencil body", "pencil",
          prism(6, r, [-1.8, y, 0], [1.6, y, 0]), at)
    s.add("pencil wood tip", "wood",
          cone([1.58, y, 0], 0.135, [2.05, y, 0], 0.045), at)
    s.add("pencil lead", "graphite",
          cone([2.04, y, 0], 0.046, [2.2, y, 0]), at)
    s.add("pencil ferrule", "ferrule",
          cylinder([-2.15, y, 0], [-1.79, y, 0], 0.15), at)
    s.add("pencil eraser", "eraser",
          cylinder([-2.4, y, 0], [-2.14, y, 0], 0.14), at)
    s.write("b_desk.json")


# ----------------------------------------------------------------- (c) ------

def scene_c_thermometer():
    """Fig. 8(c): a thermometer and other objects, 12 objects in all.

    The 12 rendered objects: table, mirror, mirror frame, thermometer board,
    glass tube, liquid column, bulb, cup (CSG difference), die (CSG
    intersection), glass ball, cone, block. CSG operands are listed in the
    file too but are rendered only through their CSG node.
    """
    s = Scene(camera([3.0, 4.6, 10.5], [0.0, 1.6, -0.6], 40.0),
              background=[0.1, 0.1, 0.12], ambient=0.15)
    s.light([-5.0, 9.0, 8.0], [0.8, 0.8, 0.78])
    s.light([7.0, 6.0, 2.0], [0.35, 0.35, 0.4])

    s.material("table", [0.75, 0.7, 0.62], kd=0.9)
    s.material("mirror", [1.0, 1.0, 1.0], kd=0.05, ks=0.9, shine=200.0)
    s.material("frame", [0.4, 0.22, 0.1], kd=0.85)
    s.material("board", [0.95, 0.92, 0.8], kd=0.9)
    add_glass(s, "glass")
    s.material("red liquid", [0.9, 0.05, 0.05], kd=0.8, ks=0.2, shine=80.0)
    s.material("porcelain", [0.2, 0.4, 0.8], kd=0.8, ks=0.1, shine=60.0)
    s.material("ivory", [0.95, 0.9, 0.8], kd=0.85, ks=0.05, shine=40.0)
    s.material("orange", [0.95, 0.45, 0.1], kd=0.9)
    s.material("green", [0.2, 0.65, 0.3], kd=0.9)

    s.add("table", "table", box([-12, -0.4, -8], [12, 0, 10]))

    # A standing mirror behind everything: a polygon facing the camera (+z,
    # counter-clockwise seen from the front) in a wooden frame.
    zm = -3.0
    s.add("mirror", "mirror", polygon([[-3.0, 0.3, zm], [3.0, 0.3, zm],
                                       [3.0, 4.3, zm], [-3.0, 4.3, zm]]))
    s.add("mirror frame", "frame",
          box([-3.25, 0, zm - 0.2], [3.25, 4.55, zm - 0.01]))

    # The thermometer: a board, a capped glass tube in front of it, a red
    # liquid column inside the tube and a red bulb at its foot.
    xt, zt = -1.2, -0.6
    s.add("thermometer board", "board",
          box([xt - 0.4, 0, zt - 0.38], [xt + 0.4, 4.0, zt - 0.24]))
    s.add("thermometer tube", "glass",
          cylinder([xt, 0.75, zt], [xt, 3.7, zt], 0.14))
    s.add("liquid column", "red liquid",
          cylinder([xt, 0.6, zt], [xt, 2.6, zt], 0.045))
    s.add("thermometer bulb", "red liquid", sphere([xt, 0.62, zt], 0.21))

    # A cup: the difference of two capped cylinders (an open bowl).
    outer = s.add("cup outside", "porcelain",
                  cylinder([1.3, 0, -1.3], [1.3, 1.3, -1.3], 0.7))
    inner = s.add("cup inside", "porcelain",
                  cylinder([1.3, 0.12, -1.3], [1.3, 1.5, -1.3], 0.6))
    s.add("cup", "porcelain", csg("DIFFERENCE", outer, inner))

    # A die with rounded corners: a sphere intersected with a cube.
    # Both operands are placed by the same transform; the node has none.
    at = placed([0.4, 0, 1.2], 35.0)
    ball = s.add("die sphere", "ivory", sphere([0, 0.5, 0], 0.68), at)
    cube = s.add("die cube", "ivory", box([-0.5, 0, -0.5], [0.5, 1.0, 0.5]), at)
    s.add("die", "ivory", csg("INTERSECTION", ball, cube))

    s.add("glass ball", "glass", sphere([-2.6, 0.61, 1.0], 0.6))
    s.add("cone", "orange", cone([2.8, 0, 0.6], 0.55, [2.8, 1.6, 0.6]))
    s.add("block", "green", box([-0.7, 0, -0.35], [0.7, 0.5, 0.35]),
          placed([-0.4, 0, -1.6], -15.0))
    s.write("c_thermometer.json")


# ----------------------------------------------------------------- (d) ------

PRISM_COLOURS = [
    [0.85, 0.15, 0.12], [0.95, 0.55, 0.1], [0.9, 0.85, 0.15],
    [0.2, 0.7, 0.25], [0.15, 0.55, 0.8], [0.25, 0.25, 0.85],
    [0.6, 0.25, 0.75], [0.85, 0.85, 0.85],
]

# The same lights in all three files; file k uses the first k.
D_LIGHTS = [[-9.0, 14.0, 9.0], [11.0, 12.0, 3.0], [1.0, 15.0, -12.0]]


def scene_d_spheres(n_lights, radius=1.8, ring=3.2, spacing=4.4, eye=(0.0, 15.0, 13.0),
                    angle=50.0):
    """Fig. 8(d) and Table 1: four groups of a perfectly mirroring sphere
    ringed by 16 opaque prisms, arranged 2 x 2 on a floor.

    Only the spheres reflect, so only their spans need ray tracing; the
    prisms and the floor are diffuse (ks = 0) and fully handled by the
    scanline pass. Lights take the SPD default intensity sqrt(L)/(2L).

    The paper notes that in its examples the mirrors "occupy a considerable
    part" of the image; here the spheres' bounding polyhedra cover about a
    quarter of it (docs/shadow-volumes.md, Table 1).
    """
    s = Scene(camera(list(eye), [0.0, 0.0, 0.6], angle),
              background=[0.25, 0.3, 0.4], ambient=0.2)
    for position in D_LIGHTS[:n_lights]:
        s.light(position)

    s.material("floor", [0.8, 0.8, 0.78], kd=0.9)
    s.material("mirror", [1.0, 1.0, 1.0], kd=0.0, ks=1.0, shine=200.0)
    for i, colour in enumerate(PRISM_COLOURS):
        s.material("prism %d" % i, colour, kd=0.9)

    s.add("floor", "floor", box([-30, -0.2, -30], [30, 0, 30]))
    group = 0
    for gz in (-spacing, spacing):
        for gx in (-spacing, spacing):
            s.add("mirror sphere %d" % group, "mirror",
                  sphere([gx, radius, gz], radius))
            # Groups 0 and 3 have square prisms, 1 and 2 hexagonal ones.
            sides = 4 if group in (0, 3) else 6
            for k in range(16):
                a = 2 * math.pi * k / 16
                x = gx + ring * math.cos(a)
                z = gz + ring * math.sin(a)
                height = 0.6 + 0.3 * ((k + group) % 4)  # 0.6 .. 1.5
                s.add("group %d prism %d" % (group, k),
                      "prism %d" % ((k + 2 * group) % len(PRISM_COLOURS)),
                      prism(sides, 0.32, [x, 0, z], [x, height, z],
                            twist=math.degrees(a)))
            group += 1
    names = {1: "1light", 2: "2lights", 3: "3lights"}
    s.write("d_spheres_%s.json" % names[n_lights])


if __name__ == "__main__":
    scene_a_glass()
    scene_b_desk()
    scene_c_thermometer()
    for lights in (1, 2, 3):
        scene_d_spheres(lights)

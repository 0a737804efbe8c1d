#!/usr/bin/env python3
"""Analytic self-tests of the reference renderer (no C++ involved).

    python3 -m unittest discover -s tests/reference -v
    python3 tests/reference/test_nff_ref.py
"""
import contextlib
import io
import math
import os
import sys
import tempfile
import unittest

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import compare  # noqa: E402
import nff_ref  # noqa: E402


def render(text, W, H):
    sc = nff_ref.parse_nff(text)
    with np.errstate(all='ignore'):
        return nff_ref.render(sc, W, H)


VIEW = """v
from 0 0 5
at 0 0 0
up 0 1 0
angle 40
hither 0.1
resolution 3 3
"""


class Camera(unittest.TestCase):
    def test_directions(self):
        sc = nff_ref.parse_nff("v\nfrom 0 0 0\nat 0 0 -1\nup 0 1 0\nangle 90\n"
                               "hither 0\nresolution 4 2\n")
        d = nff_ref.camera_rays(sc, 4, 2).reshape(2, 4, 3)
        # pixel (0,0): centre (0.5, 0.5) -> w + (-0.75*1*2) u + (0.5*1) v
        e = np.array([-1.5, 0.5, -1.0])
        np.testing.assert_allclose(d[0, 0], e / np.linalg.norm(e), atol=1e-15)
        e = np.array([0.5, -0.5, -1.0])   # pixel (2,1): x = 2.5, y = 1.5
        np.testing.assert_allclose(d[1, 2], e / np.linalg.norm(e), atol=1e-15)

    def test_hither_hides_near_surface(self):
        # sphere surface at distance 4 from the eye; hither 4.5 hides the
        # front, the eye ray sees the sphere's inside (back) at distance 6.
        sc = VIEW.replace('hither 0.1', 'hither 4.5') + \
            "b 0 0 0\nl 0 0 0\nf 1 1 1 1 0 1 0 1\ns 0 0 0 1\n"
        img = render(sc, 3, 3)
        # back point (0,0,-1), inward-facing N = (0,0,1), light at centre:
        # L = (0,0,1), N.L = 1 -> A*Kd*C + E*Kd*C = 0.5 + 0.5
        np.testing.assert_allclose(img[1, 1], [1, 1, 1], atol=1e-12)


class Shading(unittest.TestCase):
    def test_diffuse_sphere_with_highlight_and_mirror(self):
        # centre pixel of a 3x3 image looks straight down -z at (0,0,1).
        s60, c60 = math.sin(math.radians(60)), 0.5
        light = np.array([0, 0, 1]) + 10 * np.array([s60, 0, c60])
        sc = VIEW + "b 0.1 0.2 0.3\nl %r %r %r\nf 1 0.5 0.25 0.8 0.3 10 0 1\ns 0 0 0 1\n" \
            % tuple(light)
        img = render(sc, 3, 3)
        C, bg = np.array([1, 0.5, 0.25]), np.array([0.1, 0.2, 0.3])
        A = E = math.sqrt(1) / 2
        ndl, rv = c60, c60          # R = (-sin60, 0, cos60), V = (0,0,1)
        want = A * 0.8 * C + E * (0.8 * C * ndl + 0.3 * rv ** 10) + 0.3 * bg
        np.testing.assert_allclose(img[1, 1], want, atol=1e-12)
        # corner pixels miss the sphere (tan20 * 5 > 1): background
        np.testing.assert_allclose(img[0, 0], bg, atol=0)

    def test_background_and_no_lights(self):
        img = render(VIEW + "b 0.25 0.5 0.75\nf 1 1 1 1 0 1 0 1\ns 0 0 -100 1\n", 5, 4)
        self.assertEqual(img.shape, (4, 5, 3))
        np.testing.assert_array_equal(img, np.broadcast_to([0.25, 0.5, 0.75], img.shape))
        img = render(VIEW + "f 1 1 1 1 0 1 0 1\ns 0 0 0 1\n", 3, 3)
        np.testing.assert_array_equal(img, 0)   # no lights: A = 0, black bg

    def test_light_intensity_rule(self):
        # 4 lights behind the surface (N.L <= 0): only ambient sqrt(4)/8 shows
        sc = VIEW + "l 0 0 -10\nl 1 0 -10\nl 0 1 -10\nl 1 1 -10\n" \
            "f 1 1 1 1 0 1 0 1\np 4\n-9 -9 0\n9 -9 0\n9 9 0\n-9 9 0\n"
        np.testing.assert_allclose(render(sc, 3, 3)[1, 1], [0.25] * 3, atol=1e-15)


class RayTree(unittest.TestCase):
    MIRRORS = """v
from 0 0 1
at 0 0 0
up 0 1 0
angle 30
hither 0
resolution 3 3
l 0 0 1
f 1 1 1 1 KS 1 0 1
p 4
-9 -9 0
9 -9 0
9 9 0
-9 9 0
p 4
-9 -9 2
-9 9 2
9 9 2
9 -9 2
"""

    def test_depth_limit(self):
        # Eye ray bounces between two facing mirrors; every hit sees L = N = V:
        # local = A + E*(Kd + Ks) = 0.5 + 0.5*1.5; depths 1..5 weigh Ks^(d-1).
        img = render(self.MIRRORS.replace('KS', '0.5'), 3, 3)
        want = 1.25 * sum(0.5 ** i for i in range(5))
        np.testing.assert_allclose(img[1, 1], [want] * 3, atol=1e-12)

    def test_weight_threshold(self):
        # Ks = 0.1: weight 0.001 < 1/512, so depth 4 is never spawned
        img = render(self.MIRRORS.replace('KS', '0.1'), 3, 3)
        np.testing.assert_allclose(img[1, 1], [1.05 * 1.11] * 3, atol=1e-12)

    def test_refraction_straight_through(self):
        # normal incidence on a glass sphere: undeviated, weight T per surface
        img = render(VIEW + "b 0.4 0.8 1\nf 1 1 1 0 0 1 0.5 1.5\ns 0 0 0 1\n", 3, 3)
        np.testing.assert_allclose(img[1, 1], 0.25 * np.array([0.4, 0.8, 1]), atol=1e-12)

    def test_total_internal_reflection(self):
        # Glass prism: the eye ray enters the top face normally, meets the 45
        # degree face from inside (> critical angle 41.8 for n = 1.5), is
        # totally reflected to +x with the same weight T and leaves normally.
        prism = """f 1 1 1 0 0 1 0.5 1.5
p 4\n-1 -1 1\n1 -1 1\n1 1 1\n-1 1 1
p 4\n1 -1 1\n1 -1 -1\n1 1 -1\n1 1 1
p 4\n-1 -1 1\n-1 1 1\n1 1 -1\n1 -1 -1
p 3\n-1 -1 1\n1 -1 -1\n1 -1 1
p 3\n-1 1 1\n1 1 1\n1 1 -1
"""
        img = render(VIEW + "b 0.4 0.8 1\n" + prism, 3, 3)
        np.testing.assert_allclose(img[1, 1], 0.125 * np.array([0.4, 0.8, 1]), atol=1e-12)
        self.assertEqual(nff_ref.fresnel(np.array([0.5 ** 0.5]), np.array([1.5]))[0], 1.0)


class Fresnel(unittest.TestCase):
    def test_normal_incidence(self):
        for n in (1.1, 1.5, 2.4):
            r = ((n - 1) / (n + 1)) ** 2
            f = nff_ref.fresnel(np.array([-1.0, 1.0]), np.array([n, n]))
            np.testing.assert_allclose(f, [r, r], rtol=1e-14)

    def test_critical_angle(self):
        n = 1.5
        crit = math.asin(1 / n)
        inside = nff_ref.fresnel(np.array([math.cos(crit - 1e-3)]), np.array([n]))
        beyond = nff_ref.fresnel(np.array([math.cos(crit + 1e-3)]), np.array([n]))
        self.assertLess(inside[0], 1.0)
        self.assertEqual(beyond[0], 1.0)

    def test_slab_shadow(self):
        # Glass box (closed, outward CCW faces) between a floor point and the
        # light straight above: t_p = (1 - r)^2 at normal incidence.
        box = """f 1 1 1 0 0 1 0.9 1.5
p 4\n-1 -1 5\n1 -1 5\n1 1 5\n-1 1 5
p 4\n-1 -1 4\n-1 1 4\n1 1 4\n1 -1 4
p 4\n-1 -1 4\n1 -1 4\n1 -1 5\n-1 -1 5
p 4\n1 1 4\n-1 1 4\n-1 1 5\n1 1 5
p 4\n1 -1 4\n1 1 4\n1 1 5\n1 -1 5
p 4\n-1 1 4\n-1 -1 4\n-1 -1 5\n-1 1 5
"""
        scene = """v
from 5 0 1
at 0 0 0
up 0 0 1
angle 30
hither 0
resolution 3 3
l 0 0 10
f 0.2 0.6 1 1 0 1 0 1
p 4
-9 -9 0
9 -9 0
9 9 0
-9 9 0
""" + box
        sc = nff_ref.parse_nff(scene)
        r = 0.04
        with np.errstate(all='ignore'):
            tp = nff_ref.transmittance(sc, np.array([[0.0, 0, 1e-9]]),
                                       np.array([[0.0, 0, 1]]), np.array([10.0]))
            img = nff_ref.render(sc, 3, 3)
        np.testing.assert_allclose(tp, [(1 - r) ** 2], rtol=1e-14)
        C = np.array([0.2, 0.6, 1])
        np.testing.assert_allclose(img[1, 1], 0.5 * C + 0.5 * C * (1 - r) ** 2, atol=1e-12)
        # an opaque occluder instead: t_p = 0
        sc = nff_ref.parse_nff(scene + "f 1 1 1 1 0 1 0 1\ns 0 0 7 0.5\n")
        with np.errstate(all='ignore'):
            img = nff_ref.render(sc, 3, 3)
        np.testing.assert_allclose(img[1, 1], 0.5 * C, atol=1e-12)


class Geometry(unittest.TestCase):
    def test_concave_polygon(self):
        # "U" shape, CCW seen from +z; the notch x in (1,2), y in (1,3) is outside
        sc = nff_ref.parse_nff("v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 30\n"
                               "f 1 1 1 1 0 1 0 1\np 8\n0 0 0\n3 0 0\n3 3 0\n2 3 0\n"
                               "2 1 0\n1 1 0\n1 3 0\n0 3 0\n")
        g = sc.groups[0]
        pts = {(0.5, 2): True, (1.5, 2): False, (2.5, 2.5): True, (1.5, 0.5): True,
               (4, 1): False, (1.5, 2.99): False, (0.01, 0.01): True, (-0.1, 1): False}
        O = np.array([[x, y, 1.0] for x, y in pts])
        D = np.tile([0.0, 0, -1], (len(O), 1))
        with np.errstate(all='ignore'):
            (t, c), = g.roots(O, D, 0, 1)
        np.testing.assert_array_equal(~np.isnan(t[:, 0]), list(pts.values()))
        np.testing.assert_allclose(t[~np.isnan(t)], 1.0)
        np.testing.assert_allclose(c[:, 0], -1.0)   # ray enters through the front

    def test_cone_and_sphere_roots(self):
        rng = np.random.default_rng(1)
        sc = nff_ref.parse_nff("v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 30\n"
                               "f 1 1 1 1 0 1 0 1\nc 0.1 -0.2 0.3 0.7 0.5 0.8 -0.4 0.2\n"
                               "s 0.2 0.1 0 0.6\n")
        O = rng.normal(size=(4000, 3)) * 3
        D = nff_ref.normalize(rng.normal(size=(4000, 3)) * 0.3 - O)
        B, A = np.array([0.1, -0.2, 0.3]), np.array([0.5, 0.8, -0.4])
        for g in sc.groups:
            with np.errstate(all='ignore'):
                roots = g.roots(O, D, 0, 1)
            n_hits = 0
            for t, c in roots:
                h = ~np.isnan(t[:, 0])
                n_hits += h.sum()
                P = O[h] + t[h, 0:1] * D[h]
                k = np.zeros(h.sum(), int)
                Ng, _ = g.geometry(P, k)
                np.testing.assert_allclose(c[h, 0], nff_ref.dot(D[h], Ng), atol=1e-9)
                if isinstance(g, nff_ref.Cones):
                    a = (A - B) / np.linalg.norm(A - B)
                    s = (P - B) @ a
                    r = 0.7 + (0.2 - 0.7) * s / np.linalg.norm(A - B)
                    perp = np.linalg.norm((P - B) - s[:, None] * a, axis=1)
                    np.testing.assert_allclose(perp, r, atol=1e-9)
                    self.assertTrue(((s >= 0) & (s <= np.linalg.norm(A - B))).all())
                    # outward normal: perpendicular to the cone's generator
                    self.assertTrue(np.all(nff_ref.dot(Ng, (P - B) - s[:, None] * a) > 0))
                else:
                    np.testing.assert_allclose(np.linalg.norm(P - [0.2, 0.1, 0], axis=1),
                                               0.6, atol=1e-9)
            self.assertGreater(n_hits, 100)

    def test_patch_normal_interpolation(self):
        # pp square, fan triangles (0,1,2) and (0,2,3); normals given per vertex
        sc = nff_ref.parse_nff("v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 30\n"
                               "f 1 1 1 1 0 1 0 1\npp 4\n0 0 0 0 0 1\n1 0 0 1 0 1\n"
                               "1 1 0 0 1 1\n0 1 0 0 0 1\n")
        g = sc.groups[0]
        P = np.array([[0.5, 0.25, 0], [0.25, 0.5, 0]])
        Ng, Ns = g.geometry(P, np.zeros(2, int))
        np.testing.assert_allclose(Ng, [[0, 0, 1]] * 2)
        # first point in triangle (0,1,2): bary (0.5, 0.25, 0.25)
        n1 = 0.5 * np.array([0, 0, 1]) + 0.25 * np.array([1, 0, 1]) + 0.25 * np.array([0, 1, 1])
        # second in (0,2,3): bary (0.5, 0.25, 0.25) for vertices 0, 2, 3
        n2 = 0.5 * np.array([0, 0, 1]) + 0.25 * np.array([0, 1, 1]) + 0.25 * np.array([0, 0, 1])
        np.testing.assert_allclose(Ns[0], n1 / np.linalg.norm(n1), atol=1e-15)
        np.testing.assert_allclose(Ns[1], n2 / np.linalg.norm(n2), atol=1e-15)


def write_exr(path, img, zip_half):
    """Minimal scanline EXR writer (FLOAT/NONE or HALF/ZIP) for reader tests;
    the reader was also checked by hand against files written by libOpenEXR."""
    import struct
    import zlib
    H, W, _ = img.shape
    ptype, dt, comp, lines = (1, '<f2', 3, 16) if zip_half else (2, '<f4', 0, 1)

    def attr(name, typ, val):
        return name.encode() + b'\0' + typ.encode() + b'\0' + struct.pack('<i', len(val)) + val
    ch = b''.join(c.encode() + b'\0' + struct.pack('<iB3xii', ptype, 0, 1, 1) for c in 'BGR')
    box = struct.pack('<iiii', 0, 0, W - 1, H - 1)
    head = (struct.pack('<ii', 20000630, 2) + attr('channels', 'chlist', ch + b'\0')
            + attr('compression', 'compression', bytes([comp]))
            + attr('dataWindow', 'box2i', box) + attr('displayWindow', 'box2i', box)
            + attr('lineOrder', 'lineOrder', b'\0')
            + attr('pixelAspectRatio', 'float', struct.pack('<f', 1))
            + attr('screenWindowCenter', 'v2f', struct.pack('<ff', 0, 0))
            + attr('screenWindowWidth', 'float', struct.pack('<f', 1)) + b'\0')
    chunks = []
    for y in range(0, H, lines):
        rows = img[y:y + lines]
        raw = b''.join(rows[r, :, c].astype(dt).tobytes()
                       for r in range(len(rows)) for c in (2, 1, 0))
        if zip_half:
            b = np.frombuffer(raw, np.uint8)
            t = np.concatenate([b[0::2], b[1::2]]).astype(np.int64)
            d = t.copy()
            d[1:] = (t[1:] - t[:-1] + 128) & 0xFF
            z = zlib.compress(d.astype(np.uint8).tobytes())
            raw = z if len(z) < len(raw) else raw   # as OpenEXR does
        chunks.append(struct.pack('<ii', y, len(raw)) + raw)
    offs, pos = [], len(head) + 8 * len(chunks)
    for c in chunks:
        offs.append(pos)
        pos += len(c)
    with open(path, 'wb') as f:
        f.write(head + struct.pack('<%dQ' % len(offs), *offs) + b''.join(chunks))


class Files(unittest.TestCase):
    def test_exr_reader(self):
        img = np.random.default_rng(3).random((37, 11, 3)) * 4 - 1
        with tempfile.TemporaryDirectory() as d:
            p = os.path.join(d, 'a.exr')
            write_exr(p, img, False)
            np.testing.assert_allclose(compare.read_exr(p), img.astype('<f4'), rtol=0)
            smooth = np.linspace(0, 1, img.size).reshape(img.shape)  # compressible
            write_exr(p, smooth, True)
            self.assertLess(os.path.getsize(p), smooth.size * 2)
            np.testing.assert_allclose(compare.read_exr(p), smooth.astype('<f2'), rtol=0)

    def test_pfm_roundtrip_and_compare(self):
        img = np.random.default_rng(2).random((5, 7, 3))
        with tempfile.TemporaryDirectory() as d:
            p = os.path.join(d, 'a.pfm')
            nff_ref.write_pfm(p, img)
            np.testing.assert_allclose(nff_ref.read_pfm(p), img, atol=1e-7)
            q = os.path.join(d, 'b.png')
            nff_ref.save(q, img)
            c = os.path.join(d, 'c.npy')

            def run(*args):
                with contextlib.redirect_stdout(io.StringIO()):
                    return compare.main(list(args))
            self.assertEqual(run(p, q, '--tol', '0'), 0)
            img[0, 0] += 3 / 255            # one pixel of 35 off by 3/255
            np.save(c, img)
            self.assertEqual(run(c, q, '--tol', '2/255', '--max-bad-fraction', '0.01'), 1)
            self.assertEqual(run(c, q, '--tol', '2/255', '--max-bad-fraction', '0.03'), 0)
            self.assertEqual(run(c, q, '--tol', '3/255', '--max-bad-fraction', '0'), 0)
            self.assertEqual(run(c, p, '--tol', '2/255', '--max-bad-fraction', '0'), 1)


if __name__ == '__main__':
    unittest.main()

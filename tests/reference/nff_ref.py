#!/usr/bin/env python3
"""Independent reference ray tracer for NFF scenes, exactly per shared/SHADING.md.

Written without looking at the C++ renderer, so the test suite can compare the
two. One sample per pixel (pixel centre), float64 throughout, numpy vectorised
over rays (all rays of one ray-tree level at once, looping over object chunks).

    python3 nff_ref.py SCENE.nff [--size WxH] -o OUT.npy|OUT.pfm|OUT.png

Output: linear RGB, H x W x 3, top row first (.npy float64, .pfm float32,
.png 8-bit round(255*clamp(v,0,1)) for viewing only).
"""
import argparse
import math
import sys

import numpy as np

MAX_DEPTH = 5             # SHADING.md "Ray tree": primary ray has depth 1
MIN_WEIGHT = 1.0 / 512.0  # branch product threshold for spawning a ray
EPS_REL = 1e-7            # origin offset = EPS_REL * scene bounding-box diagonal
PAIRS = 1 << 20           # max ray x object pairs in one numpy array


class SceneError(Exception):
    pass


def dot(a, b):
    return np.einsum('...k,...k->...', a, b)


def normalize(a):
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


# ---------------------------------------------------------------- primitives
# Every group offers
#   roots(O, D, j0, j1) -> list of (t, c), each (N, m) for objects j0..j1-1:
#       ray parameters of the surface crossings (nan if none) and
#       c = D . outward geometric normal there (c < 0: the ray enters);
#   geometry(P, k) -> (Ng, Ns): outward unit geometric normal and the
#       (unflipped) unit shading normal at hit points P on objects k.

class Spheres:
    def __init__(self, items):
        self.C = np.array([c for c, r, m in items], float).reshape(-1, 3)
        self.r = np.array([r for c, r, m in items], float)
        self.mat = np.array([m for c, r, m in items], int)
        self.M = len(items)

    def bounds(self):
        return np.vstack([self.C - self.r[:, None], self.C + self.r[:, None]])

    def roots(self, O, D, j0, j1):
        C, r = self.C[j0:j1], self.r[j0:j1]
        oc = O[:, None, :] - C[None]
        b = np.einsum('nmk,nk->nm', oc, D)
        perp = oc - b[..., None] * D[:, None, :]
        disc = r * r - dot(perp, perp)        # = b^2 - c0, without cancellation
        c0 = dot(oc, oc) - r * r
        q = -b - np.copysign(np.sqrt(disc), b)  # stable quadratic (|D| = 1)
        t1, t2 = q, c0 / q
        return [(t1, (b + t1) / r), (t2, (b + t2) / r)]

    def geometry(self, P, k):
        n = normalize(P - self.C[k])
        return n, n


class Cones:
    """Open cone/cylinder: radius rb at base B, ra at apex A, no caps."""

    def __init__(self, items):
        self.B = np.array([b for b, rb, a, ra, m in items], float).reshape(-1, 3)
        A = np.array([a for b, rb, a, ra, m in items], float).reshape(-1, 3)
        self.rb = np.array([rb for b, rb, a, ra, m in items], float)
        self.ra = np.array([ra for b, rb, a, ra, m in items], float)
        self.mat = np.array([m for b, rb, a, ra, m in items], int)
        self.H = np.linalg.norm(A - self.B, axis=1)
        self.a = (A - self.B) / self.H[:, None]
        self.k = (self.ra - self.rb) / self.H   # dr/ds along the axis
        self.A = A
        self.M = len(items)

    def bounds(self):
        r = np.maximum(self.rb, self.ra)[:, None]
        return np.vstack([self.B - r, self.B + r, self.A - r, self.A + r])

    def roots(self, O, D, j0, j1):
        B, a = self.B[j0:j1], self.a[j0:j1]
        rb, k, H = self.rb[j0:j1], self.k[j0:j1], self.H[j0:j1]
        dl = O[:, None, :] - B[None]
        da = D @ a.T                                   # (N, m)
        dla = dot(dl, a[None])
        Dp = D[:, None, :] - da[..., None] * a[None]   # D across the axis
        dlp = dl - dla[..., None] * a[None]
        rr = rb + k * dla
        A2 = dot(Dp, Dp) - k * k * da * da
        hb = dot(dlp, Dp) - k * rr * da
        C2 = dot(dlp, dlp) - rr * rr
        q = -(hb + np.copysign(np.sqrt(hb * hb - A2 * C2), hb))
        out = []
        # A2 == 0 gives q/A2 = inf and C2/q = the single linear root.
        for t in (q / A2, C2 / q):
            s = dla + t * da
            t = np.where((s >= 0) & (s <= H), t, np.nan)
            r = rb + k * s
            dperp = dot(dlp, Dp) + t * dot(Dp, Dp)     # D . (radial vector)
            c = (dperp / r - k * da) / np.sqrt(1 + k * k)
            out.append((t, c))
        return out

    def geometry(self, P, k):
        dl = P - self.B[k]
        a = self.a[k]
        perp = dl - dot(dl, a)[:, None] * a
        n = normalize(normalize(perp) - self.k[k][:, None] * a)
        return n, n


class Polygons:
    """Planar polygons with n vertices each (possibly concave), optionally with
    vertex normals (NFF pp). Front (outward) side: vertices counter-clockwise."""

    def __init__(self, items):
        V = np.array([v for v, nv, m in items], float)          # (M, n, 3)
        self.mat = np.array([m for v, nv, m in items], int)
        self.Nv = (np.array([nv for v, nv, m in items], float)
                   if items[0][1] is not None else None)
        rel = V - V[:, :1]
        # Newell / area normal: its sign is the CCW (front) side.
        nrm = np.cross(rel, np.roll(rel, -1, axis=1)).sum(axis=1)
        self.N = normalize(nrm)
        self.d = dot(V, self.N[:, None, :]).mean(axis=1)
        ax = np.eye(3)[np.argmin(np.abs(self.N), axis=1)]
        self.e1 = normalize(np.cross(self.N, ax))
        self.e2 = np.cross(self.N, self.e1)
        self.o1 = dot(V[:, 0], self.e1)
        self.o2 = dot(V[:, 0], self.e2)
        self.X = dot(rel, self.e1[:, None, :])                 # (M, n) 2-D coords
        self.Y = dot(rel, self.e2[:, None, :])
        self.V = V
        self.M, self.n = V.shape[0], V.shape[1]

    def bounds(self):
        return self.V.reshape(-1, 3)

    def project(self, O, D, t, j0, j1):
        px = O @ self.e1[j0:j1].T - self.o1[j0:j1] + t * (D @ self.e1[j0:j1].T)
        py = O @ self.e2[j0:j1].T - self.o2[j0:j1] + t * (D @ self.e2[j0:j1].T)
        return px, py

    def roots(self, O, D, j0, j1):
        Nm = self.N[j0:j1]
        dn = D @ Nm.T
        t = (self.d[j0:j1] - O @ Nm.T) / dn
        px, py = self.project(O, D, t, j0, j1)
        X, Y = self.X[j0:j1], self.Y[j0:j1]
        inside = np.zeros(t.shape, bool)
        for i in range(self.n):  # even-odd crossing test
            xi, yi = X[:, i], Y[:, i]
            xj, yj = X[:, (i + 1) % self.n], Y[:, (i + 1) % self.n]
            cross = (yi > py) != (yj > py)
            xint = xi + (py - yi) * (xj - xi) / (yj - yi)
            inside ^= cross & (px < xint)
        return [(np.where(inside, t, np.nan), dn)]

    def geometry(self, P, k):
        Ng = self.N[k]
        if self.Nv is None:
            return Ng, Ng
        rel = P - self.V[k, 0]
        px, py = dot(rel, self.e1[k]), dot(rel, self.e2[k])
        X, Y = self.X[k], self.Y[k]
        # barycentrics in every fan triangle (0, i, i+1); take the one that
        # contains the point (largest minimum coordinate).
        x1, y1, x2, y2 = X[:, 1:-1], Y[:, 1:-1], X[:, 2:], Y[:, 2:]
        det = x1 * y2 - x2 * y1
        l1 = (px[:, None] * y2 - x2 * py[:, None]) / det
        l2 = (x1 * py[:, None] - px[:, None] * y1) / det
        l0 = 1 - l1 - l2
        best = np.argmax(np.minimum(np.minimum(l0, l1), l2), axis=1)
        idx = np.arange(len(k))
        b0, b1, b2 = l0[idx, best], l1[idx, best], l2[idx, best]
        Nv = self.Nv[k]
        ns = (b0[:, None] * Nv[:, 0] + b1[:, None] * Nv[idx, best + 1]
              + b2[:, None] * Nv[idx, best + 2])
        ln = np.linalg.norm(ns, axis=1)
        ok = ln > 1e-12
        ns = np.where(ok[:, None], ns / np.where(ok, ln, 1)[:, None], Ng)
        return Ng, ns


# ---------------------------------------------------------------- scene

class Scene:
    def __init__(self):
        self.eye = self.at = self.up = None
        self.angle, self.hither, self.res = 45.0, 0.0, (256, 256)
        self.bg = np.zeros(3)
        self.lights = []     # (position, colour or None)
        self.mats = []       # (C(3), Kd, Ks, Shine, T, ior)
        self.groups = []

    def finish(self, spheres, cones, polys, order):
        # order[kind]: file position of each object (ties between coincident
        # surfaces go to the object defined first, see nearest()).
        if self.eye is None:
            raise SceneError('no viewpoint (v) entity')
        if spheres:
            self.groups.append(Spheres(spheres))
            self.groups[-1].order = np.array(order['s'], np.int64)
        if cones:
            self.groups.append(Cones(cones))
            self.groups[-1].order = np.array(order['c'], np.int64)
        by_kind = {}
        ord_by_kind = {}
        for (v, nv, m), o in zip(polys, order['p']):
            rel = np.array(v) - v[0]
            area = np.linalg.norm(np.cross(rel, np.roll(rel, -1, axis=0)).sum(axis=0))
            if not area > 1e-14 * np.abs(rel).max() ** 2:
                continue   # degenerate (zero-area) polygon: never hit
            by_kind.setdefault((len(v), nv is not None), []).append((v, nv, m))
            ord_by_kind.setdefault((len(v), nv is not None), []).append(o)
        for key in sorted(by_kind):
            self.groups.append(Polygons(by_kind[key]))
            self.groups[-1].order = np.array(ord_by_kind[key], np.int64)
        L = len(self.lights)
        default = math.sqrt(L) / (2 * L) if L else 0.0
        self.ambient = default
        self.light_pos = np.array([p for p, c in self.lights], float).reshape(-1, 3)
        self.light_col = np.array([c if c is not None else [default] * 3
                                   for p, c in self.lights], float).reshape(-1, 3)
        m = self.mats or [(np.ones(3), 0, 0, 0, 0, 1)]
        self.C = np.array([x[0] for x in m], float)
        self.kd, self.ks, self.shine, self.T, self.ior = (
            np.array([x[i] for x in m], float) for i in range(1, 6))
        pts = [g.bounds() for g in self.groups] or [np.zeros((1, 3))]
        pts = np.vstack(pts)
        diag = np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))
        self.eps = EPS_REL * max(diag, 1e-12)


def parse_nff(text, name='scene'):
    toks = []   # (token, line number)
    for ln, line in enumerate(text.splitlines(), 1):
        toks += [(w, ln) for w in line.split('#', 1)[0].split()]
    pos = 0

    def err(msg):
        line = toks[min(pos, len(toks) - 1)][1] if toks else 0
        raise SceneError('%s:%d: %s' % (name, line, msg))

    def num():
        nonlocal pos
        if pos >= len(toks):
            err('unexpected end of file')
        try:
            v = float(toks[pos][0])
        except ValueError:
            err('expected a number, got %r' % toks[pos][0])
        pos += 1
        return v

    def isnum(i):
        try:
            float(toks[i][0])
            return True
        except (ValueError, IndexError):
            return False

    def vec(n=3):
        return [num() for _ in range(n)]

    sc = Scene()
    spheres, cones, polys = [], [], []
    order = {'s': [], 'c': [], 'p': []}
    mat = None

    def cur_mat():
        if mat is None:
            err('object before any f (material) entity')
        return mat

    while pos < len(toks):
        kw = toks[pos][0]
        pos += 1
        if kw == 'v':
            while pos < len(toks) and toks[pos][0] in (
                    'from', 'at', 'up', 'angle', 'hither', 'resolution'):
                key = toks[pos][0]
                pos += 1
                if key in ('from', 'at', 'up'):
                    setattr(sc, 'eye' if key == 'from' else key, np.array(vec()))
                elif key == 'angle':
                    sc.angle = num()
                elif key == 'hither':
                    sc.hither = num()
                else:
                    sc.res = (int(num()), int(num()))
        elif kw == 'b':
            sc.bg = np.array(vec())
        elif kw == 'l':
            p = vec()
            col = vec() if isnum(pos) else None
            sc.lights.append((p, col))
        elif kw == 'f':
            x = vec(8)
            if x[6] > 0 and x[7] <= 0:
                err('transparent material needs an index of refraction > 0')
            sc.mats.append((x[0:3], x[3], x[4], x[5], x[6], x[7]))
            mat = len(sc.mats) - 1
        elif kw == 's':
            c, r = vec(), num()
            if r <= 0:
                err('sphere radius must be positive (inside-only spheres unsupported)')
            spheres.append((c, r, cur_mat()))
            order['s'].append(len(spheres) + len(cones) + len(polys))
        elif kw == 'c':
            b, rb, a, ra = vec(), num(), vec(), num()
            if rb < 0 or ra < 0 or rb + ra == 0:
                err('cone radii must be >= 0 and not both 0 (inside-only unsupported)')
            if b == a:
                err('cone base and apex coincide')
            cones.append((b, rb, a, ra, cur_mat()))
            order['c'].append(len(spheres) + len(cones) + len(polys))
        elif kw in ('p', 'pp'):
            n = int(num())
            if n < 3:
                err('polygon needs at least 3 vertices')
            vs, ns = [], []
            for _ in range(n):
                vs.append(vec())
                if kw == 'pp':
                    ns.append(vec())
            polys.append((vs, ns if kw == 'pp' else None, cur_mat()))
            order['p'].append(len(spheres) + len(cones) + len(polys))
        else:
            err('unknown entity %r' % kw)
    sc.finish(spheres, cones, polys, order)
    return sc


# ---------------------------------------------------------------- tracing

def chunks(g, N):
    step = max(1, PAIRS // max(N, 1))
    for j0 in range(0, g.M, step):
        yield j0, min(g.M, j0 + step)


# Crossings closer than this relative distance to the nearest one count as
# coincident surfaces (e.g. SPD teapot s1's doubled spout triangles); among
# them the object defined first in the file wins, so the answer does not
# depend on rounding.
TIE_REL = 1e-9


def nearest(sc, O, D, tmin):
    """Nearest crossing with t > tmin: (t, group index or -1, object index)."""
    N = len(O)
    idx = np.arange(N)
    best_t = np.full(N, np.inf)
    for g in sc.groups:                       # pass 1: the nearest distance
        for j0, j1 in chunks(g, N):
            for t, _ in g.roots(O, D, j0, j1):
                t = np.where(t > tmin[:, None], t, np.inf)
                best_t = np.minimum(best_t, t.min(axis=1))
    band = best_t * (1 + TIE_REL)
    big = np.iinfo(np.int64).max
    best_o = np.full(N, big)
    best_g = np.full(N, -1)
    best_k = np.zeros(N, int)
    out_t = np.full(N, np.inf)
    for gi, g in enumerate(sc.groups):        # pass 2: first-defined in the band
        for j0, j1 in chunks(g, N):
            for t, _ in g.roots(O, D, j0, j1):
                t = np.where(t > tmin[:, None], t, np.inf)
                near = (t <= band[:, None]) & np.isfinite(t)
                o = np.where(near, g.order[j0:j1][None, :], big)
                j = np.argmin(o, axis=1)
                oj = o[idx, j]
                better = oj < best_o
                best_o[better] = oj[better]
                best_g[better] = gi
                best_k[better] = j[better] + j0
                out_t[better] = t[idx, j][better]
    return out_t, best_g, best_k


def fresnel(c, ior):
    """Unpolarised Fresnel reflectance for a crossing with c = D . n_outward
    (c < 0: entering, from 1 into ior); 1 beyond the critical angle."""
    ent = c < 0
    n1 = np.where(ent, 1.0, ior)
    n2 = np.where(ent, ior, 1.0)
    ci = np.abs(c)
    s2 = (n1 / n2) ** 2 * (1 - ci * ci)
    ct = np.sqrt(np.maximum(0.0, 1 - s2))
    rs = ((n1 * ci - n2 * ct) / (n1 * ci + n2 * ct)) ** 2
    rp = ((n1 * ct - n2 * ci) / (n1 * ct + n2 * ci)) ** 2
    return np.where(s2 >= 1, 1.0, 0.5 * (rs + rp))


def transmittance(sc, O, D, tmax):
    """Eqs (2)(3): fraction of light along the segment O + tD, 0 < t < tmax."""
    f = np.ones(len(O))
    for g in sc.groups:
        for j0, j1 in chunks(g, len(O)):
            m = g.mat[j0:j1]
            T, ior = sc.T[m], sc.ior[m]
            for t, c in g.roots(O, D, j0, j1):
                crossed = (t > 0) & (t < tmax[:, None])
                fac = np.where(T > 0, 1 - fresnel(c, np.where(T > 0, ior, 1.0)), 0.0)
                f *= np.prod(np.where(crossed, fac, 1.0), axis=1)
    return f


def camera_rays(sc, W, H):
    w = normalize(sc.at - sc.eye)
    u = normalize(np.cross(w, sc.up))
    v = np.cross(u, w)
    th = math.tan(math.radians(sc.angle) / 2)
    x, y = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    d = (w + ((2 * x / W - 1) * th * (W / H))[..., None] * u
         + ((1 - 2 * y / H) * th)[..., None] * v)
    return normalize(d.reshape(-1, 3))


def offset(P, Ngf, Dn, eps):
    """Move P by eps along the geometric normal, to the side Dn goes."""
    s = np.where(dot(Ngf, Dn) >= 0, 1.0, -1.0)
    return P + (eps * s)[:, None] * Ngf


def render(sc, W, H):
    D = camera_rays(sc, W, H)
    N = len(D)
    O = np.tile(sc.eye, (N, 1))
    w = np.ones(N)                           # branch product = contribution weight
    pix = np.arange(N)
    tmin = np.full(N, max(sc.hither, 0.0))   # hither applies to eye rays only
    img = np.zeros((N, 3))
    depth = 1
    while len(pix):
        t, g, k = nearest(sc, O, D, tmin)
        miss = g < 0
        np.add.at(img, pix[miss], w[miss, None] * sc.bg)
        hit = ~miss
        O, D, t, g, k, w, pix = O[hit], D[hit], t[hit], g[hit], k[hit], w[hit], pix[hit]
        n = len(pix)
        if n == 0:
            break
        P = O + t[:, None] * D
        Ng = np.zeros((n, 3))
        Ns = np.zeros((n, 3))
        m = np.zeros(n, int)
        for gi, grp in enumerate(sc.groups):
            s = g == gi
            if s.any():
                Ng[s], Ns[s] = grp.geometry(P[s], k[s])
                m[s] = grp.mat[k[s]]
        entering = dot(D, Ng) < 0                  # arriving from the outward side
        Ngf = np.where(entering[:, None], Ng, -Ng)  # geometric normal facing the ray
        Ns = np.where((dot(D, Ns) > 0)[:, None], -Ns, Ns)
        C, kd, ks, shine, T, ior = (sc.C[m], sc.kd[m], sc.ks[m], sc.shine[m],
                                    sc.T[m], sc.ior[m])
        V = -D
        col = sc.ambient * kd[:, None] * C
        # direct light: batch all (hit, light) pairs that face the light
        for j in range(len(sc.light_pos)):
            Lv = sc.light_pos[j] - P
            dist = np.linalg.norm(Lv, axis=1)
            L = Lv / dist[:, None]
            ndl = dot(Ns, L)
            a = np.nonzero(ndl > 0)[0]
            if len(a) == 0:
                continue
            tp = transmittance(sc, offset(P[a], Ngf[a], L[a], sc.eps), L[a], dist[a])
            R = 2 * ndl[a, None] * Ns[a] - L[a]
            hl = ks[a] * np.maximum(0.0, dot(R, V[a])) ** shine[a]
            term = kd[a, None] * C[a] * ndl[a, None] + hl[:, None]
            col[a] += sc.light_col[j] * (tp[:, None] * term)
        np.add.at(img, pix, w[:, None] * col)
        # children: mirror (Ks) and refracted (T) rays
        if depth + 1 > MAX_DEPTH:
            break
        Rd = D - 2 * dot(D, Ns)[:, None] * Ns
        kids = []
        wr = w * ks
        s = (ks > 0) & (wr >= MIN_WEIGHT)
        kids.append((offset(P[s], Ngf[s], Rd[s], sc.eps), Rd[s], wr[s], pix[s]))
        wt = w * T
        s = (T > 0) & (wt >= MIN_WEIGHT)
        eta = np.where(entering, 1 / ior, ior)[s]
        ci = -dot(D[s], Ns[s])
        kk = 1 - eta * eta * (1 - ci * ci)
        tir = kk < 0
        Dt = eta[:, None] * D[s] + (eta * ci - np.sqrt(np.maximum(kk, 0)))[:, None] * Ns[s]
        Dt = np.where(tir[:, None], Rd[s], normalize(Dt))
        kids.append((offset(P[s], Ngf[s], Dt, sc.eps), Dt, wt[s], pix[s]))
        O, D, w, pix = (np.concatenate(x) for x in zip(*kids))
        tmin = np.zeros(len(pix))  # secondary rays: origins are offset instead
        depth += 1
    return img.reshape(H, W, 3)


# ---------------------------------------------------------------- files

def write_pfm(path, img):
    H, W, _ = img.shape
    with open(path, 'wb') as f:
        f.write(b'PF\n%d %d\n-1.0\n' % (W, H))
        f.write(np.ascontiguousarray(img[::-1], '<f4').tobytes())  # bottom row first


def read_pfm(path):
    with open(path, 'rb') as f:
        data = f.read()
    parts, p = [], 0
    while len(parts) < 4:   # 'PF', W, H, scale separated by whitespace
        while data[p:p + 1].isspace():
            p += 1
        q = p
        while not data[q:q + 1].isspace():
            q += 1
        parts.append(data[p:q])
        p = q
    p += 1
    ch = {b'PF': 3, b'Pf': 1}[parts[0]]
    W, H, scale = int(parts[1]), int(parts[2]), float(parts[3])
    a = np.frombuffer(data, '<f4' if scale < 0 else '>f4', W * H * ch, p)
    a = a.reshape(H, W, ch)[::-1].astype(np.float64)
    return np.repeat(a, 3, axis=2) if ch == 1 else a


def save(path, img):
    if path.endswith('.npy'):
        np.save(path, img)
    elif path.endswith('.pfm'):
        write_pfm(path, img)
    elif path.endswith('.png'):
        from PIL import Image
        q = np.floor(255 * np.clip(img, 0, 1) + 0.5).astype(np.uint8)
        Image.fromarray(q, 'RGB').save(path)
    else:
        raise SystemExit('output must end in .npy, .pfm or .png: ' + path)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('scene')
    ap.add_argument('--size', help='WxH, overrides the NFF resolution')
    ap.add_argument('-o', '--output', required=True)
    args = ap.parse_args(argv)
    try:
        with open(args.scene) as f:
            sc = parse_nff(f.read(), args.scene)
    except (OSError, SceneError) as e:
        print('nff_ref: %s' % e, file=sys.stderr)
        return 2
    W, H = sc.res
    if args.size:
        W, H = (int(x) for x in args.size.lower().split('x'))
    with np.errstate(all='ignore'):
        img = render(sc, W, H)
    save(args.output, img)
    return 0


if __name__ == '__main__':
    sys.exit(main())

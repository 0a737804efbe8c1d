#!/usr/bin/env python3
"""Compare two renders pixel by pixel.

    python3 compare.py A B [--tol 2/255] [--max-bad-fraction 0.005] [--diff D.png]

A and B: .npy / .pfm (float, e.g. from nff_ref.py), .exr (float; scanline,
compression NONE/RLE/ZIPS/ZIP, HALF/FLOAT/UINT channels) or .png (8-bit).
If either side is 8-bit, the float side is quantised like SHADING.md "Output"
(round(255 * clamp(v, 0, 1))) and 8-bit values are compared; otherwise the
linear float values are compared directly. A pixel is bad if any channel
differs by more than tol. Prints max error, RMS error and the bad fraction;
exits 1 if the bad fraction exceeds the limit, 2 on unusable input.
"""
import argparse
import os
import struct
import sys
import zlib
from fractions import Fraction

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from nff_ref import read_pfm  # noqa: E402


# ---------------------------------------------------------------- OpenEXR

def _unpredict(raw):
    """Undo OpenEXR's ZIP/RLE byte predictor, then its half-split reordering."""
    d = np.frombuffer(raw, np.uint8).astype(np.int64) - 128
    if len(d):
        d[0] += 128
    t = (np.cumsum(d) & 0xFF).astype(np.uint8)   # t[i] = t[i-1] + raw[i] - 128
    half = (len(t) + 1) // 2
    out = np.empty(len(t), np.uint8)
    out[0::2] = t[:half]
    out[1::2] = t[half:]
    return out.tobytes()


def _unrle(data):
    out = bytearray()
    i = 0
    while i < len(data):
        n = struct.unpack_from('b', data, i)[0]
        i += 1
        if n < 0:
            out += data[i:i - n]
            i -= n
        else:
            out += data[i:i + 1] * (n + 1)
            i += 1
    return bytes(out)


def read_exr(path):
    with open(path, 'rb') as f:
        data = f.read()
    magic, version = struct.unpack_from('<ii', data, 0)
    if magic != 20000630:
        raise ValueError('%s: not an OpenEXR file' % path)
    if version & 0x1200:
        raise ValueError('%s: tiled or multi-part EXR not supported' % path)
    p, attrs = 8, {}
    while data[p] != 0:
        name_end = data.index(b'\0', p)
        type_end = data.index(b'\0', name_end + 1)
        name = data[p:name_end].decode()
        size = struct.unpack_from('<i', data, type_end + 1)[0]
        attrs[name] = data[type_end + 5:type_end + 5 + size]
        p = type_end + 5 + size
    p += 1
    chans, q, cl = [], 0, attrs['channels']
    while cl[q] != 0:
        e = cl.index(b'\0', q)
        ptype = struct.unpack_from('<i', cl, e + 1)[0]
        chans.append((cl[q:e].decode(), ptype))
        q = e + 17
    comp = attrs['compression'][0]
    x0, y0, x1, y1 = struct.unpack('<iiii', attrs['dataWindow'])
    W, H = x1 - x0 + 1, y1 - y0 + 1
    lines = {0: 1, 1: 1, 2: 1, 3: 16}.get(comp)
    if lines is None:
        raise ValueError('%s: EXR compression %d not supported (use NONE/RLE/ZIP)'
                         % (path, comp))
    dtypes = {0: '<u4', 1: '<f2', 2: '<f4'}
    nchunks = (H + lines - 1) // lines
    offsets = struct.unpack_from('<%dQ' % nchunks, data, p)
    img = {c: np.zeros((H, W)) for c, _ in chans}
    for off in offsets:
        y, size = struct.unpack_from('<ii', data, off)
        raw = data[off + 8:off + 8 + size]
        n = min(lines, y1 + 1 - y)
        expect = n * W * sum(np.dtype(dtypes[t]).itemsize for _, t in chans)
        if size < expect:   # stored compressed (else raw, as OpenEXR does)
            raw = _unpredict(zlib.decompress(raw) if comp in (2, 3) else _unrle(raw))
        q = 0
        for r in range(n):
            for c, t in chans:
                dt = np.dtype(dtypes[t])
                img[c][y - y0 + r] = np.frombuffer(raw, dt, W, q)
                q += W * dt.itemsize
    names = [c for c, _ in chans]
    pick = [next((c for c in names if c.split('.')[-1] == k), None) for k in 'RGB']
    if None in pick:
        if len(names) == 1 or 'Y' in names:
            pick = ['Y' if 'Y' in names else names[0]] * 3
        else:
            raise ValueError('%s: no R, G, B channels in %s' % (path, names))
    return np.stack([img[c] for c in pick], axis=2)


# ---------------------------------------------------------------- compare

def load(path):
    """Returns (array H x W x 3, is_8bit)."""
    low = path.lower()
    if low.endswith('.npy'):
        a = np.load(path).astype(np.float64)
        return (a if a.ndim == 3 else np.repeat(a[..., None], 3, 2)), False
    if low.endswith('.pfm'):
        return read_pfm(path), False
    if low.endswith('.exr'):
        return read_exr(path), False
    from PIL import Image
    im = Image.open(path)
    if im.mode not in ('RGB', 'RGBA', 'L', 'LA', 'P'):
        raise ValueError('%s: only 8-bit images supported, got mode %s' % (path, im.mode))
    return np.asarray(im.convert('RGB')), True


def quantise(a):
    return np.floor(255 * np.clip(a, 0, 1) + 0.5)


def compare(a, a8, b, b8, tol):
    """Per-channel error array (in [0,1] units, 8-bit steps if either is 8-bit)."""
    if a.shape != b.shape:
        raise ValueError('image sizes differ: %s vs %s' % (a.shape, b.shape))
    if a8 or b8:
        qa = a.astype(np.float64) if a8 else quantise(a)
        qb = b.astype(np.float64) if b8 else quantise(b)
        return np.abs(qa - qb) / 255.0
    return np.abs(a - b)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('a')
    ap.add_argument('b')
    ap.add_argument('--tol', default='2/255', help='per-channel tolerance, e.g. 2/255')
    ap.add_argument('--max-bad-fraction', type=float, default=0.005)
    ap.add_argument('--diff', help='write a PNG marking bad pixels in red')
    args = ap.parse_args(argv)
    tol = float(Fraction(args.tol))
    try:
        a, a8 = load(args.a)
        b, b8 = load(args.b)
        err = compare(a, a8, b, b8, tol)
    except (OSError, ValueError, KeyError, zlib.error) as e:
        print('compare: %s' % e, file=sys.stderr)
        return 2
    if not np.isfinite(err).all():
        print('compare: non-finite values', file=sys.stderr)
        return 2
    pix = err.max(axis=2)
    bad = pix > tol + 1e-9
    frac = bad.mean()
    print('max error %.6f (%.2f/255)  RMS error %.6f  bad pixels (> %.6f) %d of %d = %.4f%%'
          % (err.max(), 255 * err.max(), np.sqrt((err ** 2).mean()), tol,
             bad.sum(), bad.size, 100 * frac))
    if bad.any():
        ys, xs = np.nonzero(bad)
        print('first bad pixels (x, y):', list(zip(xs.tolist(), ys.tolist()))[:10])
    if args.diff:
        from PIL import Image
        base = b.astype(np.float64) if b8 else quantise(b)
        vis = (0.5 * base).astype(np.uint8)
        vis[bad] = (255, 0, 0)
        Image.fromarray(vis, 'RGB').save(args.diff)
    ok = frac <= args.max_bad_fraction
    print('PASS' if ok else 'FAIL: bad fraction %.4f%% > %.4f%%'
          % (100 * frac, 100 * args.max_bad_fraction))
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())

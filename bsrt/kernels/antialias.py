"""Adaptive anti-aliasing's bookkeeping, compiled (rendering/antialias.py has the rules).

``mark_rows`` marks the pixels whose 8-bit colour steps from its neighbours';
``block_samples`` decides, for each sample of each marked pixel, whether it
must be traced or can be interpolated, and interpolates those that can: per
pixel what the NumPy expressions of rendering/antialias.py did over whole
arrays in some forty passes on one thread, now one pass on every core, with
the same arithmetic in the same order (so the same bits).
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.jit import njit
from bsrt.kernels.search import first_at_least

SIDES = ((1, 0), (-1, 0), (0, 1), (0, -1))  # a pixel's four neighbours (dx, dy), in block_samples' order


@njit(cache=True, nogil=True, no_cpython_wrapper=True)
def _apart(levels_a, a, levels_b, b, contrast):
    """Do 8-bit colours levels_a[a] and levels_b[b] ((., 3) uint8 rows) differ by more than contrast in a channel?"""
    for c in range(3):
        if abs(np.int32(levels_a[a, c]) - np.int32(levels_b[b, c])) > contrast:
            return True
    return False


@njit(cache=True, nogil=True)
def mark_rows(start, stop, pixels, contrast, marked):
    """Pixel rows start..stop-1 of pixels (H, W, 3) uint8 into marked (H, W) bool: a channel's
    second difference along the row or the column (the first difference at the film's border, none
    along an axis under 2 pixels) beyond contrast levels either way."""
    h, w = pixels.shape[0], pixels.shape[1]
    for r in range(start, stop):
        for x in range(w):
            odd = False
            for c in range(3):
                p = np.int32(pixels[r, x, c])
                if h >= 2:
                    if r == 0:
                        d = np.int32(pixels[1, x, c]) - p
                    elif r == h - 1:
                        d = p - np.int32(pixels[h - 2, x, c])
                    else:
                        d = np.int32(pixels[r - 1, x, c]) - 2 * p + np.int32(pixels[r + 1, x, c])
                    odd = odd or abs(d) > contrast
                if w >= 2:
                    if x == 0:
                        d = np.int32(pixels[r, 1, c]) - p
                    elif x == w - 1:
                        d = p - np.int32(pixels[r, w - 2, c])
                    else:
                        d = np.int32(pixels[r, x - 1, c]) - 2 * p + np.int32(pixels[r, x + 1, c])
                    odd = odd or abs(d) > contrast
            marked[r, x] = odd


@njit(cache=True, nogil=True)
def block_samples(
    start,
    stop,
    marked,
    offset,
    width,
    height,
    linear,
    levels,
    hits,
    decoded,
    contrast,
    first,
    first_colour,
    first_levels,
    points,
    triangle_start,
    triangles,
    colour,
    hit,
    need,
):
    """The samples at offset (n, 2) of marked pixels start..stop-1 (marked (K,) flat indices):
    need (K, n) bool: to be traced; colour (K, n, 3) float64 linear RGB, interpolated (the caller
    traces over it where need); hit (K, n) bool, the centre's (rendering/antialias.py, _decide).

    The centres: linear (H W, 3) float64, or (0, 3) (a streamed film: levels decoded through
    decoded (256,)); levels (H W, 3) uint8; hits (H W,) bool, where the centre ray hit, or
    (0,) (every centre hit); neighbours in SIDES' order. The second pass (first
    (M,) not empty): the first pass's pixels (M,) sorted, their samples' colour (M, n, 3) and
    levels (M, n, 3) uint8; points (P, 4) and the triangles of sample s, triangles[triangle_start[s]
    : triangle_start[s + 1]] (T, 3) (antialias._triangles), for the samples a straight edge cannot
    cross.
    """
    n = offset.shape[0]
    kept = linear.shape[0] > 0
    index = np.empty(5, dtype=np.int64)  # the pixel, then its neighbours at sides (clamped)
    inside = np.empty(5, dtype=np.bool_)
    usable = np.empty(5, dtype=np.bool_)
    col = np.empty((5, 3))
    apart = np.empty(5, dtype=np.bool_)
    found = np.empty(5, dtype=np.int64)
    lv = np.empty((3, 3), dtype=np.uint8)  # a triangle's corners
    cc = np.empty((3, 3))
    for k in range(start, stop):
        p = marked[k]
        y, x = p // width, p % width
        index[0], inside[0] = p, True
        for j in range(4):
            dx, dy = SIDES[j]
            inside[j + 1] = 0 <= x + dx < width and 0 <= y + dy < height
            index[j + 1] = p + dx + dy * width if inside[j + 1] else p
        for j in range(5):
            q = index[j]
            for c in range(3):
                col[j, c] = linear[q, c] if kept else decoded[levels[q, c]]
            centre_hit = hits.shape[0] == 0 or hits[q]
            usable[j] = kept or (levels[q, 0] < 255 and levels[q, 1] < 255 and levels[q, 2] < 255) or not centre_hit
            apart[j] = j > 0 and _apart(levels, p, levels, q, contrast)
        own_hit = hits.shape[0] == 0 or hits[p]
        for s in range(n):
            dx, dy = offset[s, 0] - 0.5, offset[s, 1] - 0.5
            h = 1 + (0 if dx > 0 else 1)  # sides: (1, 0), (-1, 0), (0, 1), (0, -1)
            v = 1 + (2 if dy > 0 else 3)
            wanted = not usable[0]
            if dx != 0:
                wanted = wanted or not inside[h] or not usable[h] or apart[h]
            if dy != 0:
                wanted = wanted or not inside[v] or not usable[v] or apart[v]
            if dx != 0 and dy != 0:
                wanted = wanted or _apart(levels, index[h], levels, index[v], contrast)
            need[k, s] = wanted
            hit[k, s] = own_hit
            for c in range(3):
                colour[k, s, c] = col[0, c] + abs(dx) * (col[h, c] - col[0, c]) + abs(dy) * (col[v, c] - col[0, c])
        # the second pass: not across a line one pixel thin (the centre apart from both neighbours)
        if first.shape[0] == 0 or (apart[1] and apart[2]) or (apart[3] and apart[4]):
            continue
        for j in range(5):  # each neighbour's row among the first pass's pixels, -1: not marked there
            at = first_at_least(first, index[j])
            found[j] = at if at < first.shape[0] and first[at] == index[j] else -1
        for s in range(n):
            if not need[k, s]:
                continue
            for t in range(triangle_start[s], triangle_start[s + 1]):
                agree = True
                for corner in range(3):
                    pt = triangles[t, corner]
                    j, sample = int(points[pt, 2]) + 1, int(points[pt, 3])
                    q = index[j]
                    ok = inside[j] and usable[j]
                    for c in range(3):
                        lv[corner, c], cc[corner, c] = levels[q, c], col[j, c]
                    at = found[j]
                    if sample >= 0 and at >= 0:  # a neighbour's sample: the first pass's where it was marked
                        for c in range(3):
                            lv[corner, c], cc[corner, c] = first_levels[at, sample, c], first_colour[at, sample, c]
                        ok = inside[j]
                    if not ok:
                        agree = False
                        break
                for a in range(3 if agree else 0):  # the corners pairwise: (0, 1), (1, 2), (2, 0)
                    if _apart(lv, a, lv, (a + 1) % 3, contrast):
                        agree = False
                        break
                if agree:
                    for c in range(3):
                        colour[k, s, c] = (cc[0, c] + cc[1, c] + cc[2, c]) / 3.0
                    need[k, s] = False
                    break

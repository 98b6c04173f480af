"""The film, band by band (compiled): summing samples into pixel rows, sRGB encoding.

A film of W x H pixels with spp = columns x rows samples per pixel is traced
as a sample film of (W * columns) x (H * rows) in bands of sample rows
(rendering/pipeline.py). ``add_samples`` adds a band's samples into the pixel
rows they fall in, in the order NumPy's sum over the columns then
``np.add.at`` over the rows did (so the sums are the same to the bit), and
divides the rows it completes by spp and writes their 8-bit sRGB in the same
pass (``encode_values``: any values' bytes), looked up in ``srgb_table`` (the
curve's 255 steps: 1.7 ns a value against pow's 14, measured on one of a
2-core machine's cores).
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.jit import njit


@njit(cache=True, nogil=True, no_cpython_wrapper=True)
def srgb_byte(c):
    """Linear value -> 8-bit sRGB (IEC 61966-2-1): NaN -> 0, clipped to [0, 1], rounded half to even."""
    if c != c:
        c = 0.0
    c = min(max(c, 0.0), 1.0)
    s = 12.92 * c if c <= 0.0031308 else 1.055 * c ** (1.0 / 2.4) - 0.055
    return np.uint8(np.rint(s * 255.0))


SRGB_BINS = 4096  # srgb_table's bins over [0, 1]: at most one step of the bytes in each (the curve's
# steepest slope is 12.92 x 255 = 3,295 bytes per unit, at 0, and falls beyond: steps >= 3.0e-4 apart)


@njit(cache=True, nogil=True)
def srgb_table():
    """The 8-bit curve as a table: (thresholds (257,) float64, first (SRGB_BINS,) uint8).

    thresholds[b] (b = 1..255) is the least double whose srgb_byte is >= b, found by bisection down
    to adjacent doubles ([0] = -inf, [256] = inf); first[i] is the srgb_byte of i / SRGB_BINS.
    srgb_byte_from gives srgb_byte's very bytes from them, the curve being non-decreasing
    (tests/test_film.py checks it around every threshold)."""
    thresholds = np.empty(257)
    thresholds[0], thresholds[256] = -np.inf, np.inf
    for b in range(1, 256):
        lo, hi = 0.0, 1.0  # srgb_byte(lo) < b <= srgb_byte(hi)
        while True:
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                break
            if srgb_byte(mid) >= b:
                hi = mid
            else:
                lo = mid
        thresholds[b] = hi
    first = np.empty(SRGB_BINS, dtype=np.uint8)
    for i in range(SRGB_BINS):
        first[i] = srgb_byte(i / SRGB_BINS)
    return thresholds, first


@njit(cache=True, nogil=True, no_cpython_wrapper=True)
def srgb_byte_from(c, thresholds, first):
    """srgb_byte(c) from srgb_table's arrays: the byte at the start of c's bin, and one more if c
    is past the bin's step (no two steps share a bin); no pow and no branch to mispredict."""
    c = min(max(c, 0.0), 1.0) if c == c else 0.0
    b = np.int64(first[min(np.int64(c * SRGB_BINS), SRGB_BINS - 1)])
    return np.uint8(b + (c >= thresholds[b + 1]))


@njit(cache=True, nogil=True)
def add_samples(
    start, stop, colour, hit, first, last, rows, columns, width, linear, hits, base, spp, pixels, thresholds, table
):
    """Add the samples of sample rows first..last-1 into pixel rows start..stop-1, count those that
    hit, and encode each of those rows that they complete.

    colour: ((last - first) * width * columns, 3) float64, the band's samples
    row by row, hit: (the same,) bool; a pixel row r holds sample rows r * rows .. r * rows + rows - 1,
    a pixel (r, x) the samples x * columns .. x * columns + columns - 1 of each.
    hits: (H, width) uint16, each pixel's samples that hit, added to.
    linear: (R, width, 3) float64 sums, pixel row r at linear[r - base]; a row's
    first sample row starts its sums (0.0 + the samples: the bits of adding to
    zeros), so they need no zeroing. A row complete after sample row last - 1 is
    divided by spp in place and its sRGB bytes written into pixels[r] (H, W, 3)
    uint8, by srgb_table's thresholds and first (table).
    """
    stride = width * columns
    for r in range(start, stop):
        lo, hi = max(first, r * rows), min(last, (r + 1) * rows)
        for s in range(lo, hi):
            row = (s - first) * stride
            for x in range(width):
                k = row + x * columns
                a0, a1, a2 = colour[k, 0], colour[k, 1], colour[k, 2]
                n = np.uint16(hit[k])
                for c in range(1, columns):
                    a0 += colour[k + c, 0]
                    a1 += colour[k + c, 1]
                    a2 += colour[k + c, 2]
                    n += np.uint16(hit[k + c])
                hits[r, x] += n
                if s == r * rows:
                    linear[r - base, x, 0] = 0.0 + a0
                    linear[r - base, x, 1] = 0.0 + a1
                    linear[r - base, x, 2] = 0.0 + a2
                else:
                    linear[r - base, x, 0] += a0
                    linear[r - base, x, 1] += a1
                    linear[r - base, x, 2] += a2
        if (r + 1) * rows <= last:
            for x in range(width):
                for c in range(3):
                    value = linear[r - base, x, c] / spp
                    linear[r - base, x, c] = value
                    pixels[r, x, c] = srgb_byte_from(value, thresholds, table)


@njit(cache=True, nogil=True)
def encode_values(start, stop, linear, out, thresholds, first):
    """out[k] = the sRGB byte of linear[k] for k = start .. stop - 1: linear (N,) float64, out (N,)
    uint8 (srgb_table's thresholds and first)."""
    for k in range(start, stop):
        out[k] = srgb_byte_from(linear[k], thresholds, first)


STAT_BLOCK = 1 << 15  # rays per block of put_records' counts


@njit(cache=True, nogil=True)
def put_records(start, stop, n, at, copy, source, target, counts):
    """Blocks start..stop-1 of STAT_BLOCK rays of a band's n pixel-centre records: copied into the
    film's (when copy) at ray offset at, and counted per block.

    source, target: Hits' fields in Hits.FIELDS' order (hit (N,) bool, t, surface (int64), patch
    (int64), u, v, iterations (int32), residual), target's N the film's (the source's again when
    not copy). counts: (B, 4) int64, per block: hits, iterations summed over the rays that spent
    any, those rays, the most iterations of one ray."""
    hit, t, surface, patch, u, v, iterations, residual = source
    hit_to, t_to, surface_to, patch_to, u_to, v_to, iterations_to, residual_to = target
    for b in range(start, stop):
        hits = spent = total = most = 0
        for k in range(b * STAT_BLOCK, min(n, (b + 1) * STAT_BLOCK)):
            its = iterations[k]
            hits += hit[k]
            if its > 0:
                spent += 1
                total += its
            most = max(most, its)
            if copy:
                j = at + k
                hit_to[j], t_to[j], surface_to[j], patch_to[j] = hit[k], t[k], surface[k], patch[k]
                u_to[j], v_to[j], iterations_to[j], residual_to[j] = u[k], v[k], its, residual[k]
        counts[b, 0], counts[b, 1], counts[b, 2], counts[b, 3] = hits, total, spent, most

"""The film, band by band (compiled): summing samples into pixel rows, sRGB encoding.

A film of W x H pixels with spp = columns x rows samples per pixel is traced
as a sample film of (W * columns) x (H * rows) in bands of sample rows
(rendering/pipeline.py). ``add_samples`` adds a band's samples into the pixel
rows they fall in, in the order NumPy's sum over the columns then
``np.add.at`` over the rows did (so the sums are the same to the bit);
``encode_rows`` divides complete rows by spp and writes their 8-bit sRGB
(``encode_values`` any values' bytes), looked up in ``srgb_table`` (the curve's 255 steps: 1.7 ns a value against
pow's 14, measured on one of a 2-core machine's cores).
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
def add_samples(start, stop, colour, first, last, rows, columns, width, linear, base):
    """Add the samples of sample rows first..last-1 into pixel rows start..stop-1.

    colour: ((last - first) * width * columns, 3) float64, the band's samples
    row by row; a pixel row r holds sample rows r * rows .. r * rows + rows - 1,
    a pixel (r, x) the samples x * columns .. x * columns + columns - 1 of each.
    linear: (R, width, 3) float64 sums, pixel row r at linear[r - base].
    """
    stride = width * columns
    for r in range(start, stop):
        lo, hi = max(first, r * rows), min(last, (r + 1) * rows)
        for s in range(lo, hi):
            row = (s - first) * stride
            for x in range(width):
                k = row + x * columns
                a0, a1, a2 = colour[k, 0], colour[k, 1], colour[k, 2]
                for c in range(1, columns):
                    a0 += colour[k + c, 0]
                    a1 += colour[k + c, 1]
                    a2 += colour[k + c, 2]
                linear[r - base, x, 0] += a0
                linear[r - base, x, 1] += a1
                linear[r - base, x, 2] += a2


@njit(cache=True, nogil=True)
def encode_rows(start, stop, linear, base, spp, pixels, thresholds, first):
    """Pixel rows start..stop-1 are complete: divide their sums linear[r - base] (R, W, 3) by spp
    in place and write their sRGB bytes into pixels[r] (H, W, 3) uint8 (srgb_table's thresholds
    and first)."""
    for r in range(start, stop):
        for x in range(linear.shape[1]):
            for c in range(3):
                value = linear[r - base, x, c] / spp
                linear[r - base, x, c] = value
                pixels[r, x, c] = srgb_byte_from(value, thresholds, first)


@njit(cache=True, nogil=True)
def encode_values(start, stop, linear, out, thresholds, first):
    """out[k] = the sRGB byte of linear[k] for k = start .. stop - 1: linear (N,) float64, out (N,)
    uint8 (srgb_table's thresholds and first)."""
    for k in range(start, stop):
        out[k] = srgb_byte_from(linear[k], thresholds, first)

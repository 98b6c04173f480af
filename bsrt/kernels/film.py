"""The film, band by band (compiled): summing samples into pixel rows, sRGB encoding.

A film of W x H pixels with spp = columns x rows samples per pixel is traced
as a sample film of (W * columns) x (H * rows) in bands of sample rows
(rendering/pipeline.py). ``add_samples`` adds a band's samples into the pixel
rows they fall in, in the order NumPy's sum over the columns then
``np.add.at`` over the rows did (so the sums are the same to the bit);
``encode_rows`` divides complete rows by spp and writes their 8-bit sRGB.
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
def encode_rows(start, stop, linear, base, spp, pixels):
    """Pixel rows start..stop-1 are complete: divide their sums linear[r - base] (R, W, 3) by spp
    in place and write their sRGB bytes into pixels[r] (H, W, 3) uint8."""
    for r in range(start, stop):
        for x in range(linear.shape[1]):
            for c in range(3):
                value = linear[r - base, x, c] / spp
                linear[r - base, x, c] = value
                pixels[r, x, c] = srgb_byte(value)

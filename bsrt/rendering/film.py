"""The film a render fills band by band: pixel sums, sRGB bytes, and (when kept) every pixel's hit.

A streaming film (``keep=False``) holds the 8-bit image and only the pixel
rows the current band touches, so a render's memory is bounded by the band
(about 3 bytes per pixel of the film, plus the band's working arrays); a kept
film also holds the linear RGB (24 bytes per pixel) and the pixel-centre rays'
hits (53 bytes per pixel) that RenderResult.linear, .hits and .aovs() give.
"""

from __future__ import annotations

import functools

import numpy as np

from bsrt.kernels.film import STAT_BLOCK, add_samples, encode_values, put_records, srgb_table
from bsrt.kernels.threads import run_chunks
from bsrt.rendering.hits import Hits

ROWS_PER_TASK = 8  # pixel rows per thread-pool task when summing and encoding


class Film:
    """width x height pixels of spp = columns x rows samples, traced in bands of at most
    ``band`` sample rows (rendering/pipeline.py).

    pixels: (H, W, 3) uint8 sRGB, rows final as their samples are all in.
    linear: (H, W, 3) float64 linear RGB when kept (None when streaming).
    hits: Hits of the H * W pixel-centre rays when kept (None when streaming).
    frames: with ``frames=True`` (one sample a pixel), the (position, normal) (H * W, 3) float64
      of the pixel-centre hits, which the shading writes into (frame_rows); else None.
    coverage: (H, W) float64, the fraction of each pixel's samples that hit a surface
      (counted in 2 bytes a pixel, kept or not: the alpha of a transparent picture).
    hit_count, iterations_sum, iterations_count, iterations_max: the
      pixel-centre rays' hits and root-finding iterations (rays that spent any),
      counted as they come, kept or not.
    """

    def __init__(
        self, width: int, height: int, columns: int, rows: int, band: int, keep: bool = True, frames: bool = False
    ):
        self.width, self.height, self.columns, self.rows, self.keep = width, height, columns, rows, keep
        if frames and columns * rows != 1:
            raise ValueError("a film keeps the shading's frames only with one sample a pixel")
        self.frames = (np.empty((width * height, 3)), np.empty((width * height, 3))) if frames else None
        self.pixels = np.zeros((height, width, 3), dtype=np.uint8)
        # the pixel rows a band touches: band // rows + 2 (a band may start and end inside a row); a
        # row's first samples start its sums (kernels/film.py's add_samples): no zeroing
        self._sums = np.empty((height if keep else min(height, band // rows + 2), width, 3))
        self._base = 0  # the pixel row of _sums[0]
        self._complete = 0  # pixel rows 0 .. _complete - 1 are final
        self.hits: Hits | None = None  # when kept, every pixel-centre ray's record (put_hits)
        self._hit_samples = np.zeros((height, width), dtype=np.uint16)  # spp <= 256 < 2^16
        self.hit_count = self.iterations_sum = self.iterations_count = self.iterations_max = 0

    @property
    def linear(self) -> np.ndarray | None:
        return self._sums if self.keep else None

    def add(self, colour: np.ndarray, hit: np.ndarray, first: int, stop: int) -> None:
        """Add the samples colour ((stop - first) * width * columns, 3) float64 of sample rows
        first..stop-1 (in order: bands come top to bottom), and count those that hit (hit: (the
        same,) bool); rows completed are encoded."""
        lo, hi = first // self.rows, (stop - 1) // self.rows + 1
        spp = float(self.rows * self.columns)
        sums, base = self._sums, self._base
        args = (colour, hit, first, stop, self.rows, self.columns, self.width, sums, self._hit_samples, base, spp)
        args += (self.pixels,)
        run_chunks(_add_rows, hi - lo, lo, *args, *_srgb(), min_chunk=ROWS_PER_TASK)
        done = stop // self.rows
        if done > self._complete:
            self._complete = done
            if not self.keep:  # keep the partial row (if any) at the top: its sums go on there
                self._sums[: hi - done] = self._sums[done - self._base : hi - self._base]
                self._base = done

    @property
    def coverage(self) -> np.ndarray:
        return self._hit_samples / float(self.rows * self.columns)

    @property
    def hit_samples(self) -> np.ndarray:
        """(H, W) uint16: each pixel's samples that hit (held, not copied)."""
        return self._hit_samples

    def frame_rows(self, first: int, stop: int):
        """The (position, normal) rows of sample rows first..stop-1 (views), or None."""
        if self.frames is None:
            return None
        return tuple(a[first * self.width : stop * self.width] for a in self.frames)

    def put_hits(self, start: int, hits: Hits) -> None:
        """The pixel-centre rays start .. start + len(hits) - 1 found ``hits``. A film traced in one
        band keeps that band's records themselves (not a copy: 13 MB at 512 x 512); the caller
        must not change them after."""
        target = hits  # counted only
        if self.keep:
            n = self.width * self.height
            if self.hits is None and start == 0 and len(hits) == n:
                self.hits = hits
            else:
                if self.hits is None:
                    self.hits = Hits.blank(n)  # every record is put, band by band
                target = self.hits
        fields = lambda h: tuple(getattr(h, name) for name in Hits.FIELDS)  # noqa: E731
        n = len(hits)
        counts = np.zeros((-(-n // STAT_BLOCK), 4), dtype=np.int64)
        run_chunks(put_records, counts.shape[0], n, start, target is not hits, fields(hits), fields(target), counts,
                   min_chunk=1)  # fmt: skip
        self.hit_count += int(counts[:, 0].sum())
        self.iterations_sum += int(counts[:, 1].sum())
        self.iterations_count += int(counts[:, 2].sum())
        self.iterations_max = max(self.iterations_max, int(counts[:, 3].max(initial=0)))


def srgb_bytes(linear: np.ndarray) -> np.ndarray:
    """8-bit sRGB of linear RGB (any shape) on the pool, by the film's curve (kernels/film.py's
    encode_values): image.srgb_encode's bytes."""
    values = np.ascontiguousarray(linear, dtype=np.float64)
    out = np.empty(values.shape, dtype=np.uint8)
    run_chunks(encode_values, values.size, values.reshape(-1), out.reshape(-1), *_srgb(), min_chunk=1 << 15)
    return out


@functools.cache
def _srgb() -> tuple[np.ndarray, np.ndarray]:
    """kernels.film.srgb_table's arrays, made once (a millisecond)."""
    return srgb_table()


def _add_rows(start, stop, lo, *args):
    add_samples(lo + start, lo + stop, *args)

"""The compiled anti-aliasing bookkeeping (bsrt/kernels/antialias.py) against the NumPy expressions
it replaced, which must agree bit for bit: the marked pixels, and for each sample of a marked pixel
whether it is traced, and the colour it is interpolated to."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bsrt.rendering import antialias
from bsrt.rendering.antialias import CONTRAST, SIDES, disagreeing, rotated_grid
from bsrt.rendering.image import srgb_decode, srgb_encode
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import Geometry, render, sample_grid
from bsrt.scene import load_scene

ROOT = Path(__file__).resolve().parent.parent


# ---------------------------------------------------------------------------
# The NumPy expressions (rendering/antialias.py before the kernels)


def reference_disagreeing(pixels):
    p = pixels.astype(np.int16)
    marked = np.zeros(p.shape[:2], dtype=bool)
    for axis in (0, 1):
        q = np.moveaxis(p, axis, 0)
        m = np.moveaxis(marked, axis, 0)
        if q.shape[0] < 2:
            continue
        m[1:-1] |= _beyond(q[:-2] - 2 * q[1:-1] + q[2:])
        m[0] |= _beyond(q[1] - q[0])
        m[-1] |= _beyond(q[-1] - q[-2])
    return marked


def _beyond(difference):
    a = np.abs(difference)
    return (a[..., 0] > CONTRAST) | (a[..., 1] > CONTRAST) | (a[..., 2] > CONTRAST)


def _apart(p, q):
    return _beyond(p.astype(np.int32) - q)


class _Centres:
    def __init__(self, linear, pixels, hits, width, height):
        self.linear, self.levels = linear, pixels.reshape(-1, 3)
        self.hits, self.width, self.height = hits, width, height

    def colour(self, index):
        if self.linear is not None:
            return self.linear.reshape(-1, 3).take(index, axis=0)
        return srgb_decode(self.levels_at(index))

    def levels_at(self, index):
        return self.levels.take(index, axis=0)

    def usable(self, index):
        if self.linear is not None:
            return np.ones(len(index), bool)
        levels = self.levels_at(index)
        return (levels[:, 0] < 255) & (levels[:, 1] < 255) & (levels[:, 2] < 255) | ~self.hit(index)

    def hit(self, index):
        return self.hits.reshape(-1)[index] > 0 if self.hits is not None else np.ones(len(index), bool)

    def neighbour(self, index, dx, dy):
        y, x = np.divmod(index, self.width)
        inside = (x + dx >= 0) & (x + dx < self.width) & (y + dy >= 0) & (y + dy < self.height)
        return np.where(inside, index + dx + dy * self.width, index), inside


def reference_block(marked, offset, grid, known, centres):
    """_block's decisions before tracing: (colour (K, n, 3), hit (K, n), need (K, n))."""
    n = offset.shape[0]
    centre, levels, centre_usable = centres.colour(marked), centres.levels_at(marked), centres.usable(marked)
    colour, hit = np.empty((marked.size, n, 3)), np.repeat(centres.hit(marked)[:, None], n, axis=1)
    need = np.zeros((marked.size, n), dtype=bool)
    near = [(marked, np.ones(marked.size, bool), levels, centre, centre_usable)]
    for dx, dy in SIDES:
        index, inside = centres.neighbour(marked, dx, dy)
        near.append((index, inside, centres.levels_at(index), centres.colour(index), centres.usable(index)))
    apart = [None] + [_apart(levels, m[2]) for m in near[1:]]
    for s, (dx, dy) in enumerate(offset - 0.5):
        h = 1 + SIDES.index((1 if dx > 0 else -1, 0))
        v = 1 + SIDES.index((0, 1 if dy > 0 else -1))
        need[:, s] = ~centre_usable
        if dx != 0:
            need[:, s] |= ~near[h][1] | ~near[h][4] | apart[h]
        if dy != 0:
            need[:, s] |= ~near[v][1] | ~near[v][4] | apart[v]
        if dx != 0 and dy != 0:
            need[:, s] |= _apart(near[h][2], near[v][2])
        colour[:, s] = centre + abs(dx) * (near[h][3] - centre) + abs(dy) * (near[v][3] - centre)
    if known and need.any():
        wide = ~((apart[1] & apart[2]) | (apart[3] & apart[4]))
        _from_neighbours([tuple(a[wide] for a in m) for m in near], grid, known, colour, need, wide)
    return colour, hit, need


def _from_neighbours(near, grid, known, colour, need, rows):
    points, triangles = _triangles(*grid)
    first, first_colour, first_levels = known
    table, found = {}, {}

    def point(p):
        if p not in table:
            side, sample = int(points[p, 2]), int(points[p, 3])
            index, inside, levels, col, usable = near[side + 1]
            lv = levels.astype(np.int32)
            if sample >= 0:
                if side not in found:
                    at = np.minimum(np.searchsorted(first, index), first.size - 1)
                    there = first[at] == index
                    found[side] = there, at[there]
                there, at = found[side]
                col, usable = col.copy(), usable.copy()
                lv[there], col[there] = first_levels[at, sample], first_colour[at, sample]
                usable[there] = True
            table[p] = lv, col, inside & usable
        return table[p]

    rows = np.flatnonzero(rows)
    for s in np.flatnonzero(need[rows].any(axis=0)):
        for a, b, c in triangles[s]:
            (la, ca, ia), (lb, cb, ib), (lc, cc, ic) = point(a), point(b), point(c)
            agree = need[rows, s] & ia & ib & ic & ~_apart(la, lb) & ~_apart(lb, lc) & ~_apart(la, lc)
            done = rows[agree]
            colour[done, s] = ((ca + cb + cc) / 3.0)[agree]
            need[done, s] = False


def _triangles(columns, rows):
    """antialias._triangles as the NumPy code read it: (points, [triangles of sample s (T_s, 3)])."""
    points, starts, flat = antialias._triangles(columns, rows)
    return points, [flat[starts[s] : starts[s + 1]] for s in range(len(starts) - 1)]


# ---------------------------------------------------------------------------


@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (2, 5), (9, 1), (41, 23)])
def test_the_marks_are_the_numpy_expression(shape):
    rng = np.random.default_rng(sum(shape))
    pixels = rng.integers(0, 256, size=shape + (3,), dtype=np.uint8)
    pixels[shape[0] // 4 : shape[0] // 2 + 1, shape[1] // 4 : shape[1] // 2 + 1] = 128  # flat: unmarked inside
    want = reference_disagreeing(pixels)
    np.testing.assert_array_equal(disagreeing(pixels), want)
    smooth = np.broadcast_to((np.arange(shape[1]) * 4).astype(np.uint8)[None, :, None], shape + (3,)).copy()
    assert not disagreeing(smooth).any()  # a gradient of 4 levels a pixel marks nothing
    if shape[0] > 2 and shape[1] > 2:
        assert want.any() and not want.all()


def test_each_sample_s_triangles_hold_it_with_the_pixels_centre_a_corner():
    for grid in ((2, 2), (3, 3), (2, 3)):
        points, triangles = _triangles(*grid)
        offset = rotated_grid(*grid) - 0.5
        for (sx, sy), t in zip(offset, triangles):
            if sx == 0 and sy == 0:
                continue  # an odd grid's middle sample is the centre: never interpolated
            assert len(t) and (t == 0).any(axis=1).all()
            p = points[t][..., :2] - [sx, sy]
            cross = np.stack([p[:, i, 0] * p[:, (i + 1) % 3, 1] - p[:, i, 1] * p[:, (i + 1) % 3, 0] for i in range(3)])
            assert ((cross > 0).all(axis=0) | (cross < 0).all(axis=0)).all()  # strictly inside
            area = np.abs(cross.sum(axis=0))
            assert (np.diff(area) >= 0).all()  # smallest first


def _one_sample(background=None, keep=True):
    scene = load_scene(ROOT / "scenes" / "column.toml")
    extra = {} if background is None else {"background": background}
    options = RenderOptions.resolve(scene, width=72, height=60, adaptive_spp=0, **extra)
    res = render(scene, options, geometry=Geometry(scene), keep=keep)
    return res, options


@pytest.mark.gl
@pytest.mark.parametrize("case", ["kept", "streamed", "streamed-white"])
@pytest.mark.parametrize("n", [4, 9, 6])
def test_the_samples_decided_and_interpolated_are_the_numpy_expression(case, n):
    """Both passes on the column's one-sample render: which samples are traced, and the colour
    of the others, bit for bit (the second pass interpolating from the first pass's samples, here
    the reference's with every traced one given a colour of its own)."""
    res, options = _one_sample((1.0, 1.0, 1.0) if case == "streamed-white" else None, keep=case == "kept")
    pixels = res.pixels.copy()
    if case == "kept":
        linear, hits = res.linear, res.coverage
    else:
        linear = None
        hits = (srgb_encode(res.linear)[..., 0] != 0).astype(np.uint16) if res.linear is not None else None
        hits = np.ones(pixels.shape[:2], np.uint16) if hits is None else hits
        hits[::7, ::5] = 0  # some centres without a hit: their 255s are exact
        pixels[::11, ::3] = 255  # and some highlights
    grid = sample_grid(n)
    offset = rotated_grid(*grid)
    centres = _Centres(linear, pixels, hits, options.width, options.height)
    flat = antialias._centres(linear, pixels, hits)
    marked = np.flatnonzero(disagreeing(pixels).ravel())
    assert marked.size > 100
    odd = (marked % options.width + marked // options.width) % 2 == 1
    even = marked[~odd]
    want = reference_block(even, offset, grid, None, centres)
    got = antialias._decide(even, offset, grid, antialias._first_pass_none(n), flat, options.width, options.height)
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)
    colour = want[0].copy()
    rng = np.random.default_rng(n)
    colour[want[2]] = rng.random((int(want[2].sum()), 3))  # the traced samples' colours
    known = (even, colour, srgb_encode(colour))
    want = reference_block(marked[odd], offset, grid, known, centres)
    got = antialias._decide(marked[odd], offset, grid, known, flat, options.width, options.height)
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)
    interpolated = ~want[2] & reference_block(marked[odd], offset, grid, None, centres)[2]
    assert interpolated.any()  # the second pass interpolated from the first pass's samples


def test_the_centres_are_views_of_the_film_but_one_byte_a_pixel_for_the_hits():
    """A streamed film's hit counts (uint16) or a kept film's coverage (float64) become one bool a
    pixel, nothing larger; the colours are read in place."""
    rng = np.random.default_rng(3)
    pixels = rng.integers(0, 256, size=(30, 20, 3), dtype=np.uint8)
    for linear, hits in (
        (None, rng.integers(0, 3, size=(30, 20)).astype(np.uint16)),
        (rng.random((30, 20, 3)), rng.random((30, 20)) * (rng.random((30, 20)) > 0.5)),
    ):
        got_linear, levels, hit = antialias._centres(linear, pixels, hits)
        assert np.shares_memory(levels, pixels) and levels.shape == (600, 3)
        assert got_linear.shape == (0, 3) if linear is None else np.shares_memory(got_linear, linear)
        assert hit.dtype == np.bool_ and hit.itemsize == 1 and hit.shape == (600,)
        np.testing.assert_array_equal(hit, hits.reshape(-1) > 0)
    assert antialias._centres(None, pixels, None)[2].shape == (0,)

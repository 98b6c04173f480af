"""The film kernels (summing samples, sRGB), the streamed film, and shadow rays of the compiled lighting pass."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from bsrt.kernels.film import SRGB_BINS, srgb_byte, srgb_byte_from, srgb_table
from bsrt.kernels.jit import njit
from bsrt.rendering import pipeline
from bsrt.rendering.film import Film, srgb_bytes
from bsrt.rendering.hits import Hits
from bsrt.rendering.image import srgb_decode, srgb_encode
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import Geometry, render
from bsrt.scene import load_scene
from bsrt.scene.model import Light

SCENES = Path(__file__).resolve().parent.parent / "scenes"


def _film_bytes(values: np.ndarray, spp: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """values (N,) -> (the sRGB bytes (N, 3) of a 1 x N film whose one sample per pixel sums to
    spp * value, the film's linear values (N, 3))."""
    n = values.shape[0]
    film = Film(n, 1, spp, 1, 1)  # spp columns, one row: spp samples per pixel side by side
    colour = np.repeat(np.repeat(values[:, None], spp, axis=0)[:, :, None], 3, axis=2).reshape(-1, 3)
    film.add(colour, np.ones(colour.shape[0], dtype=bool), 0, 1)
    return film.pixels[0], film.linear[0]


def test_encoded_bytes_follow_the_srgb_curve():
    # 12.92 * 0.0031308 * 255 = 10.31; 1.055 * 0.5 ** (1 / 2.4) - 0.055 = 0.73536, * 255 = 187.52
    values = np.array([0.0, 0.0031308, 0.5, 1.0, 2.0, -1.0, np.nan, np.inf, -np.inf])
    expect = [0, 10, 188, 255, 255, 0, 0, 255, 0]
    got, _ = _film_bytes(values)
    assert got[:, 0].tolist() == expect and (got == got[:, :1]).all()


def test_encoded_bytes_equal_srgb_encode_and_the_sums_are_divided_by_spp():
    rng = np.random.default_rng(5)
    values = np.concatenate([rng.uniform(-0.1, 1.1, 50_000), rng.uniform(0.0, 0.01, 50_000)])
    got, linear = _film_bytes(values)
    assert np.array_equal(got[:, 0], srgb_encode(values))
    # three samples of the same value: (v + v + v) / 3
    got3, linear3 = _film_bytes(values[:1000], spp=3)
    assert np.array_equal(linear3[:, 0], (values[:1000] + values[:1000] + values[:1000]) / 3.0)
    assert np.array_equal(got3[:, 0], srgb_encode(linear3[:, 0]))


def test_srgb_bytes_on_the_pool_are_srgb_encode():
    """rendering/film.py's srgb_bytes (the adaptive anti-aliasing's encoder: kernels/film.py's
    encode_values on the pool) gives image.srgb_encode's bytes, in its shape, on more values than
    one slice, the curve's ends and non-finite values included."""
    rng = np.random.default_rng(6)
    values = np.concatenate([rng.uniform(-0.1, 1.1, 70_000), rng.uniform(0.0, 0.01, 20_000)])
    values = np.concatenate([values, [0.0, 0.0031308, 1.0, -0.0, np.nan, np.inf, -np.inf]])
    for shaped in (values, values[: 3 * 30_000].reshape(-1, 10, 3), values[::2]):
        got = srgb_bytes(shaped)
        assert got.dtype == np.uint8 and got.shape == shaped.shape
        assert np.array_equal(got, srgb_encode(shaped))


@pytest.mark.parametrize("keep", [True, False])
def test_put_hits_copies_the_bands_records_and_counts_them(keep):
    """Film.put_hits (kernels/film.py's put_records on the pool, in blocks of STAT_BLOCK rays): a
    kept film holds every band's records, and either film counts the hits and the iterations of
    the rays that spent any as NumPy does."""
    from bsrt.kernels.film import STAT_BLOCK

    rng = np.random.default_rng(11)
    width, height = 300, 250
    n = width * height
    whole = Hits.blank(n)
    whole.hit[:] = rng.random(n) < 0.6
    for name in ("t", "u", "v", "residual"):
        getattr(whole, name)[:] = np.where(whole.hit, rng.random(n), np.nan)
    whole.surface[:] = np.where(whole.hit, rng.integers(0, 9, n), -1)
    whole.patch[:] = np.where(whole.hit, rng.integers(0, 99, n), -1)
    whole.iterations[:] = rng.integers(0, 40, n) * (rng.random(n) < 0.8)
    film = Film(width, height, 1, 1, 100, keep)
    bands = (0, 37 * width, 37 * width + STAT_BLOCK + 5 * width, n)  # a band longer than one block
    for a, b in zip(bands[:-1], bands[1:]):
        film.put_hits(a, whole.take(slice(a, b)))
    its = whole.iterations
    assert film.hit_count == int(whole.hit.sum())
    assert film.iterations_sum == int(its[its > 0].sum()) and film.iterations_count == int((its > 0).sum())
    assert film.iterations_max == int(its.max())
    if keep:
        for name in Hits.FIELDS:
            np.testing.assert_array_equal(getattr(film.hits, name), getattr(whole, name), err_msg=name)
    else:
        assert film.hits is None


@njit(cache=False)
def _both_bytes(values, thresholds, first):
    """(N, 2) uint8: srgb_byte and srgb_byte_from of each value (both are compiled-only)."""
    out = np.empty((values.shape[0], 2), dtype=np.uint8)
    for i in range(values.shape[0]):
        out[i, 0] = srgb_byte(values[i])
        out[i, 1] = srgb_byte_from(values[i], thresholds, first)
    return out


def test_the_table_gives_the_curve_s_bytes_around_every_step():
    thresholds, first = srgb_table()
    steps = thresholds[1:256]
    assert np.all(np.diff(steps) > 1.0 / SRGB_BINS) and steps[0] > 0.0 and steps[-1] < 1.0  # a step per bin at most
    # 2,000 doubles either side of each step (positive doubles are ordered as their bits)
    near = (steps.view(np.int64)[:, None] + np.arange(-2000, 2001)[None, :]).ravel().view(np.float64)
    both = _both_bytes(near, thresholds, first)
    assert np.array_equal(both[:, 0], both[:, 1])
    # the steps are exact: the double below each gives the byte below
    at = _both_bytes(steps, thresholds, first)[:, 0]
    below = _both_bytes(np.nextafter(steps, 0.0), thresholds, first)[:, 0]
    assert at.tolist() == list(range(1, 256)) and below.tolist() == list(range(0, 255))
    rng = np.random.default_rng(3)
    spread = np.concatenate(
        [rng.uniform(-0.5, 1.5, 200_000), 10.0 ** rng.uniform(-12, 0, 200_000), [np.nan, np.inf, -np.inf, 0.0, 1.0]]
    )
    both = _both_bytes(spread, thresholds, first)
    assert np.array_equal(both[:, 0], both[:, 1])


@pytest.mark.parametrize("keep", [True, False])
def test_bands_ending_inside_pixel_rows_sum_every_sample_once_in_order(keep):
    width, height, columns, rows = 5, 7, 3, 2
    rng = np.random.default_rng(11)
    samples = rng.uniform(0.0, 1.0, (height * rows, width * columns, 3))  # the sample film
    hit = rng.random((height * rows, width * columns)) < 0.7
    film = Film(width, height, columns, rows, band=3, keep=keep)
    for first in range(0, height * rows, 3):  # bands of 3 sample rows: every other one ends inside a pixel row
        stop = min(height * rows, first + 3)
        film.add(samples[first:stop].reshape(-1, 3), hit[first:stop].reshape(-1), first, stop)
    expect = np.zeros((height, width, 3))
    for r in range(height):  # the reference order: a sample row's columns, then the rows, then / spp
        for s in range(r * rows, (r + 1) * rows):
            per_pixel = samples[s].reshape(width, columns, 3)
            acc = per_pixel[:, 0]
            for c in range(1, columns):
                acc = acc + per_pixel[:, c]
            expect[r] = expect[r] + acc
    expect /= columns * rows
    assert np.array_equal(film.pixels, srgb_encode(expect))
    if keep:
        assert np.array_equal(film.linear, expect)
    else:
        assert film.linear is None and film.hits is None
        assert film._sums.shape[0] == 3  # the rows a band touches, not the film
    # each pixel's samples that hit, counted as they were added
    np.testing.assert_array_equal(film.hit_samples, hit.reshape(height, rows, width, columns).sum(axis=(1, 3)))


def test_streamed_hit_counters_are_those_of_the_kept_hits():
    hits = Hits.empty(6)
    hits.hit[[1, 4]] = True
    hits.iterations[:] = [0, 3, 5, 0, 2, 7]
    film = Film(3, 2, 1, 1, 1, keep=False)
    film.put_hits(0, hits.take(slice(0, 3)))
    film.put_hits(3, hits.take(slice(3, 6)))
    assert (film.hit_count, film.iterations_sum, film.iterations_count, film.iterations_max) == (2, 17, 4, 7)


@pytest.mark.gl
def test_a_streamed_render_gives_the_kept_render_s_image_and_stats(monkeypatch):
    scene = load_scene(SCENES / "column.toml")
    options = RenderOptions.resolve(scene, width=24, height=16, spp=4)
    # 3 sample rows of 48 per band: bands end inside pixel rows (2 sample rows each)
    monkeypatch.setattr(pipeline, "MAX_BAND_SAMPLES", 3 * 48)
    geometry = Geometry(scene)
    kept = render(scene, options, geometry=geometry)
    streamed = render(scene, options, geometry=geometry, keep=False)
    assert np.array_equal(kept.pixels, streamed.pixels)
    assert streamed.linear is None and streamed.hits is None
    a, b = dict(kept.stats), dict(streamed.stats)
    del a["seconds"], b["seconds"]
    assert a == b and a["hits"] == int(kept.hits.hit.sum()) > 50
    with pytest.raises(ValueError, match="kept no hits"):
        streamed.aovs()


@pytest.mark.gl
def test_shadow_rays_block_exactly_where_the_any_hit_tracer_finds_an_occluder():
    """The compiled pass's shadow rays (the last occluder tried first) against bvh.intersect's any-hit
    rays from the same points: water-lily lit by one point and one directional light, Lambert only
    (specular 0, no mirrors), so each pixel is albedo * sum of visible cos * intensity (/ r^2)."""
    base = load_scene(SCENES / "water-lily.toml")
    point, sun = np.array([6.0, -5.0, 10.0]), np.array([1.0, 1.0, -1.0])
    scene = dataclasses.replace(
        base,
        materials=tuple(dataclasses.replace(m, specular=0.0, reflectance=0.0) for m in base.materials),
        lights=(
            Light("point", position=tuple(point), intensity=160.0),
            Light("directional", direction=tuple(sun), intensity=0.7),
        ),
    )
    res = render(scene, RenderOptions.resolve(scene, width=96, height=96, adaptive_spp=0))
    hits = res.hits
    hit = np.flatnonzero(hits.hit)
    p, n = res.position[hit], res.normal[hit]
    geometry = res.geometry
    patches = geometry.patches
    # the exclusion box of each start root: 1e-6 of the diagonal in u, v, at most a quarter of the patch
    from bsrt.rendering.shade import facing_frames
    from bsrt.scene.camera import pixel_rays

    speed = facing_frames(patches, hits, pixel_rays(scene.camera, 96, 96))[2][hit]
    bounds = patches.bounds[hits.patch[hit]]
    eps = 1e-6 * geometry.diagonal
    ru = np.minimum(eps / speed[:, 0], 0.25 * (bounds[:, 1] - bounds[:, 0]))
    rv = np.minimum(eps / speed[:, 1], 0.25 * (bounds[:, 3] - bounds[:, 2]))
    exclude = (hits.surface[hit], hits.u[hit], hits.v[hit], ru, rv)
    tol = scene.render.tolerance * geometry.diagonal
    to_point = point - p
    dist = np.linalg.norm(to_point, axis=1)
    to_point /= dist[:, None]
    to_sun = np.broadcast_to(-sun / np.linalg.norm(sun), p.shape)
    total = np.zeros(hit.size)
    shadowed = 0
    for direction, t_max, strength in ((to_point, dist, 160.0 / dist**2), (to_sun, np.inf, 0.7)):
        cos = np.einsum("ij,ij->i", n, direction)
        facing = cos > 0
        blocked = geometry.intersect(
            p, direction, t_max=t_max, tolerance=tol, any_hit=True, exclude=tuple(a for a in exclude)
        ).hit
        lit = facing & ~blocked
        shadowed += int((facing & blocked).sum())
        total += np.where(lit, cos * strength, 0.0)
    albedo = np.array([m.color for m in scene.materials])[geometry.material[hits.surface[hit]]]
    expect = albedo * total[:, None]
    assert shadowed > 200 and hit.size > 4000
    np.testing.assert_allclose(res.linear.reshape(-1, 3)[hit], expect, rtol=1e-12, atol=1e-15)


def test_srgb_decode_is_the_curves_inverse_at_every_level():
    """IEC 61966-2-1 by hand: the linear segment below 0.04045, the 2.4 power above; encoding
    each decoded level gives the level back; any array shape."""
    levels = np.arange(256, dtype=np.uint8)
    linear = srgb_decode(levels)
    assert linear[0] == 0.0 and linear[255] == 1.0
    assert linear[10] == pytest.approx(10 / 255 / 12.92, rel=1e-15)
    assert linear[128] == pytest.approx(((128 / 255 + 0.055) / 1.055) ** 2.4, rel=1e-15)
    np.testing.assert_array_equal(srgb_encode(linear), levels)
    assert srgb_decode(levels.reshape(16, 16)).shape == (16, 16)

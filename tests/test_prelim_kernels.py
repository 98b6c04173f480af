"""The compiled map kernels (bsrt/kernels/prelim.py) against closed forms and
the NumPy expressions they replace, which must agree bit for bit."""

import numpy as np
import pytest

from bsrt.geometry.patches import PatchSet
from bsrt.kernels.prelim import decode_tile, map_suspects, normalise_rows
from bsrt.rendering import gl, gpu, gpu_map, prelim
from bsrt.rendering.hard_pixels import (
    FOLD_PIXELS,
    LAYER_SLACK_PIXELS,
    SEAM_RATIO,
    suspect_pixels,
)
from bsrt.rendering.hits import Hits
from bsrt.rendering.screen import film_rays
from bsrt.rendering.solve import Rays
from bsrt.scene import parse_scene
from bsrt.scene.camera import Camera, pixel_ray_arrays, pixel_rays

DOMAIN = np.array([[0.0, 1.0, 0.0, 1.0], [2.0, 5.0, -1.0, 3.0], [0.25, 0.75, 10.0, 10.5]])


def reference_decode(tri, tri_dist, line, line_dist, mode):
    """The NumPy merge and decode that decode_tile replaced (GL rows flipped first)."""
    tri, tri_dist, line, line_dist = (a[::-1] for a in (tri, tri_dist, line, line_dist))
    other = line[..., 0] != tri[..., 0]
    nearer = (line[..., 0] != 0) & ((tri[..., 0] == 0) | (other & (line_dist < tri_dist)))
    raw = np.where(nearer[..., None], line, tri)
    eye_distance = np.where(nearer, line_dist, tri_dist)
    if mode == "float":
        ident = np.rint(raw[..., 0]).astype(np.int64) - 1
        g, b = raw[..., 1].astype(np.float64), raw[..., 2].astype(np.float64)
        picture = np.stack([np.clip(ident + 1, 0, 255), np.rint(g * 255), np.rint(b * 255)], axis=-1).astype(np.uint8)
    else:
        ident = raw[..., 0].astype(np.int64) - 1
        g, b = raw[..., 1] / 255.0, raw[..., 2] / 255.0
        picture = raw[..., :3].copy()
    covered = ident >= 0
    d = DOMAIN[np.where(covered, ident, 0)]
    u = np.where(covered, d[..., 0] + (d[..., 1] - d[..., 0]) * g, np.nan)
    v = np.where(covered, d[..., 2] + (d[..., 3] - d[..., 2]) * b, np.nan)
    distance = np.where(covered, eye_distance.astype(np.float64), np.inf)
    return np.where(covered, ident, -1), u, v, distance, picture


def random_pass(rng, h, w, mode):
    """A raw pass as GL writes it: empty (all 0) or surface 1..3 with u, v, and a distance."""
    ident = rng.integers(0, 4, size=(h, w))
    if mode == "float":
        raw = np.zeros((h, w, 4), dtype=np.float32)
        raw[..., 0] = ident
        raw[..., 1:3] = rng.random((h, w, 2), dtype=np.float32)
        raw[..., 3] = 1.0
    else:
        raw = np.zeros((h, w, 4), dtype=np.uint8)
        raw[..., 0] = ident
        raw[..., 1:3] = rng.integers(0, 256, size=(h, w, 2))
        raw[..., 3] = 255
    raw[ident == 0] = 0
    dist = np.where(ident > 0, rng.choice([2.0, 3.0, 4.0], size=(h, w)), 0.0).astype(np.float32)
    return raw, dist


def run_decode(tri, tri_dist, line, line_dist, mode, out_shape, row0=0, col0=0, outs=None):
    if outs is None:
        outs = (
            np.full(out_shape, 7, dtype=np.int64),
            np.zeros(out_shape),
            np.zeros(out_shape),
            np.zeros(out_shape),
            np.zeros(out_shape + (3,), dtype=np.uint8),
        )
    n = tri.shape[0] * tri.shape[1]
    for start, stop in ((0, min(5, n)), (min(5, n), n)):  # two slices, as run_chunks calls it
        decode_tile(start, stop, tri, tri_dist, line, line_dist, mode == "float", DOMAIN, row0, col0, *outs)
    return outs


@pytest.mark.parametrize("mode", ["float", "rgba8"])
def test_decode_tile_is_the_numpy_merge_and_decode_bit_for_bit(mode):
    rng = np.random.default_rng(4)
    tri, tri_dist = random_pass(rng, 9, 13, mode)
    line, line_dist = random_pass(rng, 9, 13, mode)
    got = run_decode(tri, tri_dist, line, line_dist, mode, (9, 13))
    for a, b in zip(got, reference_decode(tri, tri_dist, line, line_dist, mode)):
        assert a.dtype == b.dtype
        np.testing.assert_array_equal(a, b)


def test_decode_tile_hand_worked_pixels_and_tile_offset():
    # one GL row (the film's bottom row of the tile), three pixels:
    # 0: triangles empty, line shows surface 2 -> the line's seed
    # 1: triangles show surface 1 at 3.0, a nearer line of surface 3 -> the line wins
    # 2: triangles show surface 2 at 2.0, a nearer line of the same surface -> the triangles stay
    tri = np.array([[[0, 0, 0, 0], [1, 0.5, 0.25, 1], [2, 1.0, 0.0, 1]]], dtype=np.float32)
    line = np.array([[[2, 0.5, 0.5, 1], [3, 0.0, 1.0, 1], [2, 0.0, 0.0, 1]]], dtype=np.float32)
    tri_dist = np.array([[0.0, 3.0, 2.0]], dtype=np.float32)
    line_dist = np.array([[1.5, 2.5, 1.0]], dtype=np.float32)
    surface, u, v, distance, picture = run_decode(tri, tri_dist, line, line_dist, "float", (3, 5), row0=2, col0=2)
    np.testing.assert_array_equal(surface[2, 2:], [1, 2, 1])
    np.testing.assert_array_equal(u[2, 2:], [2.0 + 3.0 * 0.5, 0.25, 5.0])  # eq. 6: lo + (hi - lo) g
    np.testing.assert_array_equal(v[2, 2:], [-1.0 + 4.0 * 0.5, 10.5, -1.0])
    np.testing.assert_array_equal(distance[2, 2:], [1.5, 2.5, 2.0])
    np.testing.assert_array_equal(picture[2, 2:], [[2, 128, 128], [3, 0, 255], [2, 255, 0]])
    assert (surface[:2] == 7).all() and (surface[2, :2] == 7).all()  # nothing outside the tile is written


def test_decode_tile_leaves_empty_pixels_unseeded():
    empty = np.zeros((2, 2, 4), dtype=np.uint8)
    dist = np.zeros((2, 2), dtype=np.float32)
    surface, u, v, distance, picture = run_decode(empty, dist, empty, dist, "rgba8", (2, 2))
    assert (surface == -1).all() and np.isnan(u).all() and np.isnan(v).all() and np.isinf(distance).all()
    assert (picture == 0).all()


@pytest.mark.parametrize("mode", ["float", "rgba8"])
def test_the_gpu_merged_map_decodes_as_the_numpy_decode(mode):
    """gpu_map.decode_record (kernels/prelim.py's decode_merged on the pool) on map_solve.glsl's
    merged record: the NumPy decode of the same pixels bit for bit (no line pass: the merge is
    the shader's), in film order, on more pixels than one slice."""
    rng = np.random.default_rng(7)
    h, w = 37, 151
    tri, tri_dist = random_pass(rng, h, w, mode)
    none, none_dist = np.zeros_like(tri), np.zeros_like(tri_dist)
    record = np.empty((h * w, 4), dtype=np.float32)
    record[:, :3] = tri[::-1, :, :3].reshape(-1, 3)  # the film's row 0 first, as the shader writes it
    record[:, 3] = tri_dist[::-1].reshape(-1)
    got = gpu_map.decode_record(record, mode, DOMAIN, (h, w))
    want = reference_decode(tri, tri_dist, none, none_dist, mode)
    for name, b in zip(("surface", "u", "v", "distance", "picture"), want):
        a = getattr(got, name)
        assert a.dtype == b.dtype and a.shape == b.shape, name
        np.testing.assert_array_equal(a, b, err_msg=name)
    assert (got.surface >= 0).any() and (got.surface < 0).any()


def test_the_gpu_roots_are_gathered_field_by_field():
    """gpu.decode_roots: item items[k] of solve_core.glsl's root buffers into RootResult's fields."""
    rng = np.random.default_rng(8)
    n = 5000
    reals = rng.random((n, 4))
    ints = np.stack([rng.integers(0, 2, n), rng.integers(0, 90, n), rng.integers(0, 64, n), rng.integers(0, 2, n)], 1)
    ints = ints.astype(np.int32)
    items = np.sort(rng.choice(n, 3001, replace=False))
    got = gpu.decode_roots(reals, ints, items)
    want = {
        "converged": ints[items, 0] != 0,
        "trimmed": ints[items, 3] != 0,
        "u": reals[items, 0],
        "v": reals[items, 1],
        "patch": ints[items, 1].astype(np.int64),
        "t": reals[items, 2],
        "residual": reals[items, 3],
        "iterations": ints[items, 2],
    }
    for name, b in want.items():
        a = getattr(got, name)
        assert a.dtype == b.dtype, name
        np.testing.assert_array_equal(a, b, err_msg=name)


CAMERA = Camera(
    eye=np.array([1.0, -2.0, 3.0]), look_at=np.array([0.5, 0.25, -0.5]), up=np.array([0.0, 0.0, 1.0]), fov=50.0
)


@pytest.mark.parametrize("rows", [None, (3, 8)])
def test_pixel_rays_are_the_numpy_expression_bit_for_bit(rows):
    width, height = 11, 9
    first, stop = rows or (0, height)
    r, u, f = CAMERA.basis()
    tx, ty = CAMERA.half_extents(width, height)
    x = (2.0 * (np.arange(width) + 0.5) / width - 1.0) * tx
    y = (1.0 - 2.0 * (np.arange(first, stop) + 0.5) / height) * ty
    d = (f[None, None, :] + x[None, :, None] * r[None, None, :] + y[:, None, None] * u[None, None, :]).reshape(-1, 3)
    np.testing.assert_array_equal(pixel_rays(CAMERA, width, height, rows), d / np.linalg.norm(d, axis=1, keepdims=True))


@pytest.mark.parametrize("rows", [None, (3, 8)])
def test_pixel_ray_arrays_are_rays_from_arrays_of_pixel_rays_bit_for_bit(rows):
    """The map tracer's rays in one pass: the same numbers as normalising pixel_rays again."""
    origins, directions = pixel_ray_arrays(CAMERA, 11, 9, rows)
    rays = Rays.from_arrays(CAMERA.eye[None, :], pixel_rays(CAMERA, 11, 9, rows))
    np.testing.assert_array_equal(directions, rays.direction)
    np.testing.assert_array_equal(origins, rays.origin)
    assert origins.flags.c_contiguous and origins.flags.writeable and directions.flags.c_contiguous


def test_pixel_rays_closed_form_centre_and_corner():
    # odd film: the middle pixel looks at look_at; a corner pixel centre lies
    # (w - 1) / w of the half extents off the axis
    width, height = 5, 3
    d = pixel_rays(CAMERA, width, height).reshape(height, width, 3)
    r, u, f = CAMERA.basis()
    np.testing.assert_allclose(d[1, 2], f, atol=1e-15)
    tx, ty = CAMERA.half_extents(width, height)
    corner = f - 0.8 * tx * r + (2.0 / 3.0) * ty * u
    np.testing.assert_allclose(d[0, 0], corner / np.linalg.norm(corner), atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(d, axis=2), 1.0, atol=1e-15)


def test_film_rays_are_the_numpy_expression_bit_for_bit():
    """screen.film_rays (kernels/prelim.py's film_rays_into on the pool) against the NumPy steps it
    replaced, at positions inside and outside a 640 x 480 film, on more rays than one slice; the
    pixel centres give pixel_rays' directions."""
    rng = np.random.default_rng(9)
    xy = rng.uniform(-5.0, 700.0, size=(20_000, 2))
    r, u, f = CAMERA.basis()
    tx, ty = CAMERA.half_extents(640, 480)
    x = (2.0 * xy[:, 0] / 640 - 1.0) * tx
    y = (1.0 - 2.0 * xy[:, 1] / 480) * ty
    d = f[None, :] + x[:, None] * r[None, :] + y[:, None] * u[None, :]
    np.testing.assert_array_equal(film_rays(CAMERA, 640, 480, xy), d / np.linalg.norm(d, axis=1)[:, None])
    centres = np.stack(np.meshgrid(np.arange(5) + 0.5, np.arange(3) + 0.5), axis=-1).reshape(-1, 2)
    np.testing.assert_allclose(film_rays(CAMERA, 5, 3, centres), pixel_rays(CAMERA, 5, 3), rtol=0, atol=1e-15)


def test_normalise_rows_and_rays_from_arrays_are_numpy_bit_for_bit():
    d = np.random.default_rng(2).normal(size=(1000, 3)) * 7.0
    out, origin_out = np.empty_like(d), np.empty_like(d)
    normalise_rows(0, 1000, d, out, d[::-1].copy(), origin_out)
    expected = d / np.linalg.norm(d, axis=1, keepdims=True)
    np.testing.assert_array_equal(out, expected)
    np.testing.assert_array_equal(origin_out, d[::-1])
    rays = Rays.from_arrays(np.array([[1.0, 2.0, 3.0]]), d)
    np.testing.assert_array_equal(rays.direction, expected)
    np.testing.assert_array_equal(rays.origin, np.broadcast_to([1.0, 2.0, 3.0], (1000, 3)))
    np.testing.assert_array_equal(Rays.from_arrays([[0.0, 0.0, 0.0]], [[3.0, 0.0, 4.0]]).direction, [[0.6, 0.0, 0.8]])


def reference_suspects(surface, distance, u, v, domain, hit, t, failed, footprint, tolerance, floor):
    """The NumPy border, fold, layer and seam tests that map_suspects replaced: (suspect, layer, seam), each (N,)."""
    h, w = surface.shape
    padded = np.pad(surface, 1, mode="edge")
    border = np.zeros((h, w), dtype=bool)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            border |= padded[1 + di : 1 + di + h, 1 + dj : 1 + dj + w] != surface
    dist = np.where(np.isfinite(distance), distance, 0.0)
    fold = np.zeros(dist.shape, dtype=bool)
    for axis in (0, 1):
        if dist.shape[axis] < 3:
            continue
        curve = np.abs(np.diff(dist, 2, axis=axis))
        middle = dist.take(range(1, dist.shape[axis] - 1), axis=axis)
        pad = [(0, 0), (0, 0)]
        pad[axis] = (1, 1)
        fold |= np.pad(curve > FOLD_PIXELS * footprint * middle, pad)
    layer = hit & (np.abs(t - distance.ravel()) > LAYER_SLACK_PIXELS * footprint * distance.ravel() + tolerance)
    odd = (border | fold).ravel() | failed | layer
    # seams: (u, v) scaled by the domain, steps in the max norm
    s = np.maximum(surface, 0)
    su, sv = 1.0 / (domain[s, 1] - domain[s, 0]), 1.0 / (domain[s, 3] - domain[s, 2])
    jump = np.zeros((h, w), dtype=bool)
    for axis in (0, 1):
        if surface.shape[axis] < 3:
            continue
        uu, vv, scale_u, scale_v = (np.moveaxis(x, axis, 0) for x in (u, v, su, sv))  # lines along axis 0
        mid = slice(1, -1)

        def step(x, y, uu=uu, vv=vv, scale_u=scale_u[mid], scale_v=scale_v[mid]):
            return np.maximum(np.abs(uu[y] - uu[x]) * scale_u, np.abs(vv[y] - vv[x]) * scale_v)

        first, middle, last = slice(0, -2), mid, slice(2, None)
        p, q, r = step(first, middle), step(middle, last), 0.5 * step(first, last)
        found = np.maximum(p, q) > SEAM_RATIO * np.minimum(np.minimum(p, q), r) + floor
        np.moveaxis(jump, axis, 0)[mid] |= found
    seam = ~odd & (surface.ravel() >= 0) & jump.ravel()
    return odd | seam, layer, seam


@pytest.mark.parametrize("shape", [(12, 17), (1, 9), (2, 5), (7, 1)])
def test_map_suspects_are_the_numpy_border_fold_layer_and_seam_tests(shape):
    rng = np.random.default_rng(shape[0] * 31 + shape[1])
    surface = np.where(rng.random(shape) < 0.8, 0, rng.integers(-1, 3, size=shape))
    distance = np.where(surface >= 0, 5.0 + rng.normal(scale=0.02, size=shape), np.inf)
    # smooth seeds, a fifth of them on another layer
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    other = rng.random(shape) < 0.2
    u = np.where(surface >= 0, 0.01 * cols + 0.5 * other, np.nan)
    v = np.where(surface >= 0, 0.02 * rows + 0.003 * cols, np.nan)
    domain = np.array([[0.0, 1.0, 0.0, 1.0], [2.0, 5.0, -1.0, 3.0], [0.25, 0.75, 10.0, 10.5]])
    n = surface.size
    hit = (surface.ravel() >= 0) & (rng.random(n) < 0.9)
    t = np.where(hit, distance.ravel() + rng.choice([0.0, 0.1, 0.5, -0.5], size=n), np.nan)
    failed = (surface.ravel() >= 0) & ~hit
    suspect, layer, seam = (np.empty(n, dtype=bool) for _ in range(3))
    for start, stop in ((0, min(3, n)), (min(3, n), n)):
        map_suspects(
            start,
            stop,
            surface,
            distance,
            u,
            v,
            domain,
            hit,
            t,
            failed,
            FOLD_PIXELS * 0.01,
            LAYER_SLACK_PIXELS * 0.01,
            1e-3,
            SEAM_RATIO,
            1e-6,
            suspect,
            layer,
            seam,
        )
    expected_suspect, expected_layer, expected_seam = reference_suspects(
        surface, distance, u, v, domain, hit, t, failed, 0.01, 1e-3, 1e-6
    )
    assert expected_layer.any() and not expected_layer.all()
    if shape == (12, 17):
        assert expected_seam.any()
    np.testing.assert_array_equal(layer, expected_layer)
    np.testing.assert_array_equal(seam, expected_seam)
    np.testing.assert_array_equal(suspect, expected_suspect)


def test_suspects_of_a_hand_worked_map():
    # two surfaces meeting between columns 2 and 3: columns 2 and 3 border;
    # row 2's distance kinks at column 5 (a fold): 1, 1, 1, 1, 1, 2, 1
    surface = np.zeros((5, 7), dtype=np.int64)
    surface[:, 3:] = 1
    distance = np.ones((5, 7))
    distance[2, 5] = 2.0
    prelim_map = prelim.PrelimMap(surface, np.zeros((5, 7)), np.zeros((5, 7)), distance, np.zeros((5, 7, 3), np.uint8))
    hits = Hits.empty(35)
    hits.hit[[0, 6]] = True
    hits.t[[0, 6]] = [1.0 + 0.08, 1.0 + 0.0801]  # slack: 8 footprints at distance 1 = 0.08 (+ tolerance 1e-9)
    failed = np.zeros(35, dtype=bool)
    failed[34] = True
    suspect, layer, seam = suspect_pixels(
        prelim_map, hits, failed, footprint=0.01, tolerance=1e-9, domain=np.array([[0.0, 1.0, 0.0, 1.0]] * 2)
    )
    np.testing.assert_array_equal(np.flatnonzero(layer), [6])
    assert not seam.any()  # (u, v) = (0, 0) everywhere
    expected = np.zeros((5, 7), dtype=bool)
    expected[0, 6] = expected[4, 6] = True  # the wrong layer; the failed start
    expected[:, 2:4] = True
    expected[1:4, 5] = True  # second differences along column 5: 1, -2, 1 (rows 1, 2, 3)
    expected[2, 4] = True  # along row 2 at column 4: 1 (column 6 is an edge: none)
    np.testing.assert_array_equal(suspect.reshape(5, 7), expected)


def test_seams_of_a_hand_worked_map():
    # one surface, seeds u = 0.1 column, v = 0.05 row (domain u 0..2: steps 0.05 and 0.05 normalised),
    # except pixel (2, 3), which shows another layer: u + 1 (0.5 normalised)
    rows, cols = np.mgrid[0:5, 0:7]
    u, v = 0.1 * cols, 0.05 * rows
    u[2, 3] += 1.0
    surface = np.zeros((5, 7), dtype=np.int64)
    prelim_map = prelim.PrelimMap(surface, u, v, np.ones((5, 7)), np.zeros((5, 7, 3), np.uint8))
    hits = Hits.empty(35)
    suspect, layer, seam = suspect_pixels(
        prelim_map,
        hits,
        np.zeros(35, dtype=bool),
        footprint=0.01,
        tolerance=1e-9,
        domain=np.array([[0.0, 2.0, 0.0, 1.0]]),
    )
    expected = np.zeros((5, 7), dtype=bool)
    # (2, 3): steps 0.5 on both sides, 0.05 across them; its four neighbours: 0.5 against 0.05
    expected[2, 2:5] = expected[1:4, 3] = True
    np.testing.assert_array_equal(seam.reshape(5, 7), expected)
    np.testing.assert_array_equal(suspect.reshape(5, 7), expected)
    assert not layer.any()
    # a smooth map with a gentle change of speed (steps 0.05 then 0.15: less than SEAM_RATIO) has none
    u2 = np.where(cols < 3, 0.1 * cols, 0.3 + 0.3 * (cols - 3))
    prelim_map = prelim.PrelimMap(surface, u2, v, np.ones((5, 7)), np.zeros((5, 7, 3), np.uint8))
    _, _, seam = suspect_pixels(
        prelim_map,
        hits,
        np.zeros(35, dtype=bool),
        footprint=0.01,
        tolerance=1e-9,
        domain=np.array([[0.0, 2.0, 0.0, 1.0]]),
    )
    assert not seam.any()


PLATE = parse_scene(
    {
        "film": {"width": 24, "height": 16},
        "camera": {"eye": [0.5, -0.8, 1.5], "look_at": [0.5, 0.5, 0.0], "up": [0, 0, 1]},
        "surface": [
            {
                "degree": [1, 1],
                "knots_u": [0, 0, 1, 1],
                "knots_v": [0, 0, 1, 1],
                "points": [[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]]],
            }
        ],
    },
    "<plate>",
)


@pytest.mark.gl
@pytest.mark.parametrize("mode", ["float", "rgba8"])
def test_map_framebuffers_are_reused_and_give_the_same_map(mode):
    ctx = gl.headless_context()
    patches = PatchSet([s.geometry for s in PLATE.surfaces])
    first = prelim.render_map(patches, PLATE.camera, 24, 16, mode=mode, ctx=ctx)
    kept = dict(ctx.extra["bsrt_kept"])
    second = prelim.render_map(patches, PLATE.camera, 24, 16, mode=mode, ctx=ctx)
    assert (
        ctx.extra["bsrt_kept"][("prelim", (24, 16), "f4" if mode == "float" else "f1")]
        is kept[("prelim", (24, 16), "f4" if mode == "float" else "f1")]
    )
    for name in ("surface", "u", "v", "distance", "picture"):
        np.testing.assert_array_equal(getattr(first, name), getattr(second, name))
    assert (first.surface == 0).sum() > 0.3 * first.surface.size  # the plate fills the lower part of the film


def test_seeded_hits_are_as_hits_put_at_the_covered_pixels():
    from bsrt.rendering.solve import RootResult
    from bsrt.rendering.trace import _seeded_hits

    rng = np.random.default_rng(9)
    n, patch_surface = 5000, np.array([0, 0, 1, 2, 2])
    covered = np.sort(rng.choice(n, size=3000, replace=False))
    m = covered.size
    res = RootResult(
        converged=rng.random(m) < 0.8,
        trimmed=np.zeros(m, dtype=bool),
        u=rng.normal(size=m),
        v=np.where(rng.random(m) < 0.1, -0.0, rng.normal(size=m)),
        patch=rng.integers(0, 5, size=m),
        t=rng.normal(1.0, 1.0, size=m),
        residual=rng.random(m),
        iterations=rng.integers(1, 9, size=m, dtype=np.int32),
    )
    hits, failed = _seeded_hits(n, covered, res, patch_surface)
    expected = Hits.empty(n)

    class Patches:
        surface = patch_surface

    candidates = res.as_hits(Patches)
    expected.put(covered, candidates)
    for name in Hits.FIELDS:
        a, b = getattr(hits, name), getattr(expected, name)
        assert a.dtype == b.dtype, name
        np.testing.assert_array_equal(a, b, err_msg=name)
    assert ((hits.t > 0) | ~hits.hit).all() and 0 < hits.hit.sum() < m
    np.testing.assert_array_equal(np.flatnonzero(failed), covered[~candidates.hit])
    empty, none = _seeded_hits(3, np.zeros(0, dtype=np.int64), res, patch_surface)
    assert not empty.hit.any() and not none.any() and (empty.surface == -1).all() and (empty.iterations == 0).all()


# A bumpy bicubic sheet of 2 x 2 patches under a plate with a square hole (u, v in [0.3, 0.7] removed: its trim is
# the outer square and the inner one), seen at a slant: seeds on both, roots inside the hole that
# the trims remove, silhouettes where seeds fail.
HOLE = (0.3, 0.7)


def _square(lo, hi):
    corners = [[lo, lo], [hi, lo], [hi, hi], [lo, hi], [lo, lo]]
    return [{"degree": 1, "knots": [0, 0, 1, 1], "points": [a, b]} for a, b in zip(corners, corners[1:])]


def _holed_scene():
    sheet = {  # 2 x 2 patches: the plate's patch is 4, its surface 1
        "degree": [3, 3],
        "knots_u": [0, 0, 0, 0, 0.5, 1, 1, 1, 1],
        "knots_v": [0, 0, 0, 0, 0.5, 1, 1, 1, 1],
        "points": [[[x, y, 0.3 * np.sin(3 * x + 2 * y)] for y in np.linspace(-1, 1, 5)] for x in np.linspace(-1, 1, 5)],
    }
    plate = {
        "degree": [1, 1],
        "knots_u": [0, 0, 1, 1],
        "knots_v": [0, 0, 1, 1],
        "points": [[[-0.8, -0.8, 0.5], [-0.8, 0.8, 0.5]], [[0.8, -0.8, 0.5], [0.8, 0.8, 0.5]]],
        "trim": [{"curves": _square(0.0, 1.0)}, {"curves": _square(*HOLE)}],
    }
    return parse_scene(
        {
            "film": {"width": 48, "height": 40},
            "camera": {"eye": [0.4, -2.5, 2.2], "look_at": [0.0, 0.0, 0.2]},
            "light": [{"kind": "ambient", "intensity": 1.0}],
            "surface": [sheet, plate],
        },
        "<holed>",
    )


@pytest.mark.parametrize("method", ["newton", "gradient", "fast"])
def test_the_seeded_solve_into_hits_is_find_roots_then_seeded_hits(ctx, method):
    """trace._solved_seeds (solve_items writing hits) against find_roots of the seeded pixels and
    _seeded_hits of its roots, bit for bit, trimmed roots included."""
    from bsrt.methods import METHODS
    from bsrt.rendering.pipeline import Geometry
    from bsrt.rendering.solve import find_roots
    from bsrt.rendering.trace import _seeded_hits, _solved_seeds

    scene = _holed_scene()
    geometry = Geometry(scene)
    patches, camera, (w, h) = geometry.patches, scene.camera, (scene.film.width, scene.film.height)
    rays = Rays(*pixel_ray_arrays(camera, w, h))
    seeds = prelim.render_map(patches, camera, w, h, ctx=ctx)
    tolerance, stops = 1e-9 * geometry.diagonal, METHODS[method].stops_on_growth
    hits, failed, counts = _solved_seeds(patches, rays, seeds, method, tolerance, 64, stops)
    covered = np.flatnonzero(seeds.surface.ravel() >= 0)
    at = (seeds.surface.ravel()[covered], seeds.u.ravel()[covered], seeds.v.ravel()[covered])
    res = find_roots(patches, rays, covered, *at, method=method, tolerance=tolerance, stop_on_growth=stops)
    want, want_failed = _seeded_hits(len(rays), covered, res, patches.surface)
    for name in Hits.FIELDS:
        a, b = getattr(hits, name), getattr(want, name)
        assert a.dtype == b.dtype, name
        np.testing.assert_array_equal(a, b, err_msg=name)
    np.testing.assert_array_equal(failed, want_failed)
    assert counts == (covered.size, np.count_nonzero(~res.converged), np.count_nonzero(res.trimmed))
    assert counts[2] > 0 and 0 < hits.hit.sum() < covered.size  # roots in the hole, removed by the trims


def test_find_roots_keeps_a_root_exactly_where_the_square_hole_does_not_remove_it():
    """Newton on the plate from starts all over its domain: a converged root counts (converged)
    outside the hole [0.3, 0.7]^2 and is trimmed inside it, by the closed form of the hole."""
    from bsrt.rendering.pipeline import Geometry
    from bsrt.rendering.solve import find_roots

    geometry = Geometry(_holed_scene())
    rng = np.random.default_rng(3)
    n = 4000
    u, v = rng.random(n), rng.random(n)
    target = np.stack([-0.8 + 1.6 * u, -0.8 + 1.6 * v, np.full(n, 0.5)], axis=1)  # the plate at (u, v)
    eye = np.array([0.1, -0.2, 3.0])
    rays = Rays.from_arrays(eye[None, :], target - eye)
    res = find_roots(geometry.patches, rays, np.arange(n), np.ones(n, dtype=np.int64), np.full(n, 0.5), np.full(n, 0.5))
    reached = res.converged | res.trimmed
    assert reached.all()  # a plane: Newton reaches every root from its centre
    inside = (res.u > HOLE[0]) & (res.u < HOLE[1]) & (res.v > HOLE[0]) & (res.v < HOLE[1])
    edge = np.minimum.reduce(
        [np.abs(res.u - HOLE[0]), np.abs(res.u - HOLE[1]), np.abs(res.v - HOLE[0]), np.abs(res.v - HOLE[1])]
    )
    sure = edge > 1e-9
    np.testing.assert_array_equal(res.trimmed[sure], inside[sure])
    np.testing.assert_array_equal(res.converged[sure], ~inside[sure])
    assert 0.1 < inside.mean() < 0.2  # the hole's area, 0.16

"""The GPU solve reading the map where it is drawn (bsrt/rendering/gpu_map.py,
shaders/map_solve.glsl) on a real GL context: Mesa's llvmpipe here and in
CI, never skipped.

The map and the roots it brings back must be exactly what the path through
the CPU gives: render_map's arrays bit for bit (the merge of the triangle and
line passes, eq. 6's decode, the picture), and find_roots_gpu's roots from
those seeds bit for bit (the same shader code, solve_core.glsl, from the same
starts), whatever the map's mode, tiling and dispatch slices.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import bsrt
from bsrt.methods import METHODS
from bsrt.rendering import gpu, gpu_map, prelim
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import Geometry, render
from bsrt.rendering.solve import Rays
from bsrt.scene.camera import pixel_rays
from bsrt.scene.loading import load_input

pytestmark = pytest.mark.gl

ROOT = Path(__file__).resolve().parents[1]
TRIMMED_IGES = ROOT / "tests" / "data" / "iges" / "plane_circle_144.igs"


def _both_paths(path: Path, size: int, mode: str, rows: tuple[int, int], method: str | None = None):
    """(render_map's map, find_roots_gpu's roots of its covered seeds, map_roots_gpu's (map, covered, roots))."""
    scene = load_input(path, width=size, height=size)
    options = RenderOptions.resolve(scene, width=size, height=size, **({"method": method} if method else {}))
    geometry = Geometry(scene)
    patches, camera = geometry.patches, options.camera
    device, ctx = gpu.choose_device("gpu")
    assert device == "gpu"
    solve = (
        options.method,
        options.tolerance * geometry.diagonal,
        options.max_iterations,
        METHODS[options.method].stops_on_growth,
    )
    rays = Rays.from_arrays(camera.eye[None, :], pixel_rays(camera, size, size, rows))
    drawn = prelim.render_map(patches, camera, size, size, mode, ctx=ctx, rows=rows)
    seed = drawn.surface.ravel()
    covered = np.flatnonzero(seed >= 0)
    roots = gpu.find_roots_gpu(
        ctx, patches, rays, covered, seed[covered], drawn.u.ravel()[covered], drawn.v.ravel()[covered],
        method=solve[0], tolerance=solve[1], max_iterations=solve[2], stop_on_growth=solve[3],
    )  # fmt: skip
    in_place = gpu_map.map_roots_gpu(ctx, patches, camera, size, size, rows, rays.direction, mode, *solve)
    assert ctx.error == "GL_NO_ERROR"
    return drawn, covered, roots, in_place


def _assert_same(drawn, covered, roots, in_place) -> None:
    got_map, got_covered, got_roots = in_place
    for name in ("surface", "u", "v", "distance", "picture"):
        np.testing.assert_array_equal(getattr(got_map, name), getattr(drawn, name), err_msg=name)
    np.testing.assert_array_equal(got_covered, covered)
    for name in ("converged", "trimmed", "u", "v", "patch", "t", "residual", "iterations"):
        np.testing.assert_array_equal(getattr(got_roots, name), getattr(roots, name), err_msg=name)


@pytest.mark.parametrize(
    "source, mode, method",
    [
        ("column", "float", None),
        ("water-lily", "rgba8", None),
        ("water-lily", "float", "gradient"),
        ("bench-64", "float", "fast"),
        ("iges-trimmed", "float", None),
    ],
)
def test_the_map_and_roots_in_place_equal_the_read_back_path(source, mode, method):
    path = TRIMMED_IGES if source == "iges-trimmed" else ROOT / "scenes" / f"{source}.toml"
    drawn, covered, roots, in_place = _both_paths(path, 72, mode, (3, 67), method)
    assert covered.size > 500  # the model fills part of the film
    _assert_same(drawn, covered, roots, in_place)


def test_tiles_and_dispatch_slices_change_nothing(monkeypatch):
    """A 72x72 band drawn in 32x32 tiles (9 tiles, the last ones narrower), each
    dispatched in slices of 128 texels: the same map and roots in place as read
    back (a tile's own projection rounds its seeds a little differently from
    the whole film's, on both paths alike)."""
    path = ROOT / "scenes" / "water-lily.toml"
    monkeypatch.setattr(prelim, "TILE", 32)
    monkeypatch.setattr(gpu, "SLICE", 128)
    drawn, covered, roots, in_place = _both_paths(path, 72, "float", (0, 72))
    _assert_same(drawn, covered, roots, in_place)


def test_a_gpu_render_solves_the_map_in_place():
    """device = "gpu" on the map's context: no separate map stage (the map is read
    back with the roots), the stages' devices in the stats, and the same image as
    the CPU path (test_gpu.py's test_device_gpu_renders_as_the_cpu holds the rest)."""
    size = dict(width=40, height=40, spp=1, adaptive_spp=0)
    cpu = bsrt.render(ROOT / "scenes" / "column.toml", device="cpu", **size)
    on_gpu = bsrt.render(ROOT / "scenes" / "column.toml", device="gpu", **size)
    expected = {
        "map": "gl",
        "solve": "gpu",
        "repair": "cpu",
        "shade": "gpu",
        "secondary": "gpu (mirrors), cpu",
    }
    assert on_gpu.stats["devices"] == expected
    assert cpu.stats["devices"]["solve"] == "cpu"
    assert on_gpu.stats["seconds"]["map"] == 0.0 < cpu.stats["seconds"]["map"]
    for name in ("surface", "u", "v", "distance", "picture"):
        np.testing.assert_array_equal(getattr(on_gpu.prelim, name), getattr(cpu.prelim, name), err_msg=name)
    assert np.abs(cpu.pixels.astype(int) - on_gpu.pixels.astype(int)).max() <= 1


def test_a_map_given_by_the_caller_is_solved_from_its_arrays():
    """The preview's solver gets a map drawn elsewhere: the GPU solve takes its
    seeds from the arrays (find_roots_gpu), with the same hits as in place."""
    scene = load_input(ROOT / "scenes" / "quad.toml", width=32, height=32)
    options = RenderOptions.resolve(scene, width=32, height=32, spp=1, adaptive_spp=0, device="gpu")
    first = render(scene, options)
    again = render(scene, options, prelim=first.prelim)
    assert first.stats["seconds"]["map"] == 0.0 and again.stats["devices"]["solve"] == "gpu"
    np.testing.assert_array_equal(again.hits.hit, first.hits.hit)
    np.testing.assert_array_equal(again.hits.t, first.hits.t)

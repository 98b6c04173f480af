"""The GPU path (bsrt/rendering/gpu.py, shaders/solve.glsl) on a real GL context:
Mesa's llvmpipe here and in CI (OpenGL 4.5 core with compute shaders and
float64), a GPU where there is one. Never skipped: ``--device gpu`` runs
the compute shader on llvmpipe too.

- closed forms: rays at a plane and at a rational quarter cylinder, the
  distances known exactly;
- the shader against the CPU kernels (the reference) for every seeded method;
- whole renders with ``device = "gpu"`` against ``device = "cpu"`` on
  scenes/ and a trimmed IGES file: the same hit and surface on every pixel
  away from silhouettes, |dt| <= 1e-9 of the diagonal, images within 1/255;
- the device setting's bad input (an unknown name, a context without
  OpenGL 4.5) as one InputError, exit 2, nothing written; doctor's lines.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import bsrt
from bsrt.errors import InputError
from bsrt.geometry.bspline import make_surface
from bsrt.geometry.patches import PatchSet
from bsrt.methods import MAP_METHODS
from bsrt.rendering import gl, gpu
from bsrt.rendering.hits import away_from_silhouettes
from bsrt.rendering.solve import Rays, find_roots

pytestmark = pytest.mark.gl

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted((ROOT / "scenes").glob("*.toml"))
TRIMMED_IGES = ROOT / "tests" / "data" / "iges" / "plane_circle_144.igs"
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def _context():
    device, ctx = gpu.choose_device("gpu")
    assert device == "gpu"
    return ctx


def test_the_headless_context_offers_compute_and_float64():
    caps = gl.capabilities(gl.headless_context())
    assert caps.version >= 450 and caps.compute and caps.fp64 and caps.missing == []
    if "llvmpipe" in caps.renderer:
        assert not caps.hardware and not gpu.hardware_gpu()
    assert gpu.choose_device("auto") == ("cpu", None)  # the faster path, on llvmpipe and on an H200 alike


def test_plane_hits_are_exact():
    """z = 0 over [-1, 1]^2 (bilinear, u = (x + 1) / 2): rays from (0.1, -0.2, 3)
    at points of the plane; t is the distance to the point, u and v its own."""
    plane = make_surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], [[[-1, -1, 0], [-1, 1, 0]], [[1, -1, 0], [1, 1, 0]]])
    patches = PatchSet([plane])
    rng = np.random.default_rng(3)
    n = 500
    x, y = rng.uniform(-0.9, 0.9, n), rng.uniform(-0.9, 0.9, n)
    origin = np.array([0.1, -0.2, 3.0])
    target = np.stack([x, y, np.zeros(n)], axis=1)
    rays = Rays.from_arrays(origin[None, :], target - origin)
    for method in MAP_METHODS:
        res = gpu.find_roots_gpu(
            _context(), patches, rays, np.arange(n), np.zeros(n, dtype=np.int64), np.full(n, 0.5), np.full(n, 0.5),
            method=method, tolerance=1e-12, max_iterations=200,
        )  # fmt: skip
        assert res.converged.all(), method
        np.testing.assert_allclose(res.t, np.linalg.norm(target - origin, axis=1), rtol=0, atol=1e-12)
        np.testing.assert_allclose(res.u, (x + 1) / 2, rtol=0, atol=1e-12)
        np.testing.assert_allclose(res.v, (y + 1) / 2, rtol=0, atol=1e-12)


def test_rational_quarter_cylinder_hits_are_exact():
    """The quarter cylinder x^2 + y^2 = 1, 0 <= z <= 1 (a rational quadratic
    in u): rays from (0, 0, 0.2) on its axis leaving at slope s reach radius 1
    at t = sqrt(1 + s^2), the height 0.2 + s."""
    w = math.sqrt(0.5)
    points = [[[1, 0, 0], [1, 0, 1]], [[1, 1, 0], [1, 1, 1]], [[0, 1, 0], [0, 1, 1]]]
    cylinder = make_surface((2, 1), [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], points, [[1, 1], [w, w], [1, 1]])
    patches = PatchSet([cylinder])
    rng = np.random.default_rng(4)
    n = 400
    angle, slope = rng.uniform(0.05, math.pi / 2 - 0.05, n), rng.uniform(-0.15, 0.7, n)
    direction = np.stack([np.cos(angle), np.sin(angle), slope], axis=1)
    rays = Rays.from_arrays(np.array([[0.0, 0.0, 0.2]]), direction)
    for method in MAP_METHODS:
        res = gpu.find_roots_gpu(
            _context(), patches, rays, np.arange(n), np.zeros(n, dtype=np.int64), np.full(n, 0.5), np.full(n, 0.5),
            method=method, tolerance=1e-12, max_iterations=200,
        )  # fmt: skip
        assert res.converged.all(), method
        np.testing.assert_allclose(res.t, np.sqrt(1 + slope**2), rtol=0, atol=1e-11)
        np.testing.assert_allclose(res.v, 0.2 + slope, rtol=0, atol=1e-11)


@pytest.mark.parametrize("method", MAP_METHODS)
def test_the_shader_agrees_with_the_cpu_kernels(method):
    """Rays at a wavy bicubic surface with knots of several multiplicities, from
    seeds near and far: the same items converge, to the same t and (u, v)."""
    gx, gy = np.meshgrid(np.linspace(-1, 1, 8), np.linspace(-1, 1, 6), indexing="ij")
    points = np.stack([gx, gy, 0.25 * np.sin(2.5 * gx) * np.cos(2 * gy)], axis=-1)
    wavy = make_surface(
        (3, 3), [0, 0, 0, 0, 0.15, 0.5, 0.5, 0.8, 1, 1, 1, 1], [0, 0, 0, 0, 0.3, 0.6, 1, 1, 1, 1], points
    )
    patches = PatchSet([wavy])
    rng = np.random.default_rng(5)
    n = 2000
    origin = np.array([0.3, 0.2, 3.0])
    target = np.stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), np.zeros(n)], axis=1)
    rays = Rays.from_arrays(origin[None, :], target - origin)
    args = (patches, rays, np.arange(n), np.zeros(n, dtype=np.int64), rng.uniform(0, 1, n), rng.uniform(0, 1, n))
    tol = 1e-9 * patches.scene_diagonal()
    cpu = find_roots(*args, method=method, tolerance=tol, max_iterations=64)
    on_gpu = gpu.find_roots_gpu(_context(), *args, method=method, tolerance=tol, max_iterations=64)
    assert cpu.converged.sum() > n // 2  # far seeds fail sometimes; most converge
    assert (cpu.converged != on_gpu.converged).sum() <= n // 200  # rounding may decide a step at the border
    both = cpu.converged & on_gpu.converged
    assert np.abs(cpu.t[both] - on_gpu.t[both]).max() <= 10 * tol
    assert (cpu.patch[both] != on_gpu.patch[both]).sum() <= n // 200


def test_dispatches_in_slices_give_the_same_answers(monkeypatch):
    """Items solved in slices of 128 (16 dispatches, each with its own buffers) equal one dispatch's."""
    plane = make_surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], [[[-1, -1, 0], [-1, 1, 0]], [[1, -1, 0], [1, 1, 0]]])
    patches = PatchSet([plane])
    rng = np.random.default_rng(8)
    n = 2000
    target = np.stack([rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), np.zeros(n)], axis=1)
    rays = Rays.from_arrays(np.array([[0.0, 0.0, 2.0]]), target - [0.0, 0.0, 2.0])
    args = (patches, rays, np.arange(n), np.zeros(n, dtype=np.int64), rng.uniform(0, 1, n), rng.uniform(0, 1, n))
    whole = gpu.find_roots_gpu(_context(), *args, tolerance=1e-12)
    monkeypatch.setattr(gpu, "SLICE", 128)
    sliced = gpu.find_roots_gpu(_context(), *args, tolerance=1e-12)
    assert whole.converged.all()
    np.testing.assert_array_equal(sliced.t, whole.t)
    np.testing.assert_array_equal(sliced.u, whole.u)
    np.testing.assert_array_equal(sliced.iterations, whole.iterations)


IGES_TRIMMED = [
    ROOT / "tests" / "data" / "iges" / name
    for name in (
        "box_brep.igs",
        "cone_194.igs",
        "cylinder_192.igs",
        "plane_143.igs",
        "plane_circle_144.igs",
        "sphere_torus.igs",
        "surfaces_misc.igs",
    )
]


def test_buffers_are_kept_between_calls_one_set_a_family():
    """gpu.kept_buffers: a call that fits the kept set gets it again (items rounded up to an eighth
    of a power of two, at least 1,024); a larger call replaces it (the smaller set released); sets of other
    families, and other objects gl.keep keeps (the map's framebuffers: one a family too), stay."""

    class Kept:
        released = False

        def release(self):
            self.released = True

    ctx = _context()
    with ctx:
        framebuffers = gl.keep(ctx, ("bsrt_test_passes",), Kept)
        first = gpu.kept_buffers(ctx, "bsrt_test", 1000, (8, 4))
        assert [b.size for b in first] == [8192, 4096]
        assert gpu.kept_buffers(ctx, "bsrt_test", 600, (8, 4)) is first
        other = gpu.kept_buffers(ctx, "bsrt_test_other", 10, (4,))
        bigger = gpu.kept_buffers(ctx, "bsrt_test", 5000, (8, 4))
        assert [b.size for b in bigger] == [8 * 5120, 4 * 5120]  # 5,000 rounded up to 5 x 1,024
        assert all(type(b.mglo).__name__ == "InvalidObject" for b in first)  # released
        assert gpu.kept_buffers(ctx, "bsrt_test", 1000, (8, 4)) is bigger  # it holds them
        assert gpu.kept_buffers(ctx, "bsrt_test_other", 10, (4,)) is other
        assert not framebuffers.released and gl.keep(ctx, ("bsrt_test_passes",), Kept) is framebuffers
        for key in [k for k in ctx.extra["bsrt_kept"] if k[0].startswith("bsrt_test")]:
            ctx.extra["bsrt_kept"].pop(key).release()


@pytest.mark.parametrize("path", IGES_TRIMMED, ids=lambda p: p.stem)
def test_the_float64_trim_test_agrees_with_the_kernels(path):
    """shaders/trim64.glsl against kernels/trim.py's point_kept on random (u, v)
    over each trimmed surface's domain (and a margin outside): both float64,
    the same steps, so the same answer at every point."""
    from bsrt.io import load_model
    from bsrt.kernels.trim import kept_many

    patches = PatchSet(load_model(path).surfaces)
    assert patches.trimmed
    rng = np.random.default_rng(6)
    n = 20000
    m = rng.integers(0, len(patches.surfaces), n)
    d = patches.domain[m]
    u = d[:, 0] + (d[:, 1] - d[:, 0]) * rng.uniform(-0.05, 1.05, n)
    v = d[:, 2] + (d[:, 3] - d[:, 2]) * rng.uniform(-0.05, 1.05, n)
    want = kept_many(patches.trims, m, u, v)
    assert 0 < want.sum() < n  # both answers occur
    np.testing.assert_array_equal(gpu.kept_gpu(_context(), patches, m, u, v), want)


@pytest.mark.parametrize("source", [p.stem for p in SCENES] + ["iges-trimmed"])
def test_device_gpu_renders_as_the_cpu(source):
    path = TRIMMED_IGES if source == "iges-trimmed" else ROOT / "scenes" / f"{source}.toml"
    size = dict(width=48, height=48, spp=1, adaptive_spp=0)
    cpu = bsrt.render(path, device="cpu", **size)
    on_gpu = bsrt.render(path, device="gpu", **size)
    assert cpu.stats["solve_device"] == "cpu" and on_gpu.stats["solve_device"] == "gpu"
    shape = (48, 48)
    hit_c, hit_g = cpu.hits.hit.reshape(shape), on_gpu.hits.hit.reshape(shape)
    surf_c, surf_g = cpu.hits.surface.reshape(shape), on_gpu.hits.surface.reshape(shape)
    inner = away_from_silhouettes(hit_c, surf_c)
    assert hit_c.sum() > 100  # the model fills part of the film
    assert (hit_c == hit_g)[inner].all()
    assert (surf_c == surf_g)[inner & hit_c].all()
    both = (hit_c & hit_g).ravel()
    dt = np.abs(cpu.hits.t[both] - on_gpu.hits.t[both])
    assert dt.max() <= 1e-9 * cpu.geometry.diagonal
    diff = np.abs(cpu.pixels.astype(int) - on_gpu.pixels.astype(int))
    assert diff[inner].max() <= 1


def test_stats_say_which_device_solved(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "bsrt", "render", str(ROOT / "scenes" / "quad.toml"), "--width", "16", "--height",
         "16", "--device", "gpu", "-o", str(tmp_path / "q.png"), "--stats"],
        capture_output=True, text=True, env=ENV, cwd=tmp_path,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["solve_device"] == "gpu"


def test_gpu_on_a_context_without_opengl_4_5_is_one_error_exit_2(tmp_path):
    """Mesa told to offer OpenGL 3.3 only: the map still draws, --device gpu is refused."""
    out = subprocess.run(
        [sys.executable, "-m", "bsrt", "render", str(ROOT / "scenes" / "quad.toml"), "--width", "16", "--height",
         "16", "--device", "gpu", "-o", str(tmp_path / "q.png")],
        capture_output=True, text=True, env={**ENV, "MESA_GL_VERSION_OVERRIDE": "3.3"}, cwd=tmp_path,
    )  # fmt: skip
    assert out.returncode == 2
    assert "render.device: gpu needs OpenGL 4.5 (the context is 3.3)" in out.stderr
    assert "Traceback" not in out.stderr
    assert list(tmp_path.iterdir()) == []


def test_an_unknown_device_is_one_error(tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text((ROOT / "scenes" / "quad.toml").read_text().replace("[render]", '[render]\ndevice = "tpu"', 1))
    assert 'device = "tpu"' in scene.read_text()
    out = subprocess.run(
        [sys.executable, "-m", "bsrt", "render", str(scene), "-o", str(tmp_path / "q.png")],
        capture_output=True, text=True, env=ENV, cwd=tmp_path,
    )  # fmt: skip
    assert out.returncode == 2
    assert "render.device" in out.stderr and "tpu" in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "q.png").exists()
    with pytest.raises(InputError, match="device"):
        bsrt.render(ROOT / "scenes" / "quad.toml", device="tpu", width=8, height=8)


def test_egl_devices_are_named():
    """EGL device descriptions from the strings the driver gives (what doctor lists)."""
    nvidia = {0x3055: b"EGL_NV_device_cuda EGL_EXT_device_drm", 0x3233: None}
    assert gl._describe_device(nvidia.get) == "NVIDIA (CUDA device)"
    named = {0x3055: b"EGL_EXT_device_query_name EGL_EXT_device_drm", 0x3053: b"NVIDIA", 0x335F: b"NVIDIA H200",
             0x3233: b"/dev/dri/card1"}  # fmt: skip
    assert (
        gl._describe_device(named.get) == "NVIDIA H200 (/dev/dri/card1)"
    )  # the vendor once (an H200 machine said it twice)
    other = {0x3055: b"EGL_EXT_device_query_name", 0x3053: b"AMD", 0x335F: b"Radeon RX 7900 XTX"}
    assert gl._describe_device(other.get) == "AMD Radeon RX 7900 XTX"
    mesa = {0x3055: b"EGL_MESA_device_software"}
    assert gl._describe_device(mesa.get) == "software (Mesa llvmpipe)"
    assert gl._describe_device({}.get) == "unknown device"
    assert all(name != "unknown device" for name in gl.egl_devices())


@pytest.mark.gl
def test_loading_the_driver_ahead_of_the_context_fails_quietly_and_the_context_follows(monkeypatch):
    """gl.load_driver (a render's head start on a thread) never raises: a device that does not
    exist or a bad name is left to the context's own creation to report."""
    for chosen in ("4096", "abc", None):
        if chosen is None:
            monkeypatch.delenv("BSRT_EGL_DEVICE", raising=False)
        else:
            monkeypatch.setenv("BSRT_EGL_DEVICE", chosen)
        gl.load_driver()
    ctx = gl.create_headless_context()
    try:
        assert ctx.version_code >= gl.GL_VERSION
    finally:
        ctx.release()


@pytest.mark.dask
@pytest.mark.parametrize("command", ["batch", "animate"])
def test_batch_and_animate_refuse_gpu_without_opengl_4_5_before_any_item(tmp_path, command):
    args = [sys.executable, "-m", "bsrt", command, str(ROOT / "scenes" / "quad.toml"), "--out", str(tmp_path / "out")]
    args += ["--frames", "2"] if command == "animate" else []
    out = subprocess.run(
        args + ["--device", "gpu", "--width", "16", "--height", "16"],
        capture_output=True, text=True, env={**ENV, "MESA_GL_VERSION_OVERRIDE": "3.3"}, cwd=tmp_path,
    )  # fmt: skip
    assert out.returncode == 2, out.stderr
    assert "render.device: gpu needs OpenGL 4.5" in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "out").exists()

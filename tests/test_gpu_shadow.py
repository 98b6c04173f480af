"""Shadow and mirror rays and the lighting on the GPU (bsrt/rendering/gpu_shade.py,
gpu_lighting.py, shaders/anyhit.glsl) on a real GL context: Mesa's llvmpipe here and in CI,
never skipped.

- a closed form: a square plane above a larger one, rays straight up from the
  lower one: blocked exactly under the square and below its height;
- the any-hit walk against the CPU's (bvh.intersect with any_hit, the walk of
  kernels/lighting.py) on shadow rays from every hit of scenes/ and trimmed
  IGES files toward their lights: the same answer for every ray, grazing ones
  included (the start's piece or quarter skipped where the ray crosses it at
  most once: crossings.py, ported to anyhit.glsl).
- mirror rays (shaders/nearest.glsl, the nearest-hit walk) from the same hits:
  the CPU's nearest hits, with the same Newton iterations;
- the lighting (shade.glsl) and the mirror chain (bounce.glsl, mix.glsl) against
  the CPU's shading, the hits a walk leaves unsettled on llvmpipe shaded there.

Bit for bit on llvmpipe; on a GPU, whose compiler may fuse multiply-adds, within a few
roundings (_same_steps).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import bsrt
from bsrt.geometry.bspline import make_surface
from bsrt.geometry.patches import PatchSet
from bsrt.rendering import gl, gpu, gpu_lighting, gpu_shade
from bsrt.rendering.bvh import build_bvh
from bsrt.rendering.shade import facing_frames, light_arrays
from bsrt.scene.camera import pixel_rays
from bsrt.scene.parse import parse_scene

pytestmark = pytest.mark.gl

ROOT = Path(__file__).resolve().parents[1]
IGES = ROOT / "tests" / "data" / "iges"
SOURCES = [ROOT / "scenes" / f"{name}.toml" for name in ("column", "water-lily", "quad")] + [
    IGES / "plane_circle_144.igs",
    IGES / "sphere_torus.igs",
]


def _context():
    device, ctx = gpu.choose_device("gpu")
    assert device == "gpu"
    return ctx


def _same_steps() -> bool:
    """Whether the shaders take the kernels' float64 steps bit for bit on this context: on a
    software renderer (llvmpipe: no fused multiply-add), yes; a GPU's compiler may fuse a * b + c
    into one rounding (measured on an NVIDIA H200, 2026-11-26: normals up to 5.6e-16 apart, one
    mirror ray of 4,088 taking one Newton iteration more, one AO render's mirror rays 630 against
    629), so there the tests allow a few roundings' difference."""
    with _context() as ctx:
        return not gl.capabilities(ctx).hardware


def _agree(got, want, err_msg: str = "", scale: float = 1.0) -> None:
    """got equals want bit for bit where the steps are the kernels' (_same_steps), else within
    1e-12 relative or 1e-13 * scale absolute (NaN where want is NaN)."""
    if _same_steps():
        np.testing.assert_array_equal(got, want, err_msg=err_msg)
    else:
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-13 * scale, err_msg=err_msg)


def test_a_software_renderer_runs_workgroups_of_one():
    ctx = _context()
    with ctx:
        caps = gl.capabilities(ctx)
        assert gpu.group_size(ctx) == (gpu.GROUP if caps.hardware else 1)


def _plane(half: float, z: float):
    """The square [-half, half]^2 at height z, bilinear."""
    corners = [[[-half, -half, z], [-half, half, z]], [[half, -half, z], [half, half, z]]]
    return make_surface((1, 1), [0, 0, 1, 1], [0, 0, 1, 1], corners)


def test_a_square_shadows_the_plane_under_it():
    """Rays straight up from the plane z = 0 (its surface 0, excluded at the start)
    meet the square |x|, |y| <= 0.5 at z = 1: blocked under it (away from its
    edges) when t_max > 1, never beside it nor when t_max < 1."""
    bvh = build_bvh(PatchSet([_plane(2.0, 0.0), _plane(0.5, 1.0)]))
    rng = np.random.default_rng(11)
    n = 4000
    xy = rng.uniform(-1.5, 1.5, (n, 2))
    xy = xy[np.abs(np.abs(xy) - 0.5).min(axis=1) > 1e-3]  # away from the square's edges
    n = xy.shape[0]
    origins = np.column_stack([xy, np.zeros(n)])
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    exclude = (np.zeros(n, dtype=np.int64), (xy[:, 0] + 2) / 4, (xy[:, 1] + 2) / 4, np.full(n, 1e-6), np.full(n, 1e-6))
    under = (np.abs(xy) < 0.5).all(axis=1)
    assert 0 < under.sum() < n
    for t_max, want in ((np.inf, under), (5.0, under), (0.9, np.zeros(n, dtype=bool))):
        blocked, exhausted, iterations = gpu_shade.occluded_gpu(_context(), bvh, origins, up, t_max, 1e-9, exclude)
        np.testing.assert_array_equal(blocked, want)
        assert not exhausted.any()
        assert (iterations[blocked] > 0).all()
    assert _context().error == "GL_NO_ERROR"


def _starts(geometry, hits, rays):
    """(position (H, 3), normal (H, 3) facing the ray, exclusion: 5 (H,) arrays) of the H hits
    of hits (of the camera rays along rays (K, 3)), as rendering/pipeline.py's shading has them
    for the secondary rays it sends."""
    position, normal, speed = facing_frames(geometry.patches, hits, rays)
    h = np.flatnonzero(hits.hit)
    eps = 1e-6 * geometry.diagonal
    bounds = geometry.patches.arrays.bounds[hits.patch[h]]
    with np.errstate(divide="ignore"):
        ru = np.minimum(np.where(speed[h, 0] > 0, eps / speed[h, 0], np.inf), 0.25 * (bounds[:, 1] - bounds[:, 0]))
        rv = np.minimum(np.where(speed[h, 1] > 0, eps / speed[h, 1], np.inf), 0.25 * (bounds[:, 3] - bounds[:, 2]))
    return position[h], normal[h], (hits.surface[h], hits.u[h], hits.v[h], ru, rv)


def _shadow_rays(geometry, hits, rays, lights):
    """Per non-ambient light: (origins, directions, t_max, exclusion) of the shadow rays
    that hits (of the camera rays along rays (K, 3)) send (the points facing the light),
    as rendering/pipeline.py's shading sends them."""
    position, normal, exclusion = _starts(geometry, hits, rays)
    kind, light_position, light_direction, _ = light_arrays(lights)
    for j in np.flatnonzero(kind != 0):
        if kind[j] == 1:
            to_light = light_position[j] - position
            t_max = np.linalg.norm(to_light, axis=1)
            to_light = to_light / t_max[:, None]
        else:
            to_light, t_max = np.tile(light_direction[j], (position.shape[0], 1)), np.full(position.shape[0], np.inf)
        face = np.einsum("ij,ij->i", normal, to_light) > 0
        yield position[face], to_light[face], t_max[face], tuple(a[face] for a in exclusion)


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.stem)
def test_shadow_rays_agree_with_the_cpu_walk(path):
    scene = bsrt.load(path)
    result = bsrt.render(scene, width=64, height=64, spp=1, adaptive_spp=0, device="cpu")
    geometry = result.geometry
    tolerance = result.options.tolerance * geometry.diagonal
    rays = 0
    h, w = result.pixels.shape[:2]
    camera_rays = pixel_rays(result.options.camera, w, h)
    for origins, directions, t_max, exclusion in _shadow_rays(geometry, result.hits, camera_rays, scene.lights):
        cpu = geometry.intersect(
            origins, directions, t_min=0.0, t_max=t_max, tolerance=tolerance, exclude=exclusion, any_hit=True
        )
        blocked, exhausted, _ = gpu_shade.occluded_gpu(
            _context(), geometry.bvh, origins, directions, t_max, tolerance, exclusion
        )
        np.testing.assert_array_equal(blocked, cpu.hit)
        assert not exhausted.any()
        rays += origins.shape[0]
    assert rays > 1000
    assert _context().error == "GL_NO_ERROR"


def _look(scene, options):
    """shade_hits' (materials, lights, background), as rendering/pipeline.py passes them."""
    materials = (
        np.array([m.color for m in scene.materials], dtype=np.float64).reshape(-1, 3),
        np.array([m.specular for m in scene.materials], dtype=np.float64),
        np.array([m.shininess for m in scene.materials], dtype=np.float64),
    )
    background = np.array(options.background, dtype=np.float64).reshape(3)
    return materials, light_arrays(scene.lights), background


LIGHTING_CASES = [(p, 64) for p in SOURCES + [ROOT / "scenes" / "bench-64.toml"]] + [
    (ROOT / "scenes" / "column.toml", 160)
]


@pytest.mark.parametrize("path, size", LIGHTING_CASES, ids=lambda c: getattr(c, "stem", str(c)))
def test_the_lighting_shader_agrees_with_the_kernel(path, size):
    """shade.glsl against kernels/lighting.py's shade_hits on every pixel of a render:
    the same frames and exclusion boxes (bit for bit: the same float64 steps), the
    same shadow rays per hit, colours within 1e-12 relative (the specular power by
    squaring, not pow: GLSL has none in float64), the 8-bit image within 1/255. The
    column at 160 x 160 holds the hits where llvmpipe's SIMD lanes got mixed up
    (gpu.group_size)."""
    from bsrt.kernels.lighting import shade_hits
    from bsrt.kernels.threads import run_chunks
    from bsrt.rendering.bvh import DEFAULT_RETRY_DEPTH, ray_budget
    from bsrt.rendering.image import srgb_encode

    scene = bsrt.load(path)
    result = bsrt.render(scene, width=size, height=size, spp=1, adaptive_spp=0, device="cpu")
    geometry, hits, bvh = result.geometry, result.hits, result.geometry.bvh
    directions = np.ascontiguousarray(pixel_rays(result.options.camera, size, size))
    materials, lights, background = _look(scene, result.options)
    tolerance, eps, n = result.options.tolerance * geometry.diagonal, 1e-6 * geometry.diagonal, len(hits)

    def outputs():
        return tuple(np.empty(s) for s in ((n, 3), (n, 3), (n, 3), (n, 2))) + (
            np.empty(n, dtype=np.int64),
            np.empty(n, dtype=np.int64),
        )

    cpu, on_gpu = outputs(), outputs()
    run_chunks(
        shade_hits, n, geometry.patches.arrays, geometry.patches.trims, bvh.arrays, hits.hit, hits.patch,
        hits.surface, hits.u, hits.v, directions, geometry.material, *materials, *lights, background, eps,
        float(tolerance), 16, DEFAULT_RETRY_DEPTH, bvh.padding + float(tolerance), ray_budget(16), bvh.packet_spread,
        *cpu,
    )  # fmt: skip
    gpu_lighting.shade_hits_gpu(
        _context(), bvh, hits, directions, geometry.material, materials, lights, background, eps, tolerance, 16, on_gpu
    )
    assert _context().error == "GL_NO_ERROR"
    for name, want, got in zip(("position", "normal", "radius"), cpu[1:4], on_gpu[1:4]):
        _agree(got, want, name, scale=geometry.diagonal)
    for name, want, got in zip(("shadow_rays", "exhausted"), cpu[4:], on_gpu[4:]):
        np.testing.assert_array_equal(got, want, err_msg=name)
    assert cpu[4].sum() > 1000  # shadow rays were traced
    np.testing.assert_allclose(on_gpu[0], cpu[0], rtol=1e-12, atol=1e-15)
    assert np.abs(srgb_encode(on_gpu[0]).astype(int) - srgb_encode(cpu[0]).astype(int)).max() <= 1


def test_geometry_intersect_on_the_gpu_is_the_cpus():
    """Geometry.intersect(gpu=ctx), as a GPU render traces its mirror rays: camera rays through
    the column, not of unit length, give the CPU's nearest hits (hit, surface, iterations; t and
    u as test_mirror_rays_find_the_cpus_nearest_hits holds them) and the same count of rays out
    of budget; any_hit or a budget other than the shader's is a ValueError."""
    from bsrt.rendering.pipeline import Geometry

    geometry = Geometry(bsrt.load(ROOT / "scenes" / "column.toml"))
    rng = np.random.default_rng(5)
    eye = np.array([[0.3, -6.0, 2.0]])
    directions = np.column_stack([rng.uniform(-0.4, 0.4, 3000), np.full(3000, 1.0), rng.uniform(-0.5, 0.3, 3000)])
    directions *= rng.uniform(0.5, 3.0, (3000, 1))  # intersect normalises them
    tolerance = 1e-9 * geometry.diagonal
    before = geometry.out_of_budget
    cpu = geometry.intersect(eye, directions, tolerance=tolerance)
    spent = geometry.out_of_budget - before
    on_gpu = geometry.intersect(eye, directions, tolerance=tolerance, gpu=_context())
    assert geometry.out_of_budget - before == 2 * spent
    np.testing.assert_array_equal(on_gpu.hit, cpu.hit)
    assert 100 < cpu.hit.sum() < 2900
    for name in ("surface", "patch") + (("iterations",) if _same_steps() else ()):
        np.testing.assert_array_equal(getattr(on_gpu, name), getattr(cpu, name), err_msg=name)
    both = cpu.hit
    assert (np.abs(on_gpu.t[both] - cpu.t[both]) <= 1e-12 * geometry.diagonal).all()
    np.testing.assert_allclose(on_gpu.u[both], cpu.u[both], rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="budget"):
        geometry.intersect(eye, directions[:3], tolerance=tolerance, budget=7, gpu=_context())
    with pytest.raises(ValueError, match="any-hit"):
        geometry.intersect(eye, directions[:3], tolerance=tolerance, any_hit=True, gpu=_context())
    assert _context().error == "GL_NO_ERROR"


def test_dispatch_slices_change_nothing(monkeypatch):
    """Shading (direct, and with the mirror chain), shadow rays and mirror rays dispatched in slices
    of 1,000 (the last one shorter; the slices' buffers written and read again, the outputs read
    straight into their rows): the same outputs bit for bit as in one dispatch, the same hits left
    to the CPU; and the shading without its frames read back."""
    path = ROOT / "scenes" / "water-lily.toml"
    scene = bsrt.load(path)
    result = bsrt.render(scene, width=64, height=64, spp=1, adaptive_spp=0, device="cpu")
    geometry, hits, bvh = result.geometry, result.hits, result.geometry.bvh
    directions = np.ascontiguousarray(pixel_rays(result.options.camera, 64, 64))
    materials, lights, background = _look(scene, result.options)
    tolerance, eps, n = result.options.tolerance * geometry.diagonal, 1e-6 * geometry.diagonal, len(hits)
    origins, rays, t_max, exclusion = next(_shadow_rays(geometry, hits, directions, scene.lights))
    reflectance = np.array([m.reflectance for m in scene.materials])[geometry.material]

    def everything():
        out = tuple(np.empty(s) for s in ((n, 3), (n, 3), (n, 3), (n, 2))) + (
            np.empty(n, dtype=np.int64),
            np.empty(n, dtype=np.int64),
        )
        gpu_lighting.shade_hits_gpu(
            _context(), bvh, hits, directions, geometry.material, materials, lights, background, eps, tolerance, 16, out
        )
        chain, reflections, again = tuple(np.empty_like(a) for a in out), np.empty(n, dtype=np.int64), []
        gpu_lighting.shade_hits_gpu(
            _context(), bvh, hits, directions, geometry.material, materials, lights, background, eps, tolerance, 16,
            chain, reflectance=reflectance, max_depth=3, reflections=reflections, redo=again.append,
        )  # fmt: skip
        shadow = gpu_shade.occluded_gpu(_context(), bvh, origins, rays, t_max, tolerance, exclusion)
        mirror = gpu_shade.nearest_gpu(_context(), bvh, origins, rays, 0.0, np.inf, tolerance, exclusion)
        mirrored = (reflections,) + tuple(np.delete(a, np.concatenate([[], *again]).astype(int), 0) for a in chain)
        return (
            out + mirrored + shadow + tuple(getattr(mirror, f) for f in ("hit", "t", "u", "v", "patch", "iterations"))
        )

    whole = everything()
    monkeypatch.setattr(gpu, "SLICE", 1000)
    assert gpu.dispatch_size(_context()) == 1000 and n > 4000 and origins.shape[0] > 1000
    sliced = everything()
    for a, b in zip(whole, sliced):
        np.testing.assert_array_equal(a, b)
    assert whole[6].sum() > 1000  # the water sent mirror rays
    # without the frames (a caller with no mirrors, occlusion or AOVs): the same colours and counts
    colour, shadow_rays, exhausted = np.empty((n, 3)), np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    gpu_lighting.shade_hits_gpu(
        _context(), bvh, hits, directions, geometry.material, materials, lights, background, eps, tolerance, 16,
        (colour, None, None, None, shadow_rays, exhausted),
    )  # fmt: skip
    for a, b in zip((colour, shadow_rays, exhausted), (whole[0], whole[4], whole[5])):
        np.testing.assert_array_equal(a, b)
    assert _context().error == "GL_NO_ERROR"


@pytest.mark.parametrize(
    "extra",
    [
        {},
        {"max_depth": 1},
        {"max_depth": 0},
        {"ao": True, "ground": True},
        {"ao": True, "ground": True, "adaptive_spp": 4},
    ],
    ids=["mirrors", "one-bounce", "no-bounce", "ao-ground", "ao-ground-adaptive"],
)
def test_a_gpu_render_shades_as_the_cpu(extra):
    """The column (a mirror among its materials) rendered with device = "gpu": the
    direct lighting and the mirror chain on the GPU (3 bounces, 1, none), ambient occlusion
    and the ground's contact shadow on the CPU from its positions, normals and exclusion
    boxes: the same image within 1/255 (the same hits everywhere away from silhouettes:
    test_gpu.py) and the same counts, with adaptive anti-aliasing too (its extra camera rays
    on the CPU's walk: shade.GPU_SECONDARY says why)."""
    size = {**dict(width=48, height=48, spp=1, adaptive_spp=0), **extra}
    path = ROOT / "scenes" / "column.toml"
    cpu = bsrt.render(path, device="cpu", **size)
    on_gpu = bsrt.render(path, device="gpu", **size)
    assert on_gpu.stats["devices"]["shade"] == "gpu" and cpu.stats["devices"]["shade"] == "cpu"
    assert on_gpu.stats["devices"]["secondary"] == "gpu (mirrors), cpu" and cpu.stats["devices"]["secondary"] == "cpu"
    assert on_gpu.stats["shadow_rays"] == cpu.stats["shadow_rays"] > 1000
    gpu_rays, cpu_rays = on_gpu.stats["reflection_rays"], cpu.stats["reflection_rays"]
    assert (cpu_rays > 0) == (extra.get("max_depth") != 0)
    assert gpu_rays == cpu_rays if _same_steps() else abs(gpu_rays - cpu_rays) <= 0.01 * cpu_rays
    np.testing.assert_array_equal(on_gpu.hits.hit, cpu.hits.hit)
    apart = np.abs(on_gpu.pixels.astype(int) - cpu.pixels.astype(int)).max(axis=-1)
    if _same_steps():  # the mirror chain's colours mixed as the CPU's (the specular power a few ulps apart)
        np.testing.assert_allclose(on_gpu.linear, cpu.linear, rtol=1e-10, atol=1e-14)
        assert apart.max() <= 1
    else:  # a last bit apart can turn a mirror ray grazing a reflected silhouette (H200: 1 pixel of 2,304)
        assert (apart > 1).sum() <= 1 + apart.size // 1000


def _strips_under_a_light(mirror_floor: bool = False):
    """20 flat bicubic strips in the plane x = 0.5 (y in [-1, 1], z in [0.1 j, 0.1 j + 0.05]), a
    floor patch at z = -0.01 round the origin, a point light straight above it at z = 100, a
    camera looking down at the floor from the side: the floor's shadow ray runs up the z axis,
    0.5 from every strip, and meets none. mirror_floor: the floor reflects (half), an ambient
    light replaces the point light (no shadow rays) and the camera looks down from higher up:
    the floor's mirror rays rise through the strips' plane."""
    knots = [0, 0, 0, 0, 1, 1, 1, 1]
    strips = [
        {
            "degree": [3, 3],
            "knots_u": knots,
            "knots_v": knots,
            "points": [[[0.5, y, z] for z in np.linspace(0.1 * j, 0.1 * j + 0.05, 4)] for y in np.linspace(-1, 1, 4)],
        }
        for j in range(20)
    ]
    floor = {
        "degree": [1, 1],
        "knots_u": [0, 0, 1, 1],
        "knots_v": [0, 0, 1, 1],
        "points": [[[-0.2, -0.2, -0.01], [-0.2, 0.2, -0.01]], [[0.2, -0.2, -0.01], [0.2, 0.2, -0.01]]],
    }
    return parse_scene(
        {
            "film": {"width": 8, "height": 8},
            "camera": {
                "eye": [-1.0, 0.0, 1.2] if mirror_floor else [-3.0, 0.0, 0.5],
                "look_at": [0.0, 0.0, -0.01],
                "up": [0.0, 0.0, 1.0],
                "fov": 30.0,
            },
            "material": [
                {"name": "grey", "color": [0.6, 0.6, 0.6]},
                {"name": "floor", "color": [0.6, 0.6, 0.6], "reflectance": 0.5 if mirror_floor else 0.0},
            ],
            "light": [
                {"kind": "ambient", "intensity": 0.5}
                if mirror_floor
                else {"kind": "point", "position": [0.0, 0.0, 100.0], "intensity": 10000.0}
            ],
            "surface": [dict(floor, material="floor")] + [dict(strip, material="grey") for strip in strips],
        }
    )


def test_a_walk_past_llvmpipes_loop_limit_is_finished_on_the_cpu(monkeypatch):
    """A shadow ray up the z axis past 20 strips, each of whose boxes (padded by 1 here) holds it:
    the walk solves every strip, and on the CPU spends its Newton budget (taken as lit). On
    llvmpipe the walk runs into Mesa's loop limiter (anyhit.glsl's head) first, so the shader
    leaves the ray unsettled (-3): the host traces it on the CPU, and re-shades its hit with the
    CPU kernel; the answers are the CPU's, and the host is seen to take both of those ways. Until
    2026-11-25 the shader trusted a blocker it found after the limiter had cut its loops short:
    here it answered blocked (941 iterations) where the CPU finds no blocker. (On a GPU, which has
    no such limiter, nothing is re-traced.)"""
    from bsrt.kernels.lighting import shade_hits
    from bsrt.kernels.threads import run_chunks
    from bsrt.rendering.bvh import DEFAULT_RETRY_DEPTH, ray_budget
    from bsrt.rendering.options import RenderOptions
    from bsrt.rendering.pipeline import Geometry

    retraced, reshaded = [], []
    spy_intersect, spy_run_chunks = gpu_shade.intersect, gpu_lighting.run_chunks
    monkeypatch.setattr(
        gpu_shade, "intersect", lambda bvh, o, *a, **k: retraced.append(len(o)) or spy_intersect(bvh, o, *a, **k)
    )
    monkeypatch.setattr(
        gpu_lighting, "run_chunks", lambda f, n, *a, **k: reshaded.append(n) or spy_run_chunks(f, n, *a, **k)
    )
    scene = _strips_under_a_light()
    options = RenderOptions.resolve(scene)
    geometry = Geometry(scene)
    geometry._bvh = build_bvh(geometry.patches, padding=1.0)
    tolerance = options.tolerance * geometry.diagonal
    camera_rays = np.array([[3.0, 0.0, -0.51]]) / np.linalg.norm([3.0, 0.0, -0.51])  # the eye to the floor's centre
    hits = geometry.intersect(np.asarray(options.camera.eye)[None, :], camera_rays, tolerance=tolerance)
    assert hits.hit.all() and hits.surface[0] == 0
    origins, directions, t_max, exclusion = next(_shadow_rays(geometry, hits, camera_rays, scene.lights))
    cpu = geometry.intersect(origins, directions, t_max=t_max, tolerance=tolerance, exclude=exclusion, any_hit=True)
    blocked, exhausted, iterations = gpu_shade.occluded_gpu(
        _context(), geometry.bvh, origins, directions, t_max, tolerance, exclusion
    )
    with _context() as ctx:
        limited = [] if gl.capabilities(ctx).hardware else [1]  # a GPU has no loop limiter
    assert len(origins) == 1 and not cpu.hit.any() and cpu.iterations[0] >= ray_budget()  # lit, budget spent
    assert retraced == limited and not blocked.any() and exhausted.all() and iterations[0] == cpu.iterations[0]
    materials, lights, background = _look(scene, options)
    n, bvh, eps = 1, geometry.bvh, 1e-6 * geometry.diagonal
    want, got = (
        tuple(np.empty(s) for s in ((n, 3), (n, 3), (n, 3), (n, 2))) + tuple(np.empty(n, dtype=np.int64) for _ in "ab")
        for _ in "ab"
    )
    run_chunks(
        shade_hits, n, geometry.patches.arrays, geometry.patches.trims, bvh.arrays, hits.hit, hits.patch, hits.surface,
        hits.u, hits.v, camera_rays, geometry.material, *materials, *lights, background, eps, float(tolerance), 16,
        DEFAULT_RETRY_DEPTH, bvh.padding + float(tolerance), ray_budget(16), bvh.packet_spread, *want,
    )  # fmt: skip
    gpu_lighting.shade_hits_gpu(
        _context(), bvh, hits, camera_rays, geometry.material, materials, lights, background, eps, tolerance, 16, got
    )
    assert reshaded == limited  # the hit whose shadow ray the shader left unsettled, shaded by the CPU kernel
    assert want[5][0] == 1  # its shadow ray spent its budget: lit
    for a, b in zip(want, got):
        _agree(b, a, scale=geometry.diagonal)


def test_a_mirror_chain_past_llvmpipes_loop_limit_is_shaded_on_the_cpu(monkeypatch):
    """The strips over a mirror floor (lit by an ambient light only: no shadow rays), their boxes
    padded so that every mirror ray from the floor solves every strip: on llvmpipe those walks run
    into the loop limiter, and the pixels whose mirror chain the GPU left unsettled are shaded
    again, whole, on the CPU (rendering/shade.py's Shader._shade_cpu; on a GPU none are). The render
    on the GPU path, with ambient occlusion (traced between the GPU's first level and the bounce,
    and again for the pixels shaded again: counted once), gives the CPU path's colours (to a few
    roundings: the specular power) and the same counts of mirror, occlusion and out-of-budget rays."""
    from bsrt.rendering import pipeline, shade
    from bsrt.rendering.options import RenderOptions
    from bsrt.rendering.pipeline import Geometry

    scene = _strips_under_a_light(mirror_floor=True)
    results, again = {}, []
    spy = shade.Shader._shade_cpu
    for device in ("cpu", "gpu"):
        geometry = Geometry(scene)
        geometry._bvh = build_bvh(geometry.patches, padding=1.0)
        options = RenderOptions.resolve(scene, width=12, height=12, adaptive_spp=0, ao=True, device=device)
        if device == "gpu":
            monkeypatch.setattr(
                shade.Shader,
                "_shade_cpu",
                lambda self, hits, *a, **k: again.append(len(hits)) or spy(self, hits, *a, **k),
            )
        results[device] = pipeline.render(scene, options, geometry=geometry)
    cpu, on_gpu = results["cpu"], results["gpu"]
    floor = cpu.hits.hit & (cpu.hits.surface == 0)
    assert floor.sum() >= 4 and cpu.stats["reflection_rays"] == floor.sum() and cpu.stats["shadow_rays"] == 0
    assert cpu.stats["ao_rays"] >= 16 * floor.sum()
    for key in ("reflection_rays", "out_of_budget", "shadow_rays", "ao_rays", "hits"):
        assert on_gpu.stats[key] == cpu.stats[key], key
    with _context() as ctx:
        software = not gl.capabilities(ctx).hardware
    assert (len(again) > 0) == software  # the depth-0 re-shadings (their mirror rays recurse: more calls)
    np.testing.assert_allclose(on_gpu.linear, cpu.linear, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: p.stem)
def test_mirror_rays_find_the_cpus_nearest_hits(path):
    """Every hit of a 64 x 64 render sends a mirror ray (reflected about its normal, its start
    excluded, as rendering/pipeline.py's bounce): shaders/nearest.glsl's walk gives the CPU's
    nearest hit (bvh.intersect): the same hit or miss, surface and patch, t within 1e-12 of the
    diagonal, the same Newton iterations (the same walk and per-piece solve)."""
    scene = bsrt.load(path)
    result = bsrt.render(scene, width=64, height=64, spp=1, adaptive_spp=0, device="cpu")
    geometry = result.geometry
    h, w = result.pixels.shape[:2]
    camera_rays = pixel_rays(result.options.camera, w, h)
    position, normal, exclusion = _starts(geometry, result.hits, camera_rays)
    d = camera_rays[result.hits.hit]
    mirror = d - 2.0 * np.einsum("ij,ij->i", d, normal)[:, None] * normal
    mirror /= np.linalg.norm(mirror, axis=1)[:, None]
    tolerance = result.options.tolerance * geometry.diagonal
    cpu = geometry.intersect(position, mirror, t_min=0.0, tolerance=tolerance, exclude=exclusion)
    got = gpu_shade.nearest_gpu(_context(), geometry.bvh, position, mirror, 0.0, np.inf, tolerance, exclusion)
    assert _context().error == "GL_NO_ERROR"
    assert cpu.hit.any() == (path.stem != "quad") and not cpu.hit.all()  # a plane never sees itself
    for name in ("hit", "surface", "patch"):
        np.testing.assert_array_equal(getattr(got, name), getattr(cpu, name), err_msg=name)
    if _same_steps():
        np.testing.assert_array_equal(got.iterations, cpu.iterations)
    else:  # a last bit apart may take one Newton step more or less
        apart = np.abs(got.iterations - cpu.iterations)
        assert apart.max() <= 1 and (apart > 0).sum() <= 0.001 * len(apart) + 1
    both = cpu.hit
    assert (np.abs(got.t[both] - cpu.t[both]) <= 1e-12 * geometry.diagonal).all()
    np.testing.assert_allclose(got.u[both], cpu.u[both], rtol=0, atol=1e-9)
    np.testing.assert_allclose(got.v[both], cpu.v[both], rtol=0, atol=1e-9)

"""Colour from hits: exact normals, the lights as the shading kernels take them, and the Shader.

The per-hit loops are compiled: frames (``kernels/shading.py``), and the
whole lighting pass with its shadow rays (``kernels/lighting.py``). ``Shader``
is the render's shading (rendering/pipeline.py drives it band by band): the
direct lighting, the mirror bounces and the occlusion, on the CPU kernels or,
for device "gpu", the direct lighting and the mirror chain in compute shaders
(gpu_lighting.py) with the occlusion on the CPU. Linear RGB.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from bsrt.geometry.patches import PatchSet
from bsrt.kernels.lighting import shade_hits
from bsrt.kernels.shading import LIGHT_KINDS, frames_many, mirror_rays, mix_reflections
from bsrt.kernels.threads import run_chunks
from bsrt.kernels.traverse import Exclusion
from bsrt.rendering.bvh import DEFAULT_RETRY_DEPTH, ray_budget
from bsrt.rendering.gpu_lighting import shade_hits_gpu
from bsrt.rendering.hits import Hits

if TYPE_CHECKING:
    from bsrt.rendering.options import RenderOptions
    from bsrt.rendering.pipeline import Geometry
    from bsrt.rendering.stats import Stats
    from bsrt.scene import Scene

# --stats' devices of the secondary rays on the GPU path: the mirror rays there (gpu_lighting.py); the
# occlusion rays (the GPU's any-hit walk answered one of 1.1 million otherwise: a blocker's t a few
# roundings apart at the rays' reach, 2/255 on one pixel) and the anti-aliasing's camera rays on the CPU
GPU_SECONDARY = "gpu (mirrors), cpu"
SECONDARY_CHUNK = 1 << 19  # rays (hits shaded, mirror rays) per call: progress points (run_chunks takes signals)
SHADOW_ITERATIONS = 16  # Newton iterations of a shadow ray on one piece (bvh.intersect's default)


def facing_frames(patches: PatchSet, hits: Hits, directions: np.ndarray):
    """Position and unit normal (K, 3) of each hit, the normal facing the ray's
    origin, NaN where no hit, and |S_u|, |S_v| (K, 2) (scene units per unit of
    u, v). directions: (K, 3) the rays that found the hits. Where S_u x S_v
    vanishes (a pole, a collapsed edge) the limit normal is taken a small
    step toward the patch centre, so no NaN reaches the image."""
    n = len(hits)
    position, normal, speed = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 2))
    run_chunks(
        frames_many,
        n,
        patches.arrays,
        np.ascontiguousarray(hits.hit),
        np.ascontiguousarray(hits.patch),
        np.ascontiguousarray(hits.u),
        np.ascontiguousarray(hits.v),
        np.ascontiguousarray(directions, dtype=np.float64),
        position,
        normal,
        speed,
    )
    return position, normal, speed


def light_arrays(lights):
    """The kernels' view of a scene's lights (L of them): kind (L,) int64 (LIGHT_KINDS),
    position (L, 3) (point lights; 0 for others), direction (L, 3) (directional lights: the unit
    direction toward the light; 0 for others), strength (L, 3) = colour x intensity."""
    kind = np.array([LIGHT_KINDS[light.kind] for light in lights], dtype=np.int64)
    light_pos = np.array([light.position or (0.0, 0.0, 0.0) for light in lights], dtype=np.float64).reshape(-1, 3)
    light_dir = np.zeros((len(lights), 3))
    for j, light in enumerate(lights):
        if light.kind == "directional":
            light_dir[j] = -np.array(light.direction) / np.linalg.norm(light.direction)
    strength = np.array([np.array(light.color) * light.intensity for light in lights], dtype=np.float64).reshape(-1, 3)
    return kind, light_pos, light_dir, strength


class Shader:
    """Colour along camera rays: Blinn-Phong with shadow rays to every point and
    directional light (one compiled pass per slice of hits: kernels/lighting.py),
    mirror reflection up to options.max_depth bounces, and ambient occlusion and
    the ground's contact shadow on the first hits. gpu_ctx: a context where the
    lighting and the mirror chain run instead (gpu_lighting.py), or None."""

    def __init__(self, scene: Scene, options: RenderOptions, geometry: Geometry, stats: Stats, report, radius, gpu_ctx):
        self.scene, self.options, self.geometry, self.stats, self.report = scene, options, geometry, stats, report
        self.gpu = gpu_ctx
        stats.fields.setdefault("devices", {}).update(
            shade="cpu" if gpu_ctx is None else "gpu", secondary="cpu" if gpu_ctx is None else GPU_SECONDARY
        )
        grounded = options.ground and scene.surfaces and scene.surfaces[-1].name == "ground" and radius is not None
        self.ground = len(scene.surfaces) - 1 if grounded else -1  # the ground plane's surface index
        self.reach = 0.5 * (geometry.diagonal / 2.0 if radius is None else radius)  # AO_RANGE model radii
        self.tolerance = options.tolerance * geometry.diagonal
        self.reflectance = np.array([m.reflectance for m in scene.materials])
        self.surface_reflectance = self.reflectance[geometry.material]  # (S,) per surface
        self.mirror = self.surface_reflectance > 0
        mats = scene.materials
        self.materials = (
            np.array([m.color for m in mats], dtype=np.float64).reshape(-1, 3),
            np.array([m.specular for m in mats], dtype=np.float64),
            np.array([m.shininess for m in mats], dtype=np.float64),
        )
        self.lights = light_arrays(scene.lights)
        self.background = np.array(options.background, dtype=np.float64).reshape(3)
        self.span, self.expected, self.traced, self.shown = (0.0, 1.0), 1, 0, 0.0
        self.casting = sum(light.kind != "ambient" for light in scene.lights)
        stats.add("shadow_rays", 0)
        stats.add("reflection_rays", 0)

    def begin_band(self, hits: Hits, span: tuple[float, float]) -> None:
        """Progress of the band's shading is reported within span (fractions of the render),
        against an estimate of its secondary rays (one shadow ray per hit and light, and a bounce where mirrors are)."""
        mirrors = 2 if np.any(self.reflectance > 0) and self.options.max_depth > 0 else 1
        self.span, self.traced = span, 0
        self.expected = max(1, int(hits.hit.sum()) * max(self.casting, 1) * mirrors)

    def _advance(self, rays: int) -> None:
        lo, hi = self.span
        self.traced += rays
        self.shown = max(self.shown, lo + (hi - lo) * min(0.99, self.traced / self.expected))
        self.report("shade", self.shown)

    def shade(self, hits: Hits, directions: np.ndarray, frames=None):
        """Linear RGB (K, 3) seen along each camera ray (ending at ``hits``); directions: (K, 3) unit.
        frames: (position, normal) (K, 3) arrays the hits' frames are written into (else made here)."""
        directions = np.ascontiguousarray(directions, dtype=np.float64)
        numbers = self._occlusion_numbers(hits)
        if self.gpu is None:
            return self._shade_cpu(hits, directions, 0, frames, numbers)
        return self._shade_gpu(hits, directions, frames, numbers)

    def _occlusion_numbers(self, hits: Hits):
        """(K,) int: each hit's number among the call's points that take ambient occlusion or the
        ground's contact shadow (their directions' turn: occlusion.py), or None where none do."""
        if not (self.options.ao or self.ground >= 0):
            return None
        taken = hits.hit if self.options.ao else hits.hit & (hits.surface == self.ground)
        return np.cumsum(taken) - 1

    def _shade_gpu(self, hits: Hits, directions: np.ndarray, frames, numbers):
        """shade on the GPU (gpu_lighting.shade_hits_gpu): the direct lighting and the mirror chain there,
        the occlusion on the CPU from the first level's frames; the hits the GPU leaves unsettled
        shaded again by _shade_cpu."""
        n = len(hits)
        geometry, bvh = self.geometry, self.geometry.bvh
        colour = np.empty((n, 3))
        shadow_rays, exhausted, reflections = (np.empty(n, dtype=np.int64) for _ in range(3))
        position, normal = frames if frames is not None else (None, None)
        radius = np.empty((n, 2)) if frames is not None else None
        for a in range(0, n, SECONDARY_CHUNK):  # progress points
            part = slice(a, min(n, a + SECONDARY_CHUNK))
            chunk = hits.take(part)

            def occlude(rows, c, p, nrm, r, chunk=chunk, a=a):
                sub = chunk.take(rows)
                self._occlude(c, sub, p, nrm, r, numbers[a + rows.start : a + rows.stop])

            def redo(again, chunk=chunk, a=a):  # the whole shading of these rows on the CPU, counted there
                sub, rows = chunk.take(again), a + again
                framed = None if frames is None else (np.empty((again.size, 3)), np.empty((again.size, 3)))
                colour[rows] = self._shade_cpu(
                    sub, directions[rows], 0, framed, None if numbers is None else numbers[rows], counted=True
                )
                if framed is not None:
                    position[rows], normal[rows] = framed
                for count in (shadow_rays, exhausted, reflections):
                    count[rows] = 0

            outputs = tuple(None if x is None else x[part] for x in (colour, position, normal, radius))
            shade_hits_gpu(self.gpu, bvh, chunk, directions[part], geometry.material, self.materials, self.lights,
                           self.background, 1e-6 * geometry.diagonal, float(self.tolerance), SHADOW_ITERATIONS,
                           outputs + (shadow_rays[part], exhausted[part]), reflectance=self.surface_reflectance,
                           max_depth=self.options.max_depth, reflections=reflections[part],
                           first_level=None if numbers is None else occlude, redo=redo)  # fmt: skip
            self._count(shadow_rays[part], exhausted[part], reflections[part])
        return colour

    def _count(self, shadow_rays, exhausted, reflections=None) -> None:
        """Shadow rays (per hit), rays out of budget (lit, as bvh.py's "Budget" says) and mirror rays
        into the stats, and the progress."""
        self.geometry.out_of_budget += int(exhausted.sum())
        rays, bounces = int(shadow_rays.sum()), 0 if reflections is None else int(reflections.sum())
        self.stats.add("shadow_rays", rays)
        if reflections is not None:
            self.stats.add("reflection_rays", bounces)
        self._advance(rays + bounces)

    def _shade_cpu(self, hits: Hits, directions: np.ndarray, depth: int, frames, numbers, counted: bool = False):
        """shade on the CPU kernels at this mirror depth, recursing into the mirror rays. numbers: the
        hits' occlusion numbers (_occlusion_numbers; depth 0 only). counted: their occlusion rays were
        traced and counted already (the GPU path's first level, the same rays): not counted again."""
        n = len(hits)
        position, normal = frames if frames is not None else (np.empty((n, 3)), np.empty((n, 3)))
        colour = np.empty((n, 3))
        radius, shadow_rays, exhausted = np.empty((n, 2)), np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
        geometry = self.geometry
        bvh = geometry.bvh
        for a in range(0, n, SECONDARY_CHUNK):  # progress points
            part = slice(a, min(n, a + SECONDARY_CHUNK))
            outputs = (colour[part], position[part], normal[part], radius[part], shadow_rays[part], exhausted[part])
            run_chunks(
                shade_hits,
                part.stop - part.start,
                geometry.patches.arrays,
                geometry.patches.trims,
                bvh.arrays,
                hits.hit[part],
                hits.patch[part],
                hits.surface[part],
                hits.u[part],
                hits.v[part],
                directions[part],
                geometry.material,
                *self.materials,
                *self.lights,
                self.background,
                1e-6 * geometry.diagonal,
                float(self.tolerance),
                SHADOW_ITERATIONS,
                DEFAULT_RETRY_DEPTH,
                bvh.padding + float(self.tolerance),
                ray_budget(SHADOW_ITERATIONS),
                bvh.packet_spread,
                *outputs,
                min_chunk=256,
            )
            self._count(shadow_rays[part], exhausted[part])
        if numbers is not None and depth == 0:
            before = self.geometry.out_of_budget, self.stats.counts.get("ao_rays", 0)
            self._occlude(colour, hits, position, normal, radius, numbers)
            if counted:
                self.geometry.out_of_budget, self.stats.counts["ao_rays"] = before
        mirror = np.flatnonzero(hits.hit & self.mirror[hits.surface]) if depth < self.options.max_depth else []
        if len(mirror):
            m = len(mirror)
            origins, mirrored = np.empty((m, 3)), np.empty((m, 3))
            exclude = Exclusion(np.empty(m, dtype=np.int64), *(np.empty(m) for _ in range(4)))
            run_chunks(mirror_rays, m, mirror, directions, normal, position, hits.surface, hits.u, hits.v, radius,
                       origins, mirrored, exclude)  # fmt: skip
            self.stats.add("reflection_rays", m)
            seen = self._trace(origins, mirrored, exclude)
            reflected = self._shade_cpu(seen, mirrored, depth + 1, None, None)
            run_chunks(mix_reflections, m, mirror, self.surface_reflectance[hits.surface[mirror]], reflected, colour)
        return colour

    def _occlude(self, colour, hits: Hits, position, normal, radius, numbers) -> None:
        """Ambient occlusion (options.ao: the ambient lights' part of each hit's colour times its
        openness) and the ground's contact shadow (its colour times its openness), in place; the
        arrays are the K hits' rows, numbers (K,) their occlusion numbers (_occlusion_numbers)."""
        from bsrt.rendering.occlusion import AO_RAYS, occlusion

        hit = np.flatnonzero(hits.hit)
        surface = hits.surface[hit]
        on_ground = surface == self.ground
        which = hit if self.options.ao else hit[on_ground]
        if not which.size:
            return
        self.stats.add("ao_rays", which.size * AO_RAYS)
        exclude = (hits.surface[which], hits.u[which], hits.v[which], radius[which, 0], radius[which, 1])
        openness = occlusion(self._trace, position[which], normal[which], exclude, self.reach, numbers[which])
        ground = hits.surface[which] == self.ground
        if self.options.ao:
            ambient = sum(
                (np.array(light.color) * light.intensity for light in self.scene.lights if light.kind == "ambient"),
                np.zeros(3),
            )
            albedo = np.array([m.color for m in self.scene.materials])[self.geometry.material[hits.surface[which]]]
            lost = (1.0 - openness)[:, None] * albedo * ambient
            colour[which[~ground]] -= lost[~ground]
        colour[which[ground]] *= openness[ground][:, None]

    def _trace(self, origins, directions, exclude, t_max=np.inf, any_hit=False) -> Hits:
        """Mirror and occlusion rays through the hierarchy on the CPU (nearest hits, or any hit before
        t_max), in chunks (progress, cancellation)."""
        n = directions.shape[0]
        hits = Hits.blank(n)  # every record written below
        t_max = np.broadcast_to(np.asarray(t_max, dtype=np.float64), (n,))
        with self.stats.timer("secondary"):
            for a in range(0, n, SECONDARY_CHUNK):
                part = slice(a, min(n, a + SECONDARY_CHUNK))
                o, d, far, ex = origins[part], directions[part], t_max[part], tuple(x[part] for x in exclude)
                kw = dict(t_min=0.0, t_max=far, tolerance=self.tolerance, exclude=ex, any_hit=any_hit)
                self.geometry.intersect(o, d, out=hits.take(part), **kw)  # written in place
                self._advance(part.stop - part.start)
        return hits

"""Surface frames at hits and Blinn-Phong shading, per hit (compiled).

Light kinds (``LIGHT_KINDS``): ambient, point (inverse-square falloff),
directional. Everything in linear RGB, float64.
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.jit import njit
from bsrt.kernels.patches import frame

LIGHT_KINDS = {"ambient": 0, "point": 1, "directional": 2}
POLE_STEPS = (1e-7, 1e-5, 1e-3)


@njit(cache=True, nogil=True, no_cpython_wrapper=True)
def surface_frame(P, k, u, v, tx, ty, tz):
    """Position, unit normal and |S_u|, |S_v| of patch k at (u, v): 8 floats
    (x, y, z, nx, ny, nz, su, sv). The normal is S_u x S_v normalised and
    flipped to face the origin of a ray along (tx, ty, tz) (a zero vector: not
    flipped); where it vanishes (a pole, a collapsed edge) the limit normal is
    taken a step of 1e-7 (then 1e-5, 1e-3) of the patch toward its centre; if
    all vanish, 0."""
    return surface_frame_of(P, k, u, v, frame(P, k, u, v), tx, ty, tz)


@njit(cache=True, nogil=True, no_cpython_wrapper=True)
def surface_frame_of(P, k, u, v, f, tx, ty, tz):
    """surface_frame from f, patches.frame(P, k, u, v) already at hand."""
    x, y, z, xu, yu, zu, xv, yv, zv = f
    su = np.sqrt(xu * xu + yu * yu + zu * zu)
    sv = np.sqrt(xv * xv + yv * yv + zv * zv)
    nx, ny, nz = yu * zv - zu * yv, zu * xv - xu * zv, xu * yv - yu * xv
    length = np.sqrt(nx * nx + ny * ny + nz * nz)
    if not length > 1e-12 * su * sv:
        b = P.bounds[k]
        cu, cv = 0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3])
        for step in POLE_STEPS:
            f = frame(P, k, u + 2.0 * step * (cu - u), v + 2.0 * step * (cv - v))
            nx, ny, nz = f[4] * f[8] - f[5] * f[7], f[5] * f[6] - f[3] * f[8], f[3] * f[7] - f[4] * f[6]
            length = np.sqrt(nx * nx + ny * ny + nz * nz)
            if length > 0.0:
                break
    if not length > 0.0:
        nx = ny = nz = 0.0
        length = 1.0
    if nx * tx + ny * ty + nz * tz > 0.0:
        length = -length
    return x, y, z, nx / length, ny / length, nz / length, su, sv


@njit(cache=True, nogil=True)
def frames_many(start, stop, P, hit, patch, u, v, towards, position, normal, speed):
    """surface_frame at each ray i of start..stop-1 that hit (hit[i]; patch[i], u[i], v[i]), NaN where not.

    hit: (K,) bool; patch: (K,) int64; u, v: (K,) float64; towards: (K, 3) the ray directions (the
    normal faces their origins). position, normal: (K, 3) and speed: (K, 2) (|S_u|, |S_v|) outputs.
    """
    for i in range(start, stop):
        if not hit[i]:
            for c in range(3):
                position[i, c] = normal[i, c] = np.nan
            speed[i, 0] = speed[i, 1] = np.nan
            continue
        f = surface_frame(P, patch[i], u[i], v[i], towards[i, 0], towards[i, 1], towards[i, 2])
        position[i, 0], position[i, 1], position[i, 2] = f[0], f[1], f[2]
        normal[i, 0], normal[i, 1], normal[i, 2] = f[3], f[4], f[5]
        speed[i, 0], speed[i, 1] = f[6], f[7]


@njit(cache=True, nogil=True, no_cpython_wrapper=True)
def radiance(
    px,
    py,
    pz,
    nx,
    ny,
    nz,
    vx,
    vy,
    vz,
    m,
    albedo,
    specular,
    shininess,
    kind,
    light_position,
    light_direction,
    strength,
    visibility,
):
    """Blinn-Phong radiance (r, g, b) toward the viewer at one point: position p, unit normal n
    (facing the viewer), unit view direction v (viewer to point), material m; the lights as
    lighting.shade_hits's; visibility: (L,) 1 where light L reaches the point."""
    r = g = b = 0.0
    for j in range(kind.shape[0]):
        if kind[j] == 0:
            r += albedo[m, 0] * strength[j, 0]
            g += albedo[m, 1] * strength[j, 1]
            b += albedo[m, 2] * strength[j, 2]
            continue
        if kind[j] == 1:
            lx = light_position[j, 0] - px
            ly = light_position[j, 1] - py
            lz = light_position[j, 2] - pz
            dist = np.sqrt(lx * lx + ly * ly + lz * lz)
            d = max(dist, 1e-300)
            lx, ly, lz = lx / d, ly / d, lz / d
            falloff = 1.0 / (dist * dist)
        else:
            lx, ly, lz = light_direction[j, 0], light_direction[j, 1], light_direction[j, 2]
            falloff = 1.0
        falloff *= visibility[j]
        cos_l = nx * lx + ny * ly + nz * lz
        if not cos_l > 0.0:
            continue
        hx, hy, hz = lx - vx, ly - vy, lz - vz
        h = max(np.sqrt(hx * hx + hy * hy + hz * hz), 1e-300)
        cos_h = min(max((nx * hx + ny * hy + nz * hz) / h, 0.0), 1.0)
        spec = specular[m] * cos_h ** shininess[m]
        r += (albedo[m, 0] * cos_l + spec) * strength[j, 0] * falloff
        g += (albedo[m, 1] * cos_l + spec) * strength[j, 1] * falloff
        b += (albedo[m, 2] * cos_l + spec) * strength[j, 2] * falloff
    return r, g, b


@njit(cache=True, nogil=True)
def mirror_rays(start, stop, mirror, direction, normal, position, surface, u, v, radius, origin_out, direction_out, ex):
    """The bounce off mirror hits start..stop-1 of mirror (M,) (indices into the N hits): from the hit's
    position along its ray's direction mirrored in its normal, d - 2 (d . n) n, passing the root it
    leaves (the exclusion of bvh.intersect). direction, normal, position: (N, 3); surface: (N,) int64;
    u, v: (N,); radius: (N, 2) the exclusion radii in u and v. Outputs: origin_out, direction_out
    (M, 3); ex: an Exclusion of (M,) arrays."""
    for k in range(start, stop):
        i = mirror[k]
        dx, dy, dz = direction[i, 0], direction[i, 1], direction[i, 2]
        nx, ny, nz = normal[i, 0], normal[i, 1], normal[i, 2]
        s = 2.0 * (dx * nx + dy * ny + dz * nz)
        direction_out[k, 0], direction_out[k, 1], direction_out[k, 2] = dx - s * nx, dy - s * ny, dz - s * nz
        origin_out[k, 0], origin_out[k, 1], origin_out[k, 2] = position[i, 0], position[i, 1], position[i, 2]
        ex.surface[k], ex.u[k], ex.v[k] = surface[i], u[i], v[i]
        ex.radius_u[k], ex.radius_v[k] = radius[i, 0], radius[i, 1]


@njit(cache=True, nogil=True)
def mix_reflections(start, stop, mirror, reflectance, reflected, colour):
    """colour[mirror[k]] = (1 - reflectance[k]) colour[mirror[k]] + reflectance[k] reflected[k] for k in
    start..stop-1 (mirror (M,) indices into colour (N, 3), reflected (M, 3), reflectance (M,))."""
    for k in range(start, stop):
        i, r = mirror[k], reflectance[k]
        for c in range(3):
            colour[i, c] = (1.0 - r) * colour[i, c] + r * reflected[k, c]

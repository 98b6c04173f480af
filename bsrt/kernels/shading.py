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


@njit(cache=True, nogil=True)
def frames_many(start, stop, P, patch, u, v, towards, position, normal, speed):
    """Position, unit normal and |S_u|, |S_v| at each hit i (patch[i], u[i], v[i]).

    towards: (K, 3) the ray directions: the normal is flipped to face the
    ray's origin (a zero row: not flipped). position, normal: (K, 3) and
    speed: (K, 2) outputs. The normal is S_u x S_v normalised; where it
    vanishes (a pole, a collapsed edge) the limit normal is taken a step of
    1e-7 (then 1e-5, 1e-3) of the patch toward its centre; if all vanish, 0.
    """
    for i in range(start, stop):
        k = patch[i]
        x, y, z, xu, yu, zu, xv, yv, zv = frame(P, k, u[i], v[i])
        position[i, 0], position[i, 1], position[i, 2] = x, y, z
        su = np.sqrt(xu * xu + yu * yu + zu * zu)
        sv = np.sqrt(xv * xv + yv * yv + zv * zv)
        speed[i, 0], speed[i, 1] = su, sv
        nx, ny, nz = yu * zv - zu * yv, zu * xv - xu * zv, xu * yv - yu * xv
        length = np.sqrt(nx * nx + ny * ny + nz * nz)
        if not length > 1e-12 * su * sv:
            b = P.bounds[k]
            cu, cv = 0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3])
            for step in POLE_STEPS:
                f = frame(P, k, u[i] + 2.0 * step * (cu - u[i]), v[i] + 2.0 * step * (cv - v[i]))
                nx, ny, nz = f[4] * f[8] - f[5] * f[7], f[5] * f[6] - f[3] * f[8], f[3] * f[7] - f[4] * f[6]
                length = np.sqrt(nx * nx + ny * ny + nz * nz)
                if length > 0.0:
                    break
        if not length > 0.0:
            nx = ny = nz = 0.0
            length = 1.0
        if nx * towards[i, 0] + ny * towards[i, 1] + nz * towards[i, 2] > 0.0:
            length = -length
        normal[i, 0], normal[i, 1], normal[i, 2] = nx / length, ny / length, nz / length


@njit(cache=True)
def blinn_phong(
    position,
    normal,
    view,
    material,
    albedo,
    specular,
    shininess,
    kind,
    light_position,
    light_direction,
    strength,
    visibility,
    out,
):
    """Radiance toward the viewer at K points into out (K, 3).

    position, normal (unit, facing the viewer), view (unit, viewer to point):
    (K, 3); material: (K,) into albedo (M, 3), specular (M,), shininess (M,);
    lights: kind (L,), light_position (L, 3) (point), light_direction (L, 3)
    (directional: the unit direction toward the light), strength (L, 3) =
    colour x intensity; visibility: (K, L), 1 where the light reaches the point.
    """
    for i in range(position.shape[0]):
        m = material[i]
        r = g = b = 0.0
        for j in range(kind.shape[0]):
            if kind[j] == 0:
                r += albedo[m, 0] * strength[j, 0]
                g += albedo[m, 1] * strength[j, 1]
                b += albedo[m, 2] * strength[j, 2]
                continue
            if kind[j] == 1:
                lx = light_position[j, 0] - position[i, 0]
                ly = light_position[j, 1] - position[i, 1]
                lz = light_position[j, 2] - position[i, 2]
                dist = np.sqrt(lx * lx + ly * ly + lz * lz)
                d = max(dist, 1e-300)
                lx, ly, lz = lx / d, ly / d, lz / d
                falloff = 1.0 / (dist * dist)
            else:
                lx, ly, lz = light_direction[j, 0], light_direction[j, 1], light_direction[j, 2]
                falloff = 1.0
            falloff *= visibility[i, j]
            cos_l = normal[i, 0] * lx + normal[i, 1] * ly + normal[i, 2] * lz
            if not cos_l > 0.0:
                continue
            hx, hy, hz = lx - view[i, 0], ly - view[i, 1], lz - view[i, 2]
            h = max(np.sqrt(hx * hx + hy * hy + hz * hz), 1e-300)
            cos_h = min(max((normal[i, 0] * hx + normal[i, 1] * hy + normal[i, 2] * hz) / h, 0.0), 1.0)
            spec = specular[m] * cos_h ** shininess[m]
            r += (albedo[m, 0] * cos_l + spec) * strength[j, 0] * falloff
            g += (albedo[m, 1] * cos_l + spec) * strength[j, 1] * falloff
            b += (albedo[m, 2] * cos_l + spec) * strength[j, 2] * falloff
        out[i, 0], out[i, 1], out[i, 2] = r, g, b

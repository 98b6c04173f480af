"""Shading a band of hits in one compiled pass: frames, exclusion boxes, shadow rays, Blinn-Phong.

``shade_hits`` does per hit what the NumPy pipeline did in a dozen passes:
the surface frame (``shading.surface_frame``), the parameter box its
secondary rays must not hit again, one any-hit shadow ray per light the point
faces (``occluded``), and the radiance (``shading.radiance``). Mirror bounces
stay with the caller (rendering/pipeline.py), which gets each hit's position,
normal and exclusion box from here.

``occluded`` is the any-hit walk of shadow rays: the same tests and the same
per-piece solve as ``traverse.trace_rays`` with ``any_hit``, without the
nearest-first bookkeeping, and it first tries the piece that blocked the
previous shadow ray toward the same light in the same slice (neighbouring
points are mostly shadowed by the same piece). The piece holding the ray's
start is skipped where trace_rays skips it (the ray leaves it steeply), and
also where the ray's line meets it only once (``crossings.crosses_once``, an
exact bound): that one crossing is the start, the root every shadow ray
excludes. Whether a ray is blocked is otherwise the same answer trace_rays
gives: a piece that yields a valid root would yield it inside the walk too.
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.crossings import crosses_once
from bsrt.kernels.hulls import straddles
from bsrt.kernels.jit import njit
from bsrt.kernels.nets import leaf_net
from bsrt.kernels.patches import locate
from bsrt.kernels.roots import ray_frame
from bsrt.kernels.shading import radiance, surface_frame
from bsrt.kernels.traverse import STACK, _leaves_grazing, _normal, _obb_slab, _slab, _solve_piece


@njit(cache=True, nogil=True, no_cpython_wrapper=True, _nrt=False)
def _leaf_blocks(P, T, B, leaf, ox, oy, oz, dx, dy, dz, e, t_max, tol, max_iterations, retry_depth, cull_tol, ex, s):
    """(blocked, iterations): does piece ``leaf`` hold a valid root in (0, t_max)? (trace_rays's tests:
    oriented box, hull straddle, the piece's solve with its retries). ex: (surface, u, v, ru, rv) of
    the start root; s: the scratch (nets, rects, depth, tmp)."""
    lo, hi = _obb_slab(B.leaf_obb[leaf], ox, oy, oz, dx, dy, dz)
    if not (lo <= hi and hi >= 0.0 and lo <= t_max):
        return False, 0
    net = leaf_net(B.patch_net, B.leaf_net, B.leaf_net_row, leaf)
    p, q = B.leaf_degree[leaf, 0], B.leaf_degree[leaf, 1]
    if not straddles(net, p, q, ox, oy, oz, e, dx, dy, dz, 0.0, t_max, cull_tol):
        return False, 0
    found, _, _, _, _, _, its = _solve_piece(
        P,
        T,
        B,
        leaf,
        ox,
        oy,
        oz,
        dx,
        dy,
        dz,
        e,
        0.0,
        t_max,
        tol,
        max_iterations,
        retry_depth,
        cull_tol,
        ex[0],
        ex[1],
        ex[2],
        ex[3],
        ex[4],
        s[0],
        s[1],
        s[2],
        s[3],
        retry_depth >= 0,  # True (any hit), as a run-time value: a literal would compile _solve_piece twice
    )
    return found, its


@njit(cache=True, nogil=True, no_cpython_wrapper=True, _nrt=False)
def _crosses_once(B, leaf, ox, oy, oz, e, g):
    """crossings.crosses_once for piece ``leaf``: does the ray meet it at most once? g: a scratch net
    (the retries never use the last: traverse._solve_piece)."""
    net = leaf_net(B.patch_net, B.leaf_net, B.leaf_net_row, leaf)
    return crosses_once(net, B.leaf_degree[leaf, 0], B.leaf_degree[leaf, 1], ox, oy, oz, e, g)


@njit(cache=True, nogil=True, no_cpython_wrapper=True, _nrt=False)
def occluded(
    P,
    T,
    B,
    ox,
    oy,
    oz,
    dx,
    dy,
    dz,
    t_max,
    tol,
    max_iterations,
    retry_depth,
    cull_tol,
    budget,
    ex,
    start,
    hint,
    stack,
    s,
):
    """Any-hit shadow ray from (ox, oy, oz) along the unit (dx, dy, dz) with 0 < t < t_max:
    (blocked, the leaf that blocked it or -1, iterations). hint: a leaf to try first (-1: none);
    ex, s: as _leaf_blocks; start: traverse._normal at the start root (ex's surface, u, v);
    stack: (STACK,) int64 scratch. budget: the ray's Newton iterations (bvh.py, "Budget"): a ray
    that spends them without finding a blocker is lit, and the leaf returned is -2 (counted as
    out of budget). No reference counting (``_nrt=False``, as traverse.py's per-piece helpers):
    it would cost a third of a shadow ray's time."""
    e = ray_frame(dx, dy, dz)
    ex_m, ex_u, ex_v = ex[0], ex[1], ex[2]
    skip_start = ex_m >= 0 and not _leaves_grazing(start, dx, dy, dz)
    iterations = 0
    if hint >= 0:
        r = B.leaf_rect[hint]
        start = B.leaf_surface[hint] == ex_m and r[0] <= ex_u <= r[1] and r[2] <= ex_v <= r[3]
        if not (start and (skip_start or _crosses_once(B, hint, ox, oy, oz, e, s[0][s[0].shape[0] - 1]))):
            blocked, its = _leaf_blocks(
                P, T, B, hint, ox, oy, oz, dx, dy, dz, e, t_max, tol, max_iterations, retry_depth, cull_tol, ex, s
            )
            iterations += its
            if blocked:
                return True, hint, iterations
    ix = 1.0 / dx if abs(dx) > 1e-300 else np.copysign(1e300, dx)
    iy = 1.0 / dy if abs(dy) > 1e-300 else np.copysign(1e300, dy)
    iz = 1.0 / dz if abs(dz) > 1e-300 else np.copysign(1e300, dz)
    near, far = _slab(B.node_bounds[0], ox, oy, oz, ix, iy, iz)
    if not (near <= far and far >= 0.0 and near <= t_max):
        return False, -1, iterations
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = stack[top]
        left = B.node_left[node]
        if left < 0:
            for leaf in range(B.node_first[node], B.node_first[node] + B.node_count[node]):
                if leaf == hint:
                    continue  # tried above (or the start's piece, skipped below too)
                if B.leaf_surface[leaf] == ex_m:
                    r = B.leaf_rect[leaf]
                    if r[0] <= ex_u <= r[1] and r[2] <= ex_v <= r[3]:
                        if skip_start or _crosses_once(B, leaf, ox, oy, oz, e, s[0][s[0].shape[0] - 1]):
                            continue
                blocked, its = _leaf_blocks(
                    P, T, B, leaf, ox, oy, oz, dx, dy, dz, e, t_max, tol, max_iterations, retry_depth, cull_tol, ex, s
                )
                iterations += its
                if blocked:
                    return True, leaf, iterations
                if iterations >= budget:
                    return False, -2, iterations
            continue
        right = B.node_right[node]
        n1, f1 = _slab(B.node_bounds[left], ox, oy, oz, ix, iy, iz)
        n2, f2 = _slab(B.node_bounds[right], ox, oy, oz, ix, iy, iz)
        hit1 = n1 <= f1 and f1 >= 0.0 and n1 <= t_max
        hit2 = n2 <= f2 and f2 >= 0.0 and n2 <= t_max
        if hit1 and hit2 and top + 2 <= stack.shape[0]:  # a full stack drops what trace_rays drops
            stack[top], stack[top + 1] = right, left
            top += 2
        elif hit1:
            stack[top] = left
            top += 1
        elif hit2:
            stack[top] = right
            top += 1
    return False, -1, iterations


@njit(cache=True, nogil=True)
def shade_hits(
    start,
    stop,
    P,
    T,
    B,
    hit,
    patch,
    surface,
    u,
    v,
    direction,
    material_of,
    albedo,
    specular,
    shininess,
    kind,
    light_position,
    light_direction,
    strength,
    background,
    eps,
    tol,
    max_iterations,
    retry_depth,
    cull_tol,
    budget,
    colour,
    position,
    normal,
    radius,
    shadow_rays,
    exhausted,
):
    """Colour of rays start..stop-1 of K, lit with shadows (mirrors left to the caller).

    hit: (K,) bool; patch, surface: (K,) int64; u, v: (K,) float64: the hits; direction: (K, 3)
    unit ray directions. material_of: (S,) int64 material of each surface; albedo (M, 3), specular,
    shininess (M,); lights as rendering.shade.light_arrays gives them: kind (L,), light_position (L, 3), light_direction
    (L, 3) (unit, toward the light), strength (L, 3);
    background (3,). eps: the exclusion half-width in scene units (1e-6 of the diagonal); tol,
    max_iterations, retry_depth, cull_tol: the shadow rays' solve (bvh.intersect's); budget: a
    shadow ray's Newton iterations (bvh.py, "Budget").
    Outputs, (K, ...): colour (K, 3) linear RGB (background where no hit); position, normal (K, 3)
    (normal facing the ray's origin) and radius (K, 2) (the exclusion box's half-widths in u, v:
    eps / |S_u|, eps / |S_v|, at most a quarter of the patch), NaN where no hit; shadow_rays (K,)
    int64, the shadow rays traced from each hit; exhausted (K,) int64, those of them that spent
    their budget (taken as lit).
    """
    n_lights = kind.shape[0]
    pm, qm = B.patch_net.shape[1], B.patch_net.shape[2]
    size = 4 * retry_depth + 8
    stack = np.empty(STACK, dtype=np.int64)  # scratch, once per slice
    s = (np.empty((size, pm, qm, 4)), np.empty((size, 4)), np.empty(size, dtype=np.int64), np.empty(max(pm, qm)))
    visibility = np.ones(n_lights)
    hints = np.full(n_lights, -1, dtype=np.int64)  # per light: the leaf that blocked its last shadow ray
    for i in range(start, stop):
        shadow_rays[i] = 0
        exhausted[i] = 0
        if not hit[i]:
            colour[i, 0], colour[i, 1], colour[i, 2] = background[0], background[1], background[2]
            for c in range(3):
                position[i, c] = normal[i, c] = np.nan
            radius[i, 0] = radius[i, 1] = np.nan
            continue
        k = patch[i]
        vx, vy, vz = direction[i, 0], direction[i, 1], direction[i, 2]
        px, py, pz, nx, ny, nz, su, sv = surface_frame(P, k, u[i], v[i], vx, vy, vz)
        b = P.bounds[k]
        ru = min(eps / su if su > 0.0 else np.inf, 0.25 * (b[1] - b[0]))
        rv = min(eps / sv if sv > 0.0 else np.inf, 0.25 * (b[3] - b[2]))
        position[i, 0], position[i, 1], position[i, 2] = px, py, pz
        normal[i, 0], normal[i, 1], normal[i, 2] = nx, ny, nz
        radius[i, 0], radius[i, 1] = ru, rv
        ex = (surface[i], u[i], v[i], ru, rv)
        start_normal = _normal(P, locate(P, surface[i], u[i], v[i]), u[i], v[i])  # the start's, for every light
        for j in range(n_lights):
            visibility[j] = 1.0
            if kind[j] == 0:
                continue
            if kind[j] == 1:
                lx = light_position[j, 0] - px
                ly = light_position[j, 1] - py
                lz = light_position[j, 2] - pz
                dist = np.sqrt(lx * lx + ly * ly + lz * lz)
                d = max(dist, 1e-300)
                lx, ly, lz = lx / d, ly / d, lz / d
            else:
                lx, ly, lz = light_direction[j, 0], light_direction[j, 1], light_direction[j, 2]
                dist = np.inf
            if not nx * lx + ny * ly + nz * lz > 0.0:
                continue  # facing away: radiance adds nothing, no shadow ray
            shadow_rays[i] += 1
            length = np.sqrt(lx * lx + ly * ly + lz * lz)  # the tracer's own normalisation (Rays)
            blocked, leaf, _ = occluded(
                P,
                T,
                B,
                px,
                py,
                pz,
                lx / length,
                ly / length,
                lz / length,
                dist,
                tol,
                max_iterations,
                retry_depth,
                cull_tol,
                budget,
                ex,
                start_normal,
                hints[j],
                stack,
                s,
            )
            if blocked:
                visibility[j] = 0.0
                hints[j] = leaf
            elif leaf == -2:
                exhausted[i] += 1
        colour[i, 0], colour[i, 1], colour[i, 2] = radiance(
            px,
            py,
            pz,
            nx,
            ny,
            nz,
            vx,
            vy,
            vz,
            material_of[surface[i]],
            albedo,
            specular,
            shininess,
            kind,
            light_position,
            light_direction,
            strength,
            visibility,
        )

"""Rays through Martin et al.'s hierarchy of flat pieces, one ray per loop iteration.

The hierarchy's table: ``hierarchy.BVHArrays``.

Per ray (``trace_rays``): a depth-first walk, nearer child first, that skips
nodes entered beyond the nearest root so far (any-hit: stops at the first
valid root). Every piece whose oriented box the ray enters runs Newton from
the piece's centre (stop on growth); a root counts if it converged, lies in
the piece's rectangle (grown by 1e-9 of its size), has t_min < t < t_max, is
not the excluded start root of a secondary ray, and is kept by the surface's
trims. A piece whose centre start finds nothing, or finds a grazing root
(|cos| < 0.3: the ray may cross it twice), is cut into quarters by de
Casteljau, recursively up to ``retry_depth`` levels; quarters whose control
points do not straddle the ray (separating axes across the ray:
``hulls.straddles``) or lie beyond the root
found are culled (a piece's own solve is skipped alike), as are those
holding a secondary ray's start whose only crossing is that start
(crossings.py), and Newton restarts from the
survivors' centres; a quarter whose only crossing is a root that is not a
hit is not cut again. A planar piece (it meets a ray once) is cut only when
its centre start finds nothing.

The per-piece helpers allocate nothing and are compiled without numba's reference counting
(``_nrt=False``, as kernels/patches.py): a call that passes the tables (tuples of 13-14 arrays)
would otherwise count a reference to every array on entry and exit, a third of a random ray's time.
So are the retries' net helpers (nets.py) and crossing bounds (crossings.py).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from bsrt.kernels.crossings import holds_once
from bsrt.kernels.hulls import straddles
from bsrt.kernels.jit import njit
from bsrt.kernels.method_ids import NEWTON
from bsrt.kernels.nets import copy_net, leaf_net, split_half
from bsrt.kernels.patches import frame, locate
from bsrt.kernels.roots import ray_frame, solve_one
from bsrt.kernels.trim import point_kept

GRAZING_COSINE = 0.3
RECT_SLACK = 1e-9
STACK = 64
INT32_MAX = np.iinfo(np.int32).max  # Hits.iterations' largest


class Exclusion(NamedTuple):
    """The root each secondary ray starts from (N rays; surface -1: none).

    surface: (N,) int64; u, v: (N,) float64; radius_u, radius_v: (N,) float64,
    half-widths of the parameter box around (u, v) whose roots are not hits.
    """

    surface: np.ndarray
    u: np.ndarray
    v: np.ndarray
    radius_u: np.ndarray
    radius_v: np.ndarray


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def _slab(b, ox, oy, oz, ix, iy, iz):
    """Entry and exit distances of a ray (origin, inverse direction) into box b (6,)."""
    t1, t2 = (b[0] - ox) * ix, (b[3] - ox) * ix
    near, far = min(t1, t2), max(t1, t2)
    t1, t2 = (b[1] - oy) * iy, (b[4] - oy) * iy
    near, far = max(near, min(t1, t2)), min(far, max(t1, t2))
    t1, t2 = (b[2] - oz) * iz, (b[5] - oz) * iz
    return max(near, min(t1, t2)), min(far, max(t1, t2))


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def _obb_slab(obb, ox, oy, oz, dx, dy, dz):
    """Entry and exit distances of a ray into an oriented box (15,)."""
    rx, ry, rz = ox - obb[0], oy - obb[1], oz - obb[2]
    near, far = -np.inf, np.inf
    for k in range(3):
        ax, ay, az = obb[3 + 3 * k], obb[4 + 3 * k], obb[5 + 3 * k]
        o = ax * rx + ay * ry + az * rz
        d = ax * dx + ay * dy + az * dz
        if abs(d) < 1e-300:
            d = 1e-300
        half = obb[12 + k]
        t1, t2 = (-half - o) / d, (half - o) / d
        near, far = max(near, min(t1, t2)), min(far, max(t1, t2))
    return near, far


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def _cross(f):
    """S_u x S_v of a frame f (patches.frame's 9 floats), not normalised, and its length: (nx, ny, nz, length)."""
    nx = f[4] * f[8] - f[5] * f[7]
    ny = f[5] * f[6] - f[3] * f[8]
    nz = f[3] * f[7] - f[4] * f[6]
    return nx, ny, nz, np.sqrt(nx * nx + ny * ny + nz * nz)


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def _normal(P, k, u, v):
    """S_u x S_v of patch k at (u, v), not normalised, and its length: (nx, ny, nz, length)."""
    return _cross(frame(P, k, u, v))


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def _leaves_grazing(n, dx, dy, dz):
    """Is |cos| of the angle between the unit ray direction and the normal n (_normal's) below GRAZING_COSINE?"""
    return abs(n[0] * dx + n[1] * dy + n[2] * dz) / max(n[3], 1e-300) < GRAZING_COSINE


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def _grazing(P, k, u, v, dx, dy, dz):
    return _leaves_grazing(_normal(P, k, u, v), dx, dy, dz)


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def _root_in(u0, u1, v0, v1, kept, m, u, v, t, t_min, t_max, ex_m, ex_u, ex_v, ex_ru, ex_rv):
    """0: not a hit; 1: a hit; 2: the excluded start root (not a hit either); 3: a root of the piece
    that is not a hit (outside (t_min, t_max)); 4: a hit if surface m's trims keep (u, v) (the
    caller's point_kept; else 3). The piece's rectangle is (u0, u1, v0, v1);
    kept: the trims keep all of it (BVHArrays.leaf_kept), so a root inside it needs no trim test.
    Scalars only: an array argument costs reference counting on every call.

    A root that is the secondary ray's own start counts as 2 even when Newton
    reached it from a neighbouring piece; the piece is then retried (quarters)
    only when the ray leaves the start grazing: a leaf's normals lie within its
    cone (bvh.py), so only a grazing ray meets it again."""
    if m == ex_m and abs(u - ex_u) <= ex_ru and abs(v - ex_v) <= ex_rv:
        return 2
    su = RECT_SLACK * (u1 - u0)
    sv = RECT_SLACK * (v1 - v0)
    if not (u0 - su <= u <= u1 + su and v0 - sv <= v <= v1 + sv):
        return 0
    if not (t_min < t < t_max):
        return 3
    if not (kept and u0 <= u <= u1 and v0 <= v <= v1):
        return 4
    return 1


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def _newton(P, m, u, v, ox, oy, oz, dx, dy, dz, tol2, max_iterations):
    """solve_one's NEWTON from (u, v) on surface m, stopping on growth, compiled once: the piece
    solver's retries and last step call it, its first solve has solve_one inlined. (Each inlined
    copy costs about a second of the first run's compile; the retries and the last step are rare
    enough that the call costs nothing measurable.)"""
    return solve_one(P, m, u, v, ox, oy, oz, dx, dy, dz, NEWTON, tol2, max_iterations, True)


@njit(cache=True, no_cpython_wrapper=True, _nrt=False)
def _solve_piece(
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
    t_min,
    t_max,
    tol,
    max_iterations,
    retry_depth,
    cull_tol,
    ex_m,
    ex_u,
    ex_v,
    ex_ru,
    ex_rv,
    nets,
    rects,
    depth,
    tmp,
    any_hit,
):
    """Nearest valid root of one piece (any_hit: the first found): (found, t, u, v, patch, residual,
    iterations). nets (S, Pm, Qm, 4), rects (S, 4), depth (S,), tmp (max(Pm, Qm),): scratch
    for the retries, S = 4 retry_depth + 8 (the callers')."""
    m = B.leaf_surface[leaf]
    rect, kept = B.leaf_rect[leaf], B.leaf_kept[leaf]
    u0, u1, v0, v1 = rect[0], rect[1], rect[2], rect[3]
    tol2 = tol * tol
    ok, u, v, k, t, res, its, c = solve_one(
        P, m, 0.5 * (u0 + u1), 0.5 * (v0 + v1), ox, oy, oz, dx, dy, dz, NEWTON, tol2, max_iterations, True
    )
    iterations = its
    state = _root_in(u0, u1, v0, v1, kept, m, u, v, t, t_min, t_max, ex_m, ex_u, ex_v, ex_ru, ex_rv) if ok else 0
    if state == 4:
        state = 1 if point_kept(T, m, u, v) else 3
    found = state == 1
    best_t, best_u, best_v, best_k, best_res = (t, u, v, k, res) if found else (np.inf, 0.0, 0.0, -1, 0.0)
    best_c = c  # |cos| at the best root (solve_one's, from the frame it ended on)
    # No retry after a root that is not grazing. The start root of a secondary ray is retried too when
    # the ray leaves it grazing: the leaf's normals lie within its cone, so a ray that meets the leaf
    # again (a cupped surface shadowing itself) leaves it at |cos| below GRAZING_COSINE. The same holds
    # for a root that is not a hit (trimmed away, beyond t_max): not grazing, it is the piece's only one.
    if retry_depth == 0 or (state != 0 and not c < GRAZING_COSINE):
        return found, best_t, best_u, best_v, best_k, best_res, iterations
    # Retry on quarters (depth-first; at most 3 siblings wait per level), in the caller's scratch.
    p, q = B.leaf_degree[leaf, 0], B.leaf_degree[leaf, 1]
    size = nets.shape[0]
    copy_net(leaf_net(B.patch_net, B.leaf_net, B.leaf_net_row, leaf), nets[0], p, q)
    for k in range(4):
        rects[0, k] = rect[k]
    depth[0] = 0
    # A planar piece meets a ray once (one normal): a root of it, grazing or not, is its only one, so
    # only a planar piece where Newton found none is cut (grazing roots on the planar faces of CAD
    # parts were most of the retries of random rays). Its grazing root still takes the step below.
    top = 0 if found and any_hit else (1 if state == 0 or not B.leaf_planar[leaf] else 0)
    while top > 0 and not (found and any_hit):
        top -= 1
        if depth[top] >= retry_depth or top + 7 > size:  # the last slot: crosses_once's scratch
            continue
        # cut the popped piece into quarters in slots top .. top + 3 (two spare slots for the halves)
        a, b2 = top + 4, top + 5
        split_half(nets[top], nets[a], nets[b2], p, q, 0, tmp)
        split_half(nets[a], nets[top], nets[top + 1], p, q, 1, tmp)
        split_half(nets[b2], nets[top + 2], nets[top + 3], p, q, 1, tmp)
        r0, r1, r2, r3 = rects[top, 0], rects[top, 1], rects[top, 2], rects[top, 3]
        um, vm = 0.5 * (r0 + r1), 0.5 * (r2 + r3)
        d = depth[top] + 1
        rects[top, 0], rects[top, 1], rects[top, 2], rects[top, 3] = r0, um, r2, vm
        rects[top + 1, 0], rects[top + 1, 1], rects[top + 1, 2], rects[top + 1, 3] = r0, um, vm, r3
        rects[top + 2, 0], rects[top + 2, 1], rects[top + 2, 2], rects[top + 2, 3] = um, r1, r2, vm
        rects[top + 3, 0], rects[top + 3, 1], rects[top + 3, 2], rects[top + 3, 3] = um, r1, vm, r3
        first = top
        for s in range(first, first + 4):
            if not straddles(nets[s], p, q, ox, oy, oz, e, dx, dy, dz, t_min, min(t_max, best_t), cull_tol):
                continue
            sr = rects[s]
            if m == ex_m and holds_once(nets[s], p, q, sr, ex_u, ex_v, ox, oy, oz, e, nets[size - 1]):
                continue  # its one crossing is the start, excluded
            ok, u, v, k, t, res, its, c = _newton(
                P, m, 0.5 * (sr[0] + sr[1]), 0.5 * (sr[2] + sr[3]), ox, oy, oz, dx, dy, dz, tol2, max_iterations
            )
            iterations += its
            state = (
                _root_in(u0, u1, v0, v1, kept, m, u, v, t, t_min, t_max, ex_m, ex_u, ex_v, ex_ru, ex_rv) if ok else 0
            )
            if state == 4:
                state = 1 if point_kept(T, m, u, v) else 3
            again = True
            if state != 0:  # a root of this quarter: cut further only if it is grazing
                if state == 1 and t < best_t:
                    found = True
                    best_t, best_u, best_v, best_k, best_res, best_c = t, u, v, k, res, c
                # not after a root that is not a hit and is the quarter's only one
                again = c < GRAZING_COSINE and not (
                    state != 1 and holds_once(nets[s], p, q, sr, u, v, ox, oy, oz, e, nets[size - 1])
                )
            if again and d < retry_depth:  # keep it: move it down to the stack's top
                if s != top:
                    copy_net(nets[s], nets[top], p, q)
                    for k in range(4):
                        rects[top, k] = rects[s, k]
                depth[top] = d
                top += 1
            if found and any_hit:
                break
    cosine = best_c if found else 1.0
    if cosine < GRAZING_COSINE:
        # t of a grazing root is off by up to its residual / |cos|: one more Newton step takes the
        # residual (up to tol) down to rounding; kept if it is a valid root of this piece that near
        # np.int64(2), not a literal 2: numba would compile _newton again for Literal[int](2)
        ok, u, v, k, t, res, its, _ = _newton(P, m, best_u, best_v, ox, oy, oz, dx, dy, dz, 0.0, np.int64(2))
        iterations += its
        if res < best_res and abs(t - best_t) * cosine <= 4.0 * best_res:
            state = _root_in(u0, u1, v0, v1, kept, m, u, v, t, t_min, t_max, ex_m, ex_u, ex_v, ex_ru, ex_rv)
            if state == 1 or (state == 4 and point_kept(T, m, u, v)):
                best_t, best_u, best_v, best_k, best_res = t, u, v, k, res
    return found, best_t, best_u, best_v, best_k, best_res, iterations


@njit(cache=True, nogil=True)
def trace_rays(
    start,
    stop,
    P,
    T,
    B,
    origin,
    direction,
    t_min,
    t_max,
    tol,
    max_iterations,
    any_hit,
    retry_depth,
    cull_tol,
    ex,
    hit,
    t,
    u,
    v,
    patch,
    surface,
    residual,
    iterations,
    budget,
    halt,
):
    """Nearest (or any) valid root of rays start..stop-1 of origin, direction (N, 3) (unit
    directions), with t_min, t_max (N,) and the exclusion ex (an Exclusion of (N,) arrays); results
    into (N,) outputs as Hits holds them: hit, t, u, v, patch, surface, residual (NaN, -1 where
    there is no hit) and iterations (int32, clipped). budget: each ray's work bound in
    Newton iterations; once spent, no further piece is solved and the nearest root found so far is
    the answer (the piece being solved completes: at most its retries' work more). halt: (1,)
    uint8, read before each ray: set, the slice ends there (an interruption). Called on slices by
    threads.run_chunks (stoppable). One loop, no call per ray: a call passing the tables (tuples
    of arrays) costs reference counting of every array, per ray."""
    pm, qm = B.patch_net.shape[1], B.patch_net.shape[2]
    size = 4 * retry_depth + 8
    stack = np.empty(STACK, dtype=np.int64)  # scratch, once per slice
    stack_t = np.empty(STACK)
    nets = np.empty((size, pm, qm, 4))
    rects = np.empty((size, 4))
    depth = np.empty(size, dtype=np.int64)
    tmp = np.empty(max(pm, qm))
    for i in range(start, stop):
        if halt[0]:
            return
        ox, oy, oz = origin[i, 0], origin[i, 1], origin[i, 2]
        dx, dy, dz = direction[i, 0], direction[i, 1], direction[i, 2]
        lo_t, hi_t = t_min[i], t_max[i]
        ex_m, ex_u, ex_v, ex_ru, ex_rv = ex.surface[i], ex.u[i], ex.v[i], ex.radius_u[i], ex.radius_v[i]
        e = ray_frame(dx, dy, dz)
        ix = 1.0 / dx if abs(dx) > 1e-300 else np.copysign(1e300, dx)
        iy = 1.0 / dy if abs(dy) > 1e-300 else np.copysign(1e300, dy)
        iz = 1.0 / dz if abs(dz) > 1e-300 else np.copysign(1e300, dz)
        best_t, best_u, best_v, best_k, best_res = np.inf, np.nan, np.nan, -1, np.nan
        work = 0
        # The leaf holding the ray's start is skipped unless the ray leaves it grazing: a leaf's normals
        # lie within its cone (bvh.py), so only a grazing ray meets it again (a cupped surface's shadow).
        skip_start = ex_m >= 0 and not _grazing(P, locate(P, ex_m, ex_u, ex_v), ex_u, ex_v, dx, dy, dz)
        near, far = _slab(B.node_bounds[0], ox, oy, oz, ix, iy, iz)
        top = 0
        if near <= far and far >= lo_t and near <= hi_t:
            stack[0], stack_t[0] = 0, near
            top = 1
        while top > 0:  # ends with the stack, or at top = -1: out of budget, or any_hit's root
            top -= 1
            node, entry = stack[top], stack_t[top]
            if entry >= best_t:
                continue
            left = B.node_left[node]
            if left < 0:
                for leaf in range(B.node_first[node], B.node_first[node] + B.node_count[node]):
                    if work >= budget:
                        top = -1
                        break
                    if skip_start and B.leaf_surface[leaf] == ex_m:
                        r = B.leaf_rect[leaf]
                        if r[0] <= ex_u <= r[1] and r[2] <= ex_v <= r[3]:
                            continue
                    lo, hi = _obb_slab(B.leaf_obb[leaf], ox, oy, oz, dx, dy, dz)
                    if not (lo <= hi and hi >= lo_t and lo <= hi_t and lo < best_t):
                        continue
                    if not straddles(
                        leaf_net(B.patch_net, B.leaf_net, B.leaf_net_row, leaf),
                        B.leaf_degree[leaf, 0],
                        B.leaf_degree[leaf, 1],
                        ox,
                        oy,
                        oz,
                        e,
                        dx,
                        dy,
                        dz,
                        lo_t,
                        min(hi_t, best_t),
                        cull_tol,
                    ):
                        continue  # the piece's hull misses the ray: no root, no Newton
                    found, tt, uu, vv, k, res, its = _solve_piece(
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
                        lo_t,
                        min(hi_t, best_t),
                        tol,
                        max_iterations,
                        retry_depth,
                        cull_tol,
                        ex_m,
                        ex_u,
                        ex_v,
                        ex_ru,
                        ex_rv,
                        nets,
                        rects,
                        depth,
                        tmp,
                        any_hit,
                    )
                    work += its
                    if found and tt < best_t:
                        best_t, best_u, best_v, best_k, best_res = tt, uu, vv, k, res
                        if any_hit:
                            top = -1
                            break
                continue
            right = B.node_right[node]
            n1, f1 = _slab(B.node_bounds[left], ox, oy, oz, ix, iy, iz)
            n2, f2 = _slab(B.node_bounds[right], ox, oy, oz, ix, iy, iz)
            hit1 = n1 <= f1 and f1 >= lo_t and n1 <= hi_t and n1 < best_t
            hit2 = n2 <= f2 and f2 >= lo_t and n2 <= hi_t and n2 < best_t
            if hit1 and hit2 and top + 2 <= stack.shape[0]:
                if n1 <= n2:  # push the farther first: the nearer is walked first
                    stack[top], stack_t[top], stack[top + 1], stack_t[top + 1] = right, n2, left, n1
                else:
                    stack[top], stack_t[top], stack[top + 1], stack_t[top + 1] = left, n1, right, n2
                top += 2
            elif hit1:
                stack[top], stack_t[top] = left, n1
                top += 1
            elif hit2:
                stack[top], stack_t[top] = right, n2
                top += 1
        found = best_k >= 0  # else best_u, best_v, best_res are NaN and best_k -1 already
        hit[i], t[i], u[i], v[i], patch[i] = found, best_t if found else np.nan, best_u, best_v, best_k
        surface[i] = P.surface[best_k] if found else -1
        residual[i], iterations[i] = best_res, min(work, INT32_MAX)

"""The patch table as flat arrays, and its evaluation inside compiled kernels.

``PatchArrays`` (built by ``bsrt.geometry.patches.PatchSet``) holds every Bezier patch
of a scene in the power basis of its local parameters (s, t) in [0, 1]^2:

    coef:        (C,) float64, all patches' coefficients; patch k's start at
                 coef_start[k], laid out [i][c][j] (s^i, component c, t^j),
                 c over x, y, z (and w for a rational patch).
    coef_start:  (P,) int64.
    degree:      (P, 2) int64, (p, q).
    dim:         (P,) int64, 3 (polynomial) or 4 (rational, homogeneous).
    bounds:      (P, 4) float64, (u0, u1, v0, v1) in the surface's knot domain.
    inv_size:    (P, 2) float64, 1 / (u1 - u0), 1 / (v1 - v0).
    surface:     (P,) int64, the surface of each patch.
    domain:      (M, 4) float64, (umin, umax, vmin, vmax) of each surface.
    breaks_u:    (Bu,) float64, every surface's distinct u knots in its
                 domain, surface after surface; surface m's are
                 breaks_u[break_start_u[m] : break_start_u[m + 1]].
    break_start_u: (M + 1,) int64.
    breaks_v, break_start_v: the same in v.
    grid_start:  (M,) int64, patch_grid[grid_start[m] + iu * spans_v + iv]
                 is the patch of span (iu, iv) of surface m.
    patch_grid:  (P,) int64.

Evaluation is Horner's scheme in t then s, all components (and derivatives)
in one pass; no temporary arrays, so a kernel can call it per iteration of a
per-ray loop.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from bsrt.kernels.jit import njit


class PatchArrays(NamedTuple):
    coef: np.ndarray
    coef_start: np.ndarray
    degree: np.ndarray
    dim: np.ndarray
    bounds: np.ndarray
    inv_size: np.ndarray
    surface: np.ndarray
    domain: np.ndarray
    breaks_u: np.ndarray
    break_start_u: np.ndarray
    breaks_v: np.ndarray
    break_start_v: np.ndarray
    grid_start: np.ndarray
    patch_grid: np.ndarray


# inline="always": point and frame get their copies with ``derivatives`` a constant (and, for a bicubic
# patch, the degrees too: below), instead of numba compiling _horner standalone once per literal value.
@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def _horner(coef, base, p, q, dim, s, t, derivatives):
    """Homogeneous value (and d/ds, d/dt) of one patch at local (s, t), all components in one pass.

    Returns 12 floats: (x, y, z, w), (xs, ys, zs, ws), (xt, yt, zt, wt); w = 1
    and its derivatives 0 for a polynomial patch (dim 3)."""
    stride = q + 1
    x = y = z = 0.0
    w = 1.0 if dim == 3 else 0.0
    xs = ys = zs = ws = xt = yt = zt = wt = 0.0
    for i in range(p, -1, -1):
        row = base + i * dim * stride
        ax, ay, az = coef[row + q], coef[row + stride + q], coef[row + 2 * stride + q]
        aw = coef[row + 3 * stride + q] if dim == 4 else 0.0
        tx = ty = tz = tw = 0.0
        for j in range(q - 1, -1, -1):
            if derivatives:
                tx, ty, tz, tw = tx * t + ax, ty * t + ay, tz * t + az, tw * t + aw
            ax = ax * t + coef[row + j]
            ay = ay * t + coef[row + stride + j]
            az = az * t + coef[row + 2 * stride + j]
            if dim == 4:
                aw = aw * t + coef[row + 3 * stride + j]
        if derivatives:
            xs, ys, zs = xs * s + x, ys * s + y, zs * s + z
            xt, yt, zt = xt * s + tx, yt * s + ty, zt * s + tz
            if dim == 4:
                ws, wt = ws * s + w, wt * s + tw
        x, y, z = x * s + ax, y * s + ay, z * s + az
        if dim == 4:
            w = w * s + aw
    return x, y, z, w, xs, ys, zs, ws, xt, yt, zt, wt


# point and frame: bicubic polynomial patches (spline scenes, freeform CAD faces) get a copy of
# _horner with the degrees and dim constants: its loops have a known length (LLVM unrolls them) and
# its tests of dim fold away. One Newton step (an evaluation with derivatives): 97 -> 71 ns on the
# 2-core machine, one thread; the same arithmetic in the same order, so the same results. A copy per
# degree pair costs compile time: (2, 1) rational (the cylinders of CAD parts) written here as well took
# 1.3 s more of one core's compile for a CAD part's step 0-10% faster, so bicubic alone. The branches
# stay in point and frame: through a shared inlined helper returning the tuple, the step took 80 ns.
@njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True)
def point(P, k, u, v):
    """S(u, v) of patch k at global parameters: (x, y, z)."""
    s = (u - P.bounds[k, 0]) * P.inv_size[k, 0]
    t = (v - P.bounds[k, 2]) * P.inv_size[k, 1]
    p, q, dim = P.degree[k, 0], P.degree[k, 1], P.dim[k]
    if p == 3 and q == 3 and dim == 3:
        h = _horner(P.coef, P.coef_start[k], 3, 3, 3, s, t, False)
    else:
        h = _horner(P.coef, P.coef_start[k], p, q, dim, s, t, False)
    return h[0] / h[3], h[1] / h[3], h[2] / h[3]


@njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True)
def frame(P, k, u, v):
    """S, S_u, S_v of patch k at global (u, v): 9 floats (x, y, z, xu, yu, zu, xv, yv, zv)."""
    du, dv = P.inv_size[k, 0], P.inv_size[k, 1]
    s = (u - P.bounds[k, 0]) * du
    t = (v - P.bounds[k, 2]) * dv
    p, q, dim = P.degree[k, 0], P.degree[k, 1], P.dim[k]
    if p == 3 and q == 3 and dim == 3:
        x, y, z, w, xs, ys, zs, ws, xt, yt, zt, wt = _horner(P.coef, P.coef_start[k], 3, 3, 3, s, t, True)
    else:
        x, y, z, w, xs, ys, zs, ws, xt, yt, zt, wt = _horner(P.coef, P.coef_start[k], p, q, dim, s, t, True)
    x, y, z = x / w, y / w, z / w  # the quotient rule (w = 1, ws = wt = 0 for a polynomial patch)
    xs, ys, zs = (xs - x * ws) / w, (ys - y * ws) / w, (zs - z * ws) / w
    xt, yt, zt = (xt - x * wt) / w, (yt - y * wt) / w, (zt - z * wt) / w
    return x, y, z, xs * du, ys * du, zs * du, xt * dv, yt * dv, zt * dv


@njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True)
def _span(breaks, first, stop, x):
    """Index (0-based within the surface) of the span of sorted breaks[first:stop] holding x."""
    lo, hi = first, stop - 2  # spans first .. stop - 2
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if breaks[mid] <= x:
            lo = mid
        else:
            hi = mid - 1
    return lo - first


@njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True)
def clamp(P, m, u, v):
    """(u, v) clipped into surface m's domain."""
    d = P.domain  # scalar indexing: a row view would cost a reference count per call
    return min(max(u, d[m, 0]), d[m, 1]), min(max(v, d[m, 2]), d[m, 3])


@njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True)
def locate(P, m, u, v):
    """Patch of surface m holding (u, v) (parameters outside the domain: the nearest)."""
    fu, su = P.break_start_u[m], P.break_start_u[m + 1]
    fv, sv = P.break_start_v[m], P.break_start_v[m + 1]
    iu = _span(P.breaks_u, fu, su, u)
    iv = _span(P.breaks_v, fv, sv, v)
    return P.patch_grid[P.grid_start[m] + iu * (sv - fv - 1) + iv]


@njit(cache=True, error_model="numpy", _nrt=False, no_cpython_wrapper=True)
def inside_patch(P, k, u, v):
    b = P.bounds
    return b[k, 0] <= u <= b[k, 1] and b[k, 2] <= v <= b[k, 3]


@njit(cache=True, error_model="numpy", _nrt=False)
def evaluate_many(P, patch, u, v, S, Su, Sv, derivatives):
    """S (and S_u, S_v) of patch[i] at (u[i], v[i]) into (3, N) arrays."""
    for i in range(patch.shape[0]):
        if derivatives:
            f = frame(P, patch[i], u[i], v[i])
            S[0, i], S[1, i], S[2, i] = f[0], f[1], f[2]
            Su[0, i], Su[1, i], Su[2, i] = f[3], f[4], f[5]
            Sv[0, i], Sv[1, i], Sv[2, i] = f[6], f[7], f[8]
        else:
            x, y, z = point(P, patch[i], u[i], v[i])
            S[0, i], S[1, i], S[2, i] = x, y, z


@njit(cache=True, error_model="numpy", _nrt=False)
def locate_many(P, surface, u, v, out):
    """out[i] = the patch of surface[i] holding (u[i], v[i])."""
    for i in range(surface.shape[0]):
        out[i] = locate(P, surface[i], u[i], v[i])

"""Root finding per (ray, start) item: Qx = Qy = 0 on the patch table (paper 2.2, 2.3).

A ray o + t d meets S(u, v) where S - o is parallel to d. With e1, e2 an
orthonormal pair perpendicular to d (the rotation with rows (e1, e2, d) moves
the ray onto the z axis), a hit solves

    Qx(u, v) = e1 . (S(u, v) - o) = 0,   Qy(u, v) = e2 . (S(u, v) - o) = 0,

and w = Qx^2 + Qy^2 is the squared distance between the ray and S(u, v),
which the tolerance bounds; t = d . (S - o). The rotation is applied to the
evaluated point, not to the control net: two dot products per evaluation.

Methods (ids GRADIENT, FAST, NEWTON; their names are declared in bsrt/methods.py):

- newton: Newton on (Qx, Qy) with a Levenberg-Marquardt term of 1e-12 of the
  Jacobian's scale (finite steps where J is singular). ``stop_on_growth``
  gives up as soon as w grows (Martin et al.'s rule for far starts).
- gradient (paper eq. 7-9): u -= h_u dw/du, v -= h_v dw/dv. Step rule: per
  parameter, h_u = h / |dQ/du|^2 and h_v = h / |dQ/dv|^2 (the gradient
  measured in arc length, so a surface that is fast in u and slow in v, like
  a surface of revolution, does not zig-zag), with h the Cauchy step of the
  Gauss-Newton model along that direction g: h = (g . J^T q) / |J g|^2.
  S, S_u, S_v are evaluated at every point; a step that does not decrease w
  is halved from the last accepted point.
- fast (paper 2.3: keep the previous gradient while w decreases): the
  surface derivatives (the Jacobian J of (Qx, Qy)) are computed at every
  other point only. From a point with fresh derivatives it takes gradient's
  step; the next point evaluates S alone and, if w decreased, steps along
  its gradient (from the kept J and the new residual) plus beta times the
  previous direction, beta = (r . z) / (r' . z') with r = J^T q and z the
  scaled gradient (preconditioned conjugate gradients, Fletcher-Reeves).
  Two such steps reach the minimum of the kept Gauss-Newton model, where a
  gradient step alone zig-zags along a narrow valley of w: reusing the
  previous gradient is what makes the saved derivative evaluations pay.
  When w stops decreasing on a kept J, J is recomputed at the last accepted
  point. (Repeating the previous gradient step unchanged, the paper's
  literal rule, cannot pay after a Cauchy step: that step already reaches
  the model's minimum along its direction.)

Parameters are clipped to the surface's domain after every step; an item
whose clipped step is zero is stuck and fails.

Stagnation: every method stops (not converged) once w has not fallen below
half its last marked value for STALL_STEPS evaluations in a row: the
steps no longer move the point by more than float64's rounding of S (w
then only jitters at its noise floor), so a tolerance at that floor ends
in a few dozen iterations, whatever max_iterations is.
"""

from __future__ import annotations

import numpy as np

from bsrt.kernels.jit import njit
from bsrt.kernels.method_ids import FAST, GRADIENT, NEWTON
from bsrt.kernels.patches import clamp, frame, inside_patch, locate, point
from bsrt.kernels.trim import point_kept

MAX_HALVINGS = 60
STALL_STEPS = 32  # evaluations without halving w: stagnation


@njit(cache=True, error_model="numpy", _nrt=False)
def ray_frame(dx, dy, dz):
    """e1, e2 (6 floats) perpendicular to the unit direction d and to each other
    (Duff et al. 2017, "Building an orthonormal basis, revisited")."""
    sign = 1.0 if dz >= 0.0 else -1.0
    a = -1.0 / (sign + dz)
    b = dx * dy * a
    return 1.0 + sign * dx * dx * a, sign * b, -sign * dx, b, sign + dy * dy * a, -dy


@njit(cache=True, error_model="numpy", _nrt=False, inline="always")
def solve_one(P, m, u, v, ox, oy, oz, dx, dy, dz, method, tol2, max_iterations, stop_on_growth):
    """One item from (u, v) on surface m.

    Returns (converged, u, v, patch, t, residual, iterations, cosine): the
    final parameters (in the domain), their patch, the distance along the ray
    and the ray-surface distance there; for NEWTON (derivatives at every
    point), |cos| of the angle between d and the normal S_u x S_v at the last
    point (the hierarchy's grazing test, from the frame already at hand), for
    the other methods NaN.

    (Long: one loop serves the three methods, which share the evaluation,
    the acceptance test and the clipping; it is inlined into its callers, so
    splitting it would cost nothing at run time but scatter one algorithm.)
    """
    e1x, e1y, e1z, e2x, e2y, e2z = ray_frame(dx, dy, dz)
    c1 = e1x * ox + e1y * oy + e1z * oz
    c2 = e2x * ox + e2y * oy + e2z * oz
    u, v = clamp(P, m, u, v)
    k = locate(P, m, u, v)
    # Gradient methods: the last accepted point and the step taken from it.
    ua, va, ka, wa = u, v, k, np.inf
    a = b = c = d = 0.0  # the Jacobian of (Qx, Qy) in use
    gu = gv = h = rz_prev = 0.0
    need_derivatives = True
    jacobian_here = False  # J was computed at the accepted point
    refresh = False
    halvings = 0
    w_prev = np.inf
    w_mark, stall = np.inf, 0  # stagnation: the last w that halved the one before, evaluations since
    converged = False
    x = y = z = xu = yu = zu = xv = yv = zv = 0.0
    iterations = 0
    for it in range(1, max_iterations + 1):
        iterations = it
        if need_derivatives:
            x, y, z, xu, yu, zu, xv, yv, zv = frame(P, k, u, v)
        else:
            x, y, z = point(P, k, u, v)
        qx = e1x * x + e1y * y + e1z * z - c1
        qy = e2x * x + e2y * y + e2z * z - c2
        w = qx * qx + qy * qy
        if w <= tol2:
            converged = True
            break
        if not w < np.inf or it == max_iterations:  # NaN or overflow, or out of iterations
            break
        if w < 0.5 * w_mark:
            w_mark, stall = w, 0
        else:
            stall += 1
            if stall >= STALL_STEPS:  # stagnation: float64 resolves no further progress
                break
        if method == NEWTON:
            if stop_on_growth and w > w_prev:
                break
            w_prev = w
            a = e1x * xu + e1y * yu + e1z * zu
            b = e1x * xv + e1y * yv + e1z * zv
            c = e2x * xu + e2y * yu + e2z * zu
            d = e2x * xv + e2y * yv + e2z * zv
            j00, j01, j11 = a * a + c * c, a * b + c * d, b * b + d * d
            mu = 1e-12 * (j00 + j11) + 1e-300
            g0, g1 = a * qx + c * qy, b * qx + d * qy
            det = (j00 + mu) * (j11 + mu) - j01 * j01
            nu = u - ((j11 + mu) * g0 - j01 * g1) / det
            nv = v - ((j00 + mu) * g1 - j01 * g0) / det
        elif w < wa or refresh:  # accept this point, take a new step
            refresh = False
            halvings = 0
            ua, va, ka, wa = u, v, k, w
            jacobian_here = need_derivatives
            if need_derivatives:
                a = e1x * xu + e1y * yu + e1z * zu
                b = e1x * xv + e1y * yv + e1z * zv
                c = e2x * xu + e2y * yu + e2z * zu
                d = e2x * xv + e2y * yv + e2z * zv
            # gradient of w, each parameter scaled by 1 / |d(Qx, Qy)/d(parameter)|^2
            ru, rv = a * qx + c * qy, b * qx + d * qy  # J^T q: half the gradient of w
            zu = 2.0 * ru / (a * a + c * c + 1e-300)
            zv = 2.0 * rv / (b * b + d * d + 1e-300)
            rz = ru * zu + rv * zv
            if jacobian_here:  # steepest descent
                gu, gv = zu, zv
            else:  # fast, second step on the kept J: conjugate to the first (keeps the previous gradient)
                beta = rz / (rz_prev + 1e-300)
                gu, gv = zu + beta * gu, zv + beta * gv
            rz_prev = rz
            jg0, jg1 = a * gu + b * gv, c * gu + d * gv
            h = (ru * gu + rv * gv) / (jg0 * jg0 + jg1 * jg1 + 1e-300)  # the model's minimum along -g
            nu, nv = ua - h * gu, va - h * gv
            need_derivatives = method == GRADIENT or not jacobian_here
        elif method == FAST and not jacobian_here:  # the kept J no longer helps: recompute it
            u, v, k = ua, va, ka
            need_derivatives = True
            refresh = True
            continue
        else:  # rejected: halve the step from the accepted point
            halvings += 1
            if halvings > MAX_HALVINGS:
                break
            h *= 0.5
            nu, nv = ua - h * gu, va - h * gv
            need_derivatives = method == GRADIENT
        nu, nv = clamp(P, m, nu, nv)
        base_u, base_v = (u, v) if method == NEWTON else (ua, va)
        if nu == base_u and nv == base_v:  # clipped at the border with nowhere to go
            if method == FAST and not jacobian_here:  # perhaps only the kept J points outward
                u, v, k = ua, va, ka
                need_derivatives = True
                refresh = True
                continue
            break
        u, v = nu, nv
        if not inside_patch(P, k, u, v):
            k = locate(P, m, u, v)
    t = dx * (x - ox) + dy * (y - oy) + dz * (z - oz)
    cosine = np.nan
    if method == NEWTON:  # the same arithmetic as evaluating the frame again (traverse._normal)
        nx = yu * zv - zu * yv
        ny = zu * xv - xu * zv
        nz = xu * yv - yu * xv
        cosine = abs(nx * dx + ny * dy + nz * dz) / max(np.sqrt(nx * nx + ny * ny + nz * nz), 1e-300)
    if not converged and method != NEWTON and wa < np.inf and not w <= wa:
        # report the best point seen (its S is not at hand: evaluate it)
        u, v, k = ua, va, ka
        x, y, z = point(P, k, u, v)
        t = dx * (x - ox) + dy * (y - oy) + dz * (z - oz)
        w = wa
    return converged, u, v, k, t, np.sqrt(w), iterations, cosine


@njit(cache=True, nogil=True, error_model="numpy", _nrt=False)
def solve_items(
    start,
    stop,
    P,
    T,
    origin,
    direction,
    ray,
    surface,
    u0,
    v0,
    method,
    tolerance,
    max_iterations,
    stop_on_growth,
    converged,
    trimmed,
    u,
    v,
    patch,
    t,
    residual,
    iterations,
    patch_surface,
    hit,
    hit_surface,
    failed,
):
    """solve_one for items start..stop-1, a root kept only where its surface's trims (T) keep it.

    Item i is ray ray[i] (into origin, direction (N, 3), unit directions;
    ray (0,): ray i), surface[i] (-1: no start), start (u0[i], v0[i]).
    Writes (M,) converged (after the trims), trimmed (converged where the
    trims remove it), u, v, patch, t, residual, iterations; an item without
    a start: not converged, NaN, patch -1, 0 iterations. Called on slices by
    threads.run_chunks.

    As hits (hit, hit_surface, failed (M,), not (0,): the map tracer's
    seeds, item i pixel i): u, v, patch, t, residual are written as Hits'
    fields instead (NaN, -1 where there is no hit), with hit (a converged
    root with t > 0), hit_surface (patch_surface[patch], -1) and failed (a
    start without a hit).
    """
    tol2 = tolerance * tolerance
    identity = ray.shape[0] == 0
    as_hits = hit.shape[0] > 0
    for i in range(start, stop):
        r = i if identity else ray[i]
        m = surface[i]
        if m < 0:
            converged[i] = trimmed[i] = False
            u[i] = v[i] = t[i] = residual[i] = np.nan
            patch[i], iterations[i] = -1, 0
            if as_hits:
                hit[i], hit_surface[i], failed[i] = False, -1, False
            continue
        ok, uu, vv, k, tt, res, its, _ = solve_one(
            P,
            m,
            u0[i],
            v0[i],
            origin[r, 0],
            origin[r, 1],
            origin[r, 2],
            direction[r, 0],
            direction[r, 1],
            direction[r, 2],
            method,
            tol2,
            max_iterations,
            stop_on_growth,
        )
        cut = ok and not point_kept(T, m, uu, vv)
        ok = ok and not cut
        converged[i], trimmed[i], iterations[i] = ok, cut, its
        if as_hits:
            h = ok and tt > 0
            add = 0.0 if h else np.nan
            hit[i], failed[i] = h, not h
            hit_surface[i] = patch_surface[k] if h else -1
            uu, vv, tt, res, k = uu + add, vv + add, tt + add, res + add, k if h else -1
        u[i], v[i], patch[i], t[i], residual[i] = uu, vv, k, tt, res

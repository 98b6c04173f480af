"""The closest point of a B-spline surface to given points: (x, y) with S(x, y) nearest each point.

One inverter for every reader that needs one, one damped Newton loop
(``_damped_newton``): :func:`invert` (from given starts: the OpenCASCADE
import's tabulated parameter maps), :class:`SurfaceInverse` (from a hint or the
nearest point of a grid) and :class:`CurveInverse` (the same on the surface's
Bezier pieces: the IGES reader's model-space curves on surfaces), and
:class:`RevolutionInverse` in closed form.
"""

from __future__ import annotations

import math

import numpy as np

from bsrt.geometry.bspline import (
    BSplineSurface,
    basis_functions,
    bezier_patches,
    evaluate,
    find_span,
    rational_quotient,
)

_DAMP = 1e-14  # the smallest damping (relative to the normal matrix's diagonal): Gauss-Newton


def invert(surface: BSplineSurface, points: np.ndarray, x, y, size: float, iterations: int = 60):
    """(x, y), each (N,) float64, in the surface's domain with S(x, y) nearest ``points`` (N, 3), from starts x, y (N,).

    Levenberg-Marquardt, clamped to the domain, all points at once. Each
    point's damping starts at Gauss-Newton's (1e-14 of the normal matrix's
    diagonal); a step that leaves the point further from its target than it
    was is undone and retried with 10 times the damping (far from the
    surface the Gauss-Newton step overshoots, and can cycle), an accepted one
    divides it by 10 again. A parameter held at the domain's edge by its step
    leaves the other one a 1-D step (projected Newton: the coupled step would
    converge slowly, and beside the constrained minimum). A point stops when
    its step or its residual reaches rounding level (1e-14 of the domain, of
    ``size``). At a degenerate point (a pole) the free parameter stays at its
    start. Good starts matter: it converges to the nearest local minimum.
    """
    return _damped_newton(
        lambda u, v: evaluate(surface, u, v), (surface.domain_u, surface.domain_v), points, x, y, size, iterations
    )


def _grid_points(s: BSplineSurface, gu, gv) -> np.ndarray:
    """(len(gu), len(gv), 3) float64: S at the grid gu x gv, as a tensor product (one
    basis matrix per direction)."""
    mats = []
    for g, knots, p, n in ((gu, s.knots_u, s.degree[0], s.shape[0]), (gv, s.knots_v, s.degree[1], s.shape[1])):
        span = find_span(knots, p, n, g)
        vals, _ = basis_functions(knots, p, span, g)
        m = np.zeros((len(g), n))
        np.add.at(m, (np.arange(len(g))[:, None], span[:, None] - p + np.arange(p + 1)[None, :]), vals)
        mats.append(m)
    h = np.einsum("ia,abk->ibk", mats[0], s.homogeneous())
    h = np.einsum("jb,ibk->ijk", mats[1], h)
    return h[..., :3] / h[..., 3:]


class SurfaceInverse:
    """Closest-point inversion onto a B-spline surface: points (N, 3) -> (u, v) (N, 2),
    by :func:`invert` from a hint, or from the nearest point of a grid over the surface
    (3 points per knot span, at most 256 per direction, less its collapsed rows and
    columns) where there is no hint or the hint leads to a far-off local minimum."""

    def __init__(self, s: BSplineSurface):
        self.s = s
        (u0, u1), (v0, v1) = s.domain_u, s.domain_v
        self.lo, self.hi = np.array([u0, v0]), np.array([u1, v1])
        ku = np.unique(np.clip(s.knots_u, u0, u1))
        kv = np.unique(np.clip(s.knots_v, v0, v1))
        gu = np.unique(np.concatenate([np.linspace(a, b, 4) for a, b in zip(ku[:-1], ku[1:])]))
        gv = np.unique(np.concatenate([np.linspace(a, b, 4) for a, b in zip(kv[:-1], kv[1:])]))
        gu, gv = gu[:: max(1, -(-len(gu) // 256))], gv[:: max(1, -(-len(gv) // 256))]
        grid = _grid_points(s, gu, gv)
        self.size = float(np.linalg.norm(np.ptp(s.points.reshape(-1, 3), axis=0)))
        # rows and columns collapsed to a point (a pole, an apex) are left out: a start there
        # could not move along the collapsed parameter
        keep_u = np.ptp(grid, axis=1).max(axis=1) > 1e-12 * self.size
        keep_v = np.ptp(grid, axis=0).max(axis=1) > 1e-12 * self.size
        if keep_u.any() and keep_v.any():
            grid, gu, gv = grid[keep_u][:, keep_v], gu[keep_u], gv[keep_v]
        uu, vv = np.meshgrid(gu, gv, indexing="ij")
        self.grid_uv = np.stack([uu.ravel(), vv.ravel()], 1)
        self.grid = grid.reshape(-1, 3)
        # closed directions (the surface's two edges across them coincide): their seam samples
        # are put on the side their neighbours along a curve are on (``iges.pcurves.invert_curves``)
        self.closed = tuple(
            bool(np.abs(np.take(grid, 0, axis=k) - np.take(grid, -1, axis=k)).max() <= 1e-9 * self.size)
            for k in range(2)
        )
        self.grid_t = np.ascontiguousarray(self.grid.T)
        self.grid_sq = 0.5 * np.einsum("gk,gk->g", self.grid, self.grid)

    def _nearest(self, pts):
        out = np.empty((len(pts), 2))
        step = max(1, 1_000_000 // len(self.grid))
        for a in range(0, len(pts), step):
            # p.g - |g|^2 / 2: the nearest has the most (einsum: no threaded BLAS, which a busy
            # machine slows down many times over for this thin product)
            d = np.einsum("nk,kg->ng", pts[a : a + step], self.grid_t)
            d -= self.grid_sq
            out[a : a + step] = self.grid_uv[np.argmax(d, axis=1)]
        return out

    def _newton(self, pts, uv):
        """(uv (N, 2), S_u, S_v (N, 3) and distances (N,)) from starts uv: the derivatives and
        distances at each point's last evaluated parameters (uv less its last step, where that
        one was predicted small: ``_damped_newton``'s ``evaluations``)."""
        s, domain = self.s, (self.s.domain_u, self.s.domain_v)
        u, v, dist, su, sv = _damped_newton(
            lambda u, v: evaluate(s, u, v), domain, pts, uv[:, 0], uv[:, 1], self.size, evaluations=True
        )
        return np.stack([u, v], 1), su, sv, dist

    @property
    def seams(self):
        """((u0, u1, closed in u), (v0, v1, closed in v)) for ``iges.pcurves.invert_curves``."""
        return tuple((self.lo[k], self.hi[k], self.closed[k]) for k in range(2))

    def __call__(self, pts, hint=None):
        """(u, v) of the points' closest points, from ``hint`` or the nearest grid point;
        NaN in a parameter along which the surface does not move there (a collapsed edge)."""
        pts = np.asarray(pts, float)
        uv, su, sv, dist = self._newton(pts, self._nearest(pts) if hint is None else np.clip(hint, self.lo, self.hi))
        if hint is not None and len(pts):  # far further than the rest: a wrong local minimum?
            far = np.flatnonzero(dist > 10 * np.median(dist) + 1e-9 * self.size)
            if far.size:
                again, su2, sv2, d2 = self._newton(pts[far], self._nearest(pts[far]))
                better = d2 < dist[far]
                uv[far[better]], su[far[better]], sv[far[better]] = again[better], su2[better], sv2[better]
        for k, d in enumerate((su, sv)):
            still = np.linalg.norm(d, axis=1) * (self.hi[k] - self.lo[k]) <= 1e-9 * self.size
            uv[still, k] = np.nan
        return uv


class RevolutionInverse:
    """Closest points on a surface of revolution whose generatrix, in a half-plane bounded by
    the axis, is a segment (a cylinder, a cone, a flat ring) or an arc of a circle (a sphere, a
    torus), in closed form: points (N, 3) -> the B-spline's (x, y) (N, 2), x the generatrix's
    parameter, y = ``to_y(angle)``.

    The closest point lies in the point's own meridian half-plane (at its angle about the
    axis, taken nearest the hint's and clamped to the turn's range) at the point of the
    generatrix nearest it there (:class:`_Segment`, :class:`_Arc`). NaN in y where that point
    is on the axis (an apex, a pole: any angle). ``seams`` as :class:`SurfaceInverse`'s.
    Returns None from :meth:`of` for other generatrices.
    """

    def __init__(self, profile, origin, axis, e1, angles, to_y, to_angle, size: float):
        self.profile, self.o, self.a, self.e1, self.size = profile, origin, axis, e1, size
        self.e2 = np.cross(axis, e1)
        self.angles, self.to_y, self.to_angle = angles, to_y, to_angle
        self.closed = (profile.closed, angles[1] - angles[0] >= 2 * np.pi * (1 - 1e-12))

    @classmethod
    def of(cls, degree, knots, points, weights, origin, axis, angles, to_y, to_angle, pmap=None):
        """The inverse for a clamped generatrix (degree, knots, points (n, 3), weights, and the map
        ``pmap`` from its file's parameter, a ParamMap or None), or None unless it lies in a
        half-plane bounded by the axis and is one segment (degree 1, two points, even weights) or
        a circular arc (``pmap`` of "tan" pieces: the curve is c + A cos t + B sin t in the file's
        parameter t, as ``iges.bspline.arc_curve`` builds it)."""
        o, a = np.asarray(origin, float), np.asarray(axis, float)
        points = np.asarray(points, float)
        g = points - o
        z = g @ a
        radial = g - z[:, None] * a
        rho = np.linalg.norm(radial, axis=1)
        size = float(np.linalg.norm(np.ptp(points, axis=0))) + float(rho.max())
        if not rho.max() > 0:
            return None
        e1 = radial[int(np.argmax(rho))] / rho.max()  # angle 0: the generatrix's half-plane
        e2 = np.cross(a, e1)
        if np.abs(radial @ e2).max() > 1e-12 * size or (radial @ e1).min() < -1e-12 * size:
            return None
        plane = np.stack([radial @ e1, z], 1)  # (n, 2): (distance from the axis, height)
        even = weights is None or np.ptp(weights) == 0
        if degree == 1 and len(points) == 2 and even:
            profile = _Segment(plane, (float(knots[1]), float(knots[2])))
        elif degree == 2 and pmap is not None and set(pmap.kinds) == {"tan"}:
            profile = _Arc.of(degree, knots, plane, weights, pmap, size)
            if profile is None:
                return None
        else:
            return None
        return cls(profile, o, a, e1, angles, to_y, to_angle, size)

    @property
    def seams(self):
        """((x0, x1, closed in x), (y0, y1, closed in y)) for ``iges.pcurves.invert_curves``."""
        y0, y1 = (float(v) for v in self.to_y(np.array(self.angles)))
        return ((*self.profile.x_range, self.closed[0]), (y0, y1, self.closed[1]))

    def __call__(self, pts, hint=None):
        p = np.asarray(pts, float) - self.o
        z = p @ self.a
        d = p - z[:, None] * self.a
        c, s = d @ self.e1, d @ self.e2
        angle = np.arctan2(s, c)
        a0, a1 = self.angles
        if hint is not None:  # the turn nearest the hint's angle
            hint = np.asarray(hint, float)
            near = self.to_angle(hint[:, 1])
            angle = angle + 2 * np.pi * np.round((near - angle) / (2 * np.pi))
        else:
            angle = _into(angle, a0, a1)
        angle = np.clip(angle, a0, a1)
        x, rho = self.profile.closest(np.hypot(c, s), z, None if hint is None else hint[:, 0])
        uv = np.stack([x, self.to_y(angle)], axis=1)
        uv[rho * (a1 - a0) <= 1e-9 * self.size, 1] = np.nan  # on the axis
        return uv


def _into(angle, a0, a1):
    """Angles (N,) moved by whole turns into [a0, a0 + 2 pi); those past a1 onto the nearer end."""
    angle = a0 + np.mod(angle - a0, 2 * np.pi)
    past = angle > a1
    angle[past] = np.where(angle[past] - a1 <= a0 + 2 * np.pi - angle[past], a1, a0)
    return angle


class _Segment:
    """A generatrix that is a segment in its meridian half-plane: ends (2, 2) (distance from the
    axis, height), on the parameter range x_range."""

    closed = False

    def __init__(self, ends, x_range):
        self.ends, self.x_range = ends, x_range

    def closest(self, rho, z, hint):
        """(x, distance of the nearest point from the axis), each (N,), for points at rho, z (N,)."""
        (r0, z0), (r1, z1) = self.ends
        dr, dz = r1 - r0, z1 - z0
        f = np.clip(((rho - r0) * dr + (z - z0) * dz) / (dr * dr + dz * dz), 0.0, 1.0)
        x0, x1 = self.x_range
        return x0 + f * (x1 - x0), r0 + f * dr


class _Arc:
    """A generatrix that is an arc of a circle in its meridian half-plane: c + A cos t + B sin t
    for t in [t0, t1] (c, A, B (2,): distance from the axis, height; A, B orthogonal and as long
    as the radius), at the B-spline parameter x = pmap(t)."""

    def __init__(self, c, ab, pmap):
        self.c, self.ab, self.pmap = c, ab, pmap
        self.t = (float(pmap.x[0]), float(pmap.x[-1]))
        self.x_range = (float(pmap.s[0]), float(pmap.s[-1]))
        self.closed = self.t[1] - self.t[0] >= 2 * np.pi * (1 - 1e-12)

    @classmethod
    def of(cls, degree, knots, plane, weights, pmap, size):
        """The arc through the curve (degree, knots, points ``plane`` (n, 2), weights) at five
        values of t, or None unless the curve is that arc (to 1e-12 of ``size``) and it spans
        at least 1e-3 radians (a shorter one fixes c poorly)."""
        from bsrt.geometry.trim import TrimCurve

        t0, t1 = float(pmap.x[0]), float(pmap.x[-1])
        if not t1 - t0 >= 1e-3:
            return None
        t = t0 + (t1 - t0) * np.array([0.0, 1 / 3, 2 / 3, 1.0, 1 / 6])  # (the first three: apart on a whole turn)
        at = TrimCurve(degree, np.asarray(knots, float), plane, weights).evaluate(pmap(t))  # (5, 2)
        m = np.stack([np.ones(5), np.cos(t), np.sin(t)], 1)
        try:
            cab = np.linalg.solve(m[:3], at[:3])  # (3, 2): c, A, B
        except np.linalg.LinAlgError:
            return None
        c, ab = cab[0], cab[1:]
        r = np.linalg.norm(ab, axis=1)
        if (
            np.abs(m[3:] @ cab - at[3:]).max() > 1e-12 * size
            or abs(r[0] - r[1]) > 1e-12 * size
            or abs(ab[0] @ ab[1]) > 1e-12 * size * size
        ):
            return None
        return cls(c, ab, pmap)

    def closest(self, rho, z, hint):
        """(x, distance of the nearest point from the axis), each (N,), for points at rho, z (N,),
        the full circle's turn nearest the hint's x (N,) if given."""
        q = np.stack([rho, z], 1) - self.c
        (a, b), (t0, t1) = self.ab, self.t
        t = np.arctan2(q @ b, q @ a)
        if hint is not None:
            near = self.pmap.inverse(hint)
            t = t + 2 * np.pi * np.round((near - t) / (2 * np.pi))
        else:
            t = _into(t, t0, t1)
            if self.closed:  # on the seam (to rounding): its start, as the nearest grid point would give
                t[t - t0 >= 2 * np.pi * (1 - 1e-12)] = t0
        t = np.clip(t, t0, t1)
        return self.pmap(t), self.c[0] + a[0] * np.cos(t) + b[0] * np.sin(t)


class _Pieces:
    """A B-spline surface as its (rational) Bezier pieces in power form over each piece's local
    (s, t) in [0, 1]^2, evaluated at many points with a fixed, small number of NumPy calls (no
    per-degree Python loops; two stacked matrix products, several times faster than the same
    sums by einsum): the evaluator of :class:`CurveInverse`'s Newton steps."""

    def __init__(self, s: BSplineSurface):
        ctrl, bounds = bezier_patches(s)  # (K, p + 1, q + 1, 4), u-major
        p, q = s.degree
        nu = np.unique(bounds[:, 0]).size
        b = bounds.reshape(nu, -1, 4)
        self.nv = b.shape[1]
        coef = np.einsum("ka,lb,nklc->nabc", _power_from_bernstein(p), _power_from_bernstein(q), ctrl)
        self.rational = s.is_rational
        coef = coef if self.rational else coef[..., :3]  # (K, p + 1, q + 1, c), c = 4 or 3
        self.coef = np.ascontiguousarray(
            coef.transpose(0, 1, 3, 2).reshape(len(coef), -1, q + 1)
        )  # (K, (p + 1) c, q + 1)
        self.p1 = p + 1
        # per direction: the pieces' inner starts (searched), starts and 1 / lengths (each piece's)
        self.u = (b[1:, 0, 0].copy(), b[:, 0, 0].copy(), 1.0 / (b[:, 0, 1] - b[:, 0, 0]), np.arange(p + 1))
        self.v = (b[0, 1:, 2].copy(), b[0, :, 2].copy(), 1.0 / (b[0, :, 3] - b[0, :, 2]), np.arange(q + 1))

    @staticmethod
    def _powers(x, axis):
        """(piece index (N,), local powers (N, d + 1), their x-derivatives (N, d + 1)) at x (N,)."""
        inner, lo, scale, e = axis
        i = np.searchsorted(inner, x, side="right")
        k = scale[i]
        pw = ((x - lo[i]) * k)[:, None] ** e
        d = np.zeros_like(pw)
        d[:, 1:] = pw[:, :-1] * e[1:] * k[:, None]
        return i, pw, d

    def __call__(self, u, v):
        """S, S_u, S_v (each (N, 3)) at u, v (N,) (outside the domain: the end pieces extended)."""
        iu, pu, du = self._powers(u, self.u)
        iv, pv, dv = self._powers(v, self.v)
        n = len(iu)
        c = self.coef[iu * self.nv + iv]  # (N, (p + 1) c, q + 1)
        rows = np.matmul(c, np.stack([pv, dv], 2)).reshape(n, self.p1, -1)  # (N, p + 1, 2 c): at v, d/dv
        r = np.matmul(np.stack([pu, du], 1), rows).reshape(n, 2, -1, 2)  # (N, 2 (at u, d/du), c, 2)
        h, hu, hv = r[:, 0, :, 0], r[:, 1, :, 0], r[:, 0, :, 1]
        return rational_quotient(h, hu, hv) if self.rational else (h, hu, hv)


def _power_from_bernstein(n: int) -> np.ndarray:
    """(n + 1, n + 1) M with B_{k,n}(s) = sum_j M[k, j] s^j."""
    k, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    comb = np.vectorize(math.comb)
    return np.where(j >= k, comb(n, j) * comb(np.maximum(j, k), k) * (-1.0) ** (j - k), 0.0)


def _damped_newton(
    at, domain, points, x, y, size: float, iterations: int = 60, step_tol=1e-14, stall_tol=0.0, evaluations=False
):
    """(x, y), each (N,) float64: :func:`invert`'s loop (its docstring says what it does) on the
    surface evaluator ``at`` ((u, v) (N,) -> S, S_u, S_v (N, 3)) over ``domain`` ((u0, u1), (v0, v1)).
    A point stops where its step is ``step_tol`` of the domain, or where the step after it would
    be, going by the last two (both undamped: a contraction ``rate`` below 1/2, the rest of the way
    at most step x rate / (1 - rate); for Newton's quadratic convergence this overestimates), or
    where its residual is 1e-14 of ``size``; a step that made things worse after a step below
    ``stall_tol`` of the domain also stops it, at its accepted parameters (points off the surface
    converge linearly: the last digits cost many steps and move (x, y) by less than that).
    ``evaluations``: also the distances (N,), S_u and S_v (N, 3) at each point's last evaluated
    parameters (its returned ones less the last step, when that one was predicted small)."""
    (a0, a1), (b0, b1) = domain
    x = np.clip(np.array(x, dtype=np.float64), a0, a1)
    y = np.clip(np.array(y, dtype=np.float64), b0, b1)
    lo, hi = np.array([a0, b0]), np.array([a1, b1])
    points = np.asarray(points, dtype=np.float64)
    n = x.shape[0]
    scale = max(1.0, abs(a0), abs(a1), abs(b0), abs(b1))
    best = np.full(n, np.inf)  # |residual| at the accepted parameters acc
    acc = np.stack([x, y], 1)
    acc_su, acc_sv = np.zeros((n, 3)), np.zeros((n, 3))
    cur = acc.copy()
    normal = np.zeros((n, 5))  # a, b, c, g0, g1 of the normal equations at acc
    mu = np.full(n, _DAMP)
    last = np.full(n, np.nan)  # the size of each point's latest step (NaN: none yet)
    idx = np.arange(n)
    for _ in range(iterations):
        if idx.size == 0:
            break
        s, su, sv = at(cur[idx, 0], cur[idx, 1])
        r = points[idx] - s
        dist = np.sqrt(np.einsum("ni,ni->n", r, r))
        good = dist <= best[idx] * (1 + 1e-12) + 1e-15 * size
        g = idx[good]  # accepted: new normal equations there; the others retry with 10x the damping
        best[g], acc[g] = dist[good], cur[g]
        su, sv, r = su[good], sv[good], r[good]
        acc_su[g], acc_sv[g] = su, sv
        normal[g] = np.stack(
            [
                np.einsum("ni,ni->n", su, su),
                np.einsum("ni,ni->n", su, sv),
                np.einsum("ni,ni->n", sv, sv),
                np.einsum("ni,ni->n", su, r),
                np.einsum("ni,ni->n", sv, r),
            ],
            1,
        )
        mu[idx[~good]] *= 10.0
        a, b, c, g0, g1 = normal[idx].T
        damp = mu[idx] * (a + c) + 1e-300
        a, c = a + damp, c + damp
        det = a * c - b * b
        det = np.where(np.abs(det) > 1e-300, det, 1e-300)
        d = np.stack([(c * g0 - b * g1) / det, (a * g1 - b * g0) / det], 1)
        start = acc[idx]
        held = ((start <= lo) & (d < 0)) | ((start >= hi) & (d > 0))  # (M, 2)
        one_d = np.stack([g0 / a, g1 / c], 1)  # the free parameter's step where the other is held
        d = np.where(held, 0.0, np.where(held[:, ::-1], one_d, d))
        cur[idx] = np.clip(start + d, lo, hi)
        moved = np.hypot(*(cur[idx] - start).T)
        # a step this small that made things worse: rounding, the accepted parameters stand
        done = (moved <= step_tol * scale) | (~good & (last[idx] <= stall_tol * scale))
        rate = moved / last[idx]  # over the step just confirmed (NaN before the first)
        done |= good & (mu[idx] <= _DAMP) & (rate < 0.5) & (moved * rate <= (1 - rate) * step_tol * scale)
        last[idx] = moved
        back = idx[done & ~good]
        cur[back] = acc[back]
        done[good] |= dist[good] <= 1e-14 * size
        mu[g] = np.maximum(mu[g] * 0.1, _DAMP)
        idx = idx[~done]
    if evaluations:
        return cur[:, 0].copy(), cur[:, 1].copy(), best, acc_su, acc_sv
    return cur[:, 0].copy(), cur[:, 1].copy()


class CurveInverse(SurfaceInverse):
    """:class:`SurfaceInverse` whose Newton steps evaluate the surface as its Bezier pieces
    (:func:`_damped_newton` stopping at steps of 1e-12 of the domain): the IGES reader's inverter for model-space trim curves, called
    with hundreds to thousands of points a few dozen times per face."""

    def __init__(self, s: BSplineSurface):
        super().__init__(s)
        self.pieces = _Pieces(s)

    def _newton(self, pts, uv):
        domain = (self.s.domain_u, self.s.domain_v)
        u, v, dist, su, sv = _damped_newton(
            self.pieces, domain, pts, uv[:, 0], uv[:, 1], self.size, step_tol=1e-12, stall_tol=1e-10, evaluations=True
        )
        return np.stack([u, v], 1), su, sv, dist

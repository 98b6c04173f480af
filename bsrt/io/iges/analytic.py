"""Analytic and procedural surfaces as exact (rational) B-spline surfaces.

Pure geometry, no file format: planes, surfaces of revolution (cylinder,
cone, sphere, torus and the general one), extrusions and piecewise bicubic
patches (ruled surfaces: ``bsrt.io.iges.ruled``). Each constructor returns
the surface and, per parameter direction, a
:class:`~bsrt.io.param_map.ParamMap` from the
analytic parameter (an angle, a height, a curve's own parameter) to the
B-spline's. The maps are affine except along circles, where the B-spline
parameter equals the angle at every knot (every <= 90 degrees) and follows
the rational quadratic's closed form in between (see ``iges_bspline``).

Revolution: a curve G (3-D, control points Q_j, weights w_j) turned about the
axis through O with unit direction A from angle a0 to a1 (right-handed). With
the unit circle arc's control points (c_i, s_i) and weights v_i, the surface's
control points are O_j + c_i d_j + s_i (A x d_j), d_j = Q_j - O_j, O_j the foot
of Q_j on the axis, and its weights v_i w_j: exact (Piegl and Tiller's
construction).
"""

from __future__ import annotations

import numpy as np

from bsrt.geometry.bspline import BSplineSurface, make_surface
from bsrt.geometry.trim import TrimCurve
from bsrt.io.iges.bspline import clamp, param_map, unit_arc
from bsrt.io.param_map import ParamMap


def _surface(pu: int, pv: int, ku, kv, h: np.ndarray) -> BSplineSurface:
    """make_surface from homogeneous control points (nu, nv, 4)."""
    w = h[..., 3]
    return make_surface((pu, pv), ku, kv, h[..., :3] / w[..., None], None if np.all(w == w.flat[0]) else w)


def plane(origin, eu, ev, box) -> tuple[BSplineSurface, ParamMap, ParamMap]:
    """origin + u eu + v ev over box = (u0, u1, v0, v1), degree (1, 1)."""
    u0, u1, v0, v1 = box
    o, eu, ev = (np.asarray(x, float) for x in (origin, eu, ev))
    pts = np.array([[o + u * eu + v * ev for v in (v0, v1)] for u in (u0, u1)])
    s = make_surface((1, 1), [u0, u0, u1, u1], [v0, v0, v1, v1], pts)
    return s, ParamMap.identity(u0, u1), ParamMap.identity(v0, v1)


def revolve(gen: TrimCurve, origin, axis, a0: float, a1: float, angle_first: bool):
    """The curve ``gen`` (3-D) turned about the axis (origin, unit axis) from angle a0 to a1.

    angle_first: the surface's u is the angle and v the curve's parameter (else
    the other way round). Returns (surface, map_u, map_v); the angle's map takes
    radians, the curve's is ``param_map(gen)``.
    """
    gen = clamp(gen)
    o, a = np.asarray(origin, float), np.asarray(axis, float)
    knots, cs, vw, amap = unit_arc(a0, a1)
    q = gen.points
    feet = o + np.outer((q - o) @ a, a)
    d = q - feet
    ad = np.cross(a, d)
    pts = feet[None] + cs[:, :1, None] * d[None] + cs[:, 1:, None] * ad[None]  # (n_arc, n_gen, 3)
    gw = np.ones(gen.n) if gen.weights is None else gen.weights
    w = vw[:, None] * gw[None, :]
    h = np.concatenate([pts * w[..., None], w[..., None]], axis=-1)
    gmap = param_map(gen)
    if angle_first:
        return _surface(2, gen.degree, knots, gen.knots, h), amap, gmap
    return _surface(gen.degree, 2, gen.knots, knots, h.transpose(1, 0, 2)), gmap, amap


def frame(axis, refdir=None):
    """Right-handed unit (X, Y, Z) with Z along ``axis`` and X along ``refdir`` made
    perpendicular to it (any perpendicular if refdir is None or parallel)."""
    z = np.asarray(axis, float) / np.linalg.norm(axis)
    x = None
    if refdir is not None:
        r = np.asarray(refdir, float)
        x = r - np.dot(r, z) * z
        if np.linalg.norm(x) <= 1e-9 * np.linalg.norm(r):
            x = None
    if x is None:
        helper = np.eye(3)[int(np.argmin(np.abs(z)))]
        x = helper - np.dot(helper, z) * z
    x = x / np.linalg.norm(x)
    return x, np.cross(z, x), z


def _line(p0, p1, t0, t1) -> TrimCurve:
    return TrimCurve(1, np.array([t0, t0, t1, t1], float), np.array([p0, p1], float))


def _arc(centre, e1, e2, r, a0, a1) -> TrimCurve:
    knots, cs, w, pmap = unit_arc(a0, a1)
    pts = np.asarray(centre, float) + r * (cs[:, :1] * e1 + cs[:, 1:] * e2)
    return TrimCurve(2, knots, pts, w, pmap)


def cylinder(centre, x, y, z, radius, box):
    """C + R (cos u X + sin u Y) + v Z over box = (u0, u1, v0, v1)."""
    u0, u1, v0, v1 = box
    c = np.asarray(centre, float)
    gen = _line(c + radius * x + v0 * z, c + radius * x + v1 * z, v0, v1)
    return revolve(gen, c, z, u0, u1, angle_first=True)


def cone(centre, x, y, z, radius, tan_angle, box):
    """C + (R + v tan(a)) (cos u X + sin u Y) + v Z."""
    u0, u1, v0, v1 = box
    c = np.asarray(centre, float)
    gen = _line(c + (radius + v0 * tan_angle) * x + v0 * z, c + (radius + v1 * tan_angle) * x + v1 * z, v0, v1)
    return revolve(gen, c, z, u0, u1, angle_first=True)


def sphere(centre, x, y, z, radius, box):
    """C + R cos v (cos u X + sin u Y) + R sin v Z."""
    u0, u1, v0, v1 = box
    return revolve(_arc(centre, x, z, radius, v0, v1), centre, z, u0, u1, angle_first=True)


def torus(centre, x, y, z, major, minor, box):
    """C + (R + r cos u)(cos v X + sin v Y) + r sin u Z: u the minor angle, v the major one
    (IGES 198 as OpenCASCADE writes and reads it)."""
    u0, u1, v0, v1 = box
    c = np.asarray(centre, float)
    return revolve(_arc(c + major * x, x, z, minor, u0, u1), c, z, v0, v1, angle_first=False)


def extrusion(directrix: TrimCurve, vector, dmap: ParamMap):
    """S(u, v) = C(u) + v D for v in [0, 1]: u is the curve's parameter, mapped by ``dmap``."""
    c = clamp(directrix)
    h = c.homogeneous()
    d = np.asarray(vector, float)
    top = h.copy()
    top[:, :3] += h[:, 3:] * d
    hs = np.stack([h, top], axis=1)
    s = _surface(c.degree, 1, c.knots, [0, 0, 1, 1], hs)
    return s, dmap, ParamMap.identity(0.0, 1.0)


def bicubic(tu, tv, coef) -> BSplineSurface:
    """Piecewise bicubic polynomial patches as one B-spline surface, exactly.

    tu (M + 1,), tv (N + 1,): increasing breakpoints. coef: (M, N, 3, 4, 4),
    coef[i, j, k, a, b] multiplies s^a t^b in coordinate k of patch (i, j), with
    s = u - tu[i], t = v - tv[j]. Shared patch edges (equal up to the file's
    rounding) are averaged.
    """
    m, n = coef.shape[:2]
    # power basis in the local [0, 1] parameters, then to Bezier: P = M^-1 C M^-T
    to_bez = np.array([[1, 0, 0, 0], [1, 1 / 3, 0, 0], [1, 2 / 3, 1 / 3, 0], [1, 1, 1, 1]])
    pts = np.zeros((3 * m + 1, 3 * n + 1, 3))
    count = np.zeros((3 * m + 1, 3 * n + 1, 1))
    for i in range(m):
        hu = tu[i + 1] - tu[i]
        for j in range(n):
            hv = tv[j + 1] - tv[j]
            scale = np.outer(hu ** np.arange(4), hv ** np.arange(4))
            c = coef[i, j] * scale  # (3, 4, 4)
            bez = np.einsum("ia,kab,jb->ijk", to_bez, c, to_bez)
            pts[3 * i : 3 * i + 4, 3 * j : 3 * j + 4] += bez
            count[3 * i : 3 * i + 4, 3 * j : 3 * j + 4] += 1
    ku = np.concatenate([[tu[0]] * 4] + [[x] * 3 for x in tu[1:-1]] + [[tu[-1]] * 4])
    kv = np.concatenate([[tv[0]] * 4] + [[x] * 3 for x in tv[1:-1]] + [[tv[-1]] * 4])
    return make_surface((3, 3), ku, kv, pts / count)

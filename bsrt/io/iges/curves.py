"""IGES curve entities as exact (rational) B-spline curves.

Each curve becomes an :class:`~bsrt.io.iges.bspline.TrimCurve` in 3-D, mapped by
its transformation matrix; a parameter-space curve is the same thing with z
dropped (its matrix acts in the (u, v) plane). The curve's ``pmap`` maps the
entity's own IGES parameter onto the B-spline parameter (needed where a
surface is built from the curve).

* 100 circular arc: ZT X1 Y1 (centre) X2 Y2 (start) X3 Y3 (end), counter-
  clockwise in the plane z = ZT; start = end is a full circle. Rational
  quadratic pieces of at most 90 degrees; parameter = angle (radians).
* 102 composite curve: N and N member pointers, end to end. As trim-loop
  pieces the members stay separate; as one curve they are joined (degrees
  raised to the highest) and the parameter runs through the members' ranges
  one after the other.
* 104 conic arc: A B C D E F ZT X1 Y1 X2 Y2 for A x^2 + B xy + C y^2 + D x +
  E y + F = 0 in the plane z = ZT (any position, not only the standard one;
  the type comes from the coefficients). Ellipses run counterclockwise from
  start to end (start = end: the whole ellipse), hyperbolas and parabolas
  along their branch. Exact rational quadratics; an ellipse's parameter is
  its eccentric angle, a hyperbola's t in (a cosh t, b sinh t).
* 106 copious data, forms 1-3, 11-13 and 63: IP (1: x y pairs with a common
  ZT, 2: x y z, 3: x y z i j k) N and the tuples, as a degree-1 polyline with
  the point index as parameter (form 63 is closed if its ends differ).
* 110 line, form 0: X1 Y1 Z1 X2 Y2 Z2, parameter in [0, 1].
* 112 parametric spline curve: CTYPE H NDIM N T(1..N+1) and per segment the
  12 coefficients AX BX CX DX AY ... DZ of X(s) = AX + BX s + CX s^2 + DX s^3,
  s = t - T(i): cubic Bezier pieces, exactly, on the same parameter.
* 126 rational B-spline curve: K M PROP1-4, K+M+2 knots, K+1 weights, K+1
  points, V0 V1 (and a normal): restricted to [V0, V1] by knot insertion.

Anything else (130 offset curve, ...) raises :class:`Unsupported`.
"""

from __future__ import annotations

import math

import numpy as np

from bsrt.geometry.trim import TrimCurve
from bsrt.io.iges.bspline import affine, arc_curve, from_bezier, join, line_curve, polyline_curve, restrict, reverse

CURVE_TYPES = frozenset({100, 102, 104, 106, 110, 112, 126})
_POLYLINE_FORMS = (1, 2, 3, 11, 12, 13, 63)


class Unsupported(Exception):
    """bsrt does not convert this entity where a curve or surface is needed."""

    def __init__(self, entity, why: str = ""):
        super().__init__(f"entity {entity.type} (DE {entity.de}) {why}".strip())
        self.entity = entity
        self.why = why


def curve(f, entity) -> TrimCurve:
    """The entity as one 3-D curve, mapped by its transformation matrix (memoised)."""
    key = ("curve", entity.de)
    if key not in f.cache:
        if entity.type == 102:
            c = join(pieces(f, entity))
        else:
            c = _read(f, entity)
            m = f.matrix(entity)
            if m is not None:
                c = affine(c, m)
        f.used.add(entity.de)
        f.cache[key] = c
    return f.cache[key]


def pieces(f, entity, chain: tuple = ()) -> list[TrimCurve]:
    """The entity as a list of curves end to end: a composite's members (recursively),
    each mapped by its own matrix and then by the composite's; any other curve alone."""
    if entity.type != 102:
        return [curve(f, entity)]
    if entity.de in chain:
        raise f.fail(entity, "composite curves contain each other in a loop")
    params = f.params(entity)
    n = params.int("the member count N", 1)
    out = []
    for _ in range(n):
        member = f.get(params, params.pointer("a member pointer"), "member pointer")
        if member.type == 116:  # a point: a degenerate member, nothing to draw
            f.used.add(member.de)
            continue
        if member.type not in CURVE_TYPES:
            raise Unsupported(member, "as a curve")
        out += pieces(f, member, chain + (entity.de,))
    m = f.matrix(entity)
    if m is not None:
        out = [affine(c, m) for c in out]
    if not out:
        raise f.fail(entity, "the composite curve has no curve members")
    f.used.add(entity.de)
    return out


def mark_used(f, ref, de: int, what: str, chain: tuple = ()) -> None:
    """Count a curve (and a composite's members, and their matrices) as used without
    converting it: the model-space twin of a parameter-space curve that was used."""
    entity = f.get(ref, de, what)
    if entity.de in f.used or entity.de in chain:
        return
    f.matrix(entity)
    f.used.add(entity.de)
    if entity.type == 102:
        params = f.params(entity)
        for _ in range(params.int("the member count N", 1)):
            mark_used(f, params, params.pointer("a member pointer"), "member pointer", chain + (entity.de,))


def _read(f, entity) -> TrimCurve:
    reader = _READERS.get(entity.type)
    if reader is None:
        raise Unsupported(entity, "as a curve")
    return reader(f, entity, f.params(entity))


def _arc(f, entity, params) -> TrimCurve:
    zt, cx, cy, sx, sy, ex, ey = (params.real(w) for w in ("ZT", "X1", "Y1", "X2", "Y2", "X3", "Y3"))
    r = math.hypot(sx - cx, sy - cy)
    if not r > 0:
        raise params.fail("the arc's start point is its centre (radius 0)")
    a0 = math.atan2(sy - cy, sx - cx)
    if math.hypot(ex - sx, ey - sy) <= 1e-12 * r:
        a1 = a0 + 2 * math.pi
    else:
        a1 = math.atan2(ey - cy, ex - cx)
        while a1 <= a0:
            a1 += 2 * math.pi
    return arc_curve([cx, cy, zt], [1, 0, 0], [0, 1, 0], r, r, a0, a1)


def _conic(f, entity, params) -> TrimCurve:
    a, b, c, d, e, g, zt = (params.real(w) for w in ("A", "B", "C", "D", "E", "F", "ZT"))
    start = np.array([params.real("X1"), params.real("Y1")])
    end = np.array([params.real("X2"), params.real("Y2")])
    q = np.array([[a, b / 2], [b / 2, c]])
    lam, vec = np.linalg.eigh(q)
    scale = np.abs(lam).max()
    if not scale > 0:
        raise params.fail("the conic has no quadratic terms (A = B = C = 0)")
    size = max(1.0, np.abs(start).max(), np.abs(end).max())

    def frame(v1, v2):  # right-handed, so that counterclockwise stays counterclockwise
        return (v1, v2) if v1[0] * v2[1] - v1[1] * v2[0] > 0 else (v1, -v2)

    def three(p):
        return np.array([p[0], p[1], zt])

    if abs(lam[0] * lam[1]) <= 1e-12 * scale * scale:  # parabola
        k = int(np.argmax(np.abs(lam)))
        vy, vx = vec[:, k], vec[:, 1 - k]
        vx, vy = frame(vx, vy)
        lm = lam[k]
        dx, ey = np.dot([d, e], vx), np.dot([d, e], vy)
        if abs(dx) <= 1e-12 * (abs(d) + abs(e) + scale * size):
            raise params.fail("the conic is degenerate (a pair of parallel lines), not a parabola")
        kk, yv = -lm / dx, -ey / (2 * lm)
        vertex = (-(g - ey * ey / (4 * lm)) / dx) * vx + yv * vy
        s0, s1 = np.dot(start, vy) - yv, np.dot(end, vy) - yv
        if s0 == s1:
            raise params.fail("the parabolic arc starts where it ends")
        ctrl = [
            vertex + kk * s0 * s0 * vx + s0 * vy,
            vertex + kk * s0 * s1 * vx + 0.5 * (s0 + s1) * vy,
            vertex + kk * s1 * s1 * vx + s1 * vy,
        ]
        return TrimCurve(2, np.array([0, 0, 0, 1, 1, 1], float), np.array([three(p) for p in ctrl]))
    centre = np.linalg.solve(q, -0.5 * np.array([d, e]))
    g0 = g + 0.5 * (d * centre[0] + e * centre[1])
    if lam[0] * lam[1] > 0:  # ellipse
        if not -g0 / lam[0] > 0:
            raise params.fail("the conic has no real points (an imaginary ellipse)")
        v1, v2 = frame(vec[:, 0], vec[:, 1])
        r1, r2 = math.sqrt(-g0 / lam[0]), math.sqrt(-g0 / lam[1])
        loc = lambda p: (np.dot(p - centre, v1) / r1, np.dot(p - centre, v2) / r2)  # noqa: E731
        t0 = math.atan2(loc(start)[1], loc(start)[0])
        if np.abs(end - start).max() <= 1e-12 * max(r1, r2):
            t1 = t0 + 2 * math.pi
        else:
            t1 = math.atan2(loc(end)[1], loc(end)[0])
            while t1 <= t0:
                t1 += 2 * math.pi
        return arc_curve(three(centre), three(v1) - [0, 0, zt], three(v2) - [0, 0, zt], r1, r2, t0, t1)
    # hyperbola: the transverse axis is the one with -g0 / lambda > 0
    if g0 == 0:
        raise params.fail("the conic is degenerate (a pair of crossing lines), not a hyperbola")
    k = 0 if -g0 / lam[0] > 0 else 1
    v1, v2 = frame(vec[:, k], vec[:, 1 - k])
    r1, r2 = math.sqrt(-g0 / lam[k]), math.sqrt(g0 / lam[1 - k])
    if np.dot(start - centre, v1) < 0:
        v1, v2 = -v1, -v2
    if np.dot(end - centre, v1) <= 0:
        raise params.fail("the hyperbolic arc's start and end lie on different branches")
    s0, s1 = (math.asinh(np.dot(p - centre, v2) / r2) for p in (start, end))
    if s0 == s1:
        raise params.fail("the hyperbolic arc starts where it ends")
    lo, hi = min(s0, s1), max(s0, s1)
    arc = arc_curve(three(centre), three(v1) - [0, 0, zt], three(v2) - [0, 0, zt], r1, r2, lo, hi, hyperbolic=True)
    return arc if s0 < s1 else reverse(arc)


def _copious(f, entity, params) -> TrimCurve:
    if entity.form not in _POLYLINE_FORMS:
        raise Unsupported(entity, f"form {entity.form} (not a point list or polyline)")
    ip = params.int("the interpretation flag IP", 1)
    n = params.int("the number of points N", 1)
    if ip == 1:
        zt = params.real("ZT")
        xy = params.reals(2 * n, "a coordinate").reshape(n, 2)
        pts = np.concatenate([xy, np.full((n, 1), zt)], axis=1)
    elif ip in (2, 3):
        pts = params.reals((3 * ip - 3) * n, "a coordinate").reshape(n, 3 * ip - 3)[:, :3]
    else:
        raise params.fail(f"the interpretation flag IP must be 1, 2 or 3, got {ip}")
    if entity.form == 63 and np.any(pts[0] != pts[-1]):
        pts = np.concatenate([pts, pts[:1]])
    return polyline_curve(pts)


def _line(f, entity, params) -> TrimCurve:
    if entity.form != 0:
        raise Unsupported(entity, f"form {entity.form} (an unbounded line) as a curve")
    p = params.reals(6, "an end point coordinate").reshape(2, 3)
    return line_curve(p[0], p[1])


def _spline(f, entity, params) -> TrimCurve:
    params.int("the spline type CTYPE")
    params.int("the continuity H")
    params.int("the dimension NDIM")
    n = params.int("the number of segments N", 1)
    t = params.reals(n + 1, "a breakpoint T")
    if np.any(np.diff(t) <= 0):
        raise params.fail("the breakpoints T must increase")
    segs = []
    for i in range(n):
        coef = params.reals(12, "a polynomial coefficient").reshape(3, 4)  # rows x, y, z: a b c d
        h = t[i + 1] - t[i]
        a, b, c, d = (coef[:, k] * h**k for k in range(4))
        bez = np.array([a, a + b / 3, a + 2 * b / 3 + c / 3, a + b + c + d])
        segs.append(np.concatenate([bez, np.ones((4, 1))], axis=1))
    return from_bezier(t, np.stack(segs))


def _bspline(f, entity, params) -> TrimCurve:
    k = params.int("the upper index K", 0)
    m = params.int("the degree M", 1)
    for name in ("PROP1", "PROP2", "PROP3", "PROP4"):
        params.int(name)
    if k + 1 < m + 1:
        raise params.fail(f"degree {m} needs at least {m + 1} control points, got {k + 1}")
    knots = params.reals(k + m + 2, "a knot")
    w = params.reals(k + 1, "a weight")
    pts = params.reals(3 * (k + 1), "a control point coordinate").reshape(k + 1, 3)
    v0, v1 = params.real("V0"), params.real("V1")
    if np.any(np.diff(knots) < 0):
        raise params.fail("the knots must not decrease")
    lo, hi = knots[m], knots[k + 1]
    if not lo < hi:
        raise params.fail(f"the knot domain [{lo:g}, {hi:g}] is empty")
    inner = knots[(knots > lo) & (knots < hi)]
    if inner.size > m and np.any(inner[m:] == inner[:-m]):  # sorted: a value more than m times
        raise params.fail(f"an interior knot is repeated more than the degree {m} (the curve is broken there)")
    if np.any(w <= 0):
        raise params.fail(f"every weight must be > 0, found {w.min():g}")
    c = TrimCurve(m, knots, pts, None if np.all(w == w[0]) else w)
    tol = 1e-9 * max(1.0, abs(lo), abs(hi))
    a, b = max(v0, lo), min(v1, hi)
    if not (v0 < v1 and lo - tol <= v0 and v1 <= hi + tol):
        raise params.fail(f"the range V0 V1 = [{v0:g}, {v1:g}] is not inside the knot domain [{lo:g}, {hi:g}]")
    if a - lo > tol or hi - b > tol:
        return restrict(c, a, b)
    return c


_READERS = {100: _arc, 104: _conic, 106: _copious, 110: _line, 112: _spline, 126: _bspline}


def point(f, ref, de: int, what: str, parent_matrix=None) -> np.ndarray:
    """(3,) a point entity 116 (X Y Z), mapped by its matrix and then ``parent_matrix``."""
    entity = f.get(ref, de, what, {116})
    p = np.append(f.params(entity).reals(3, "a coordinate"), 1.0)
    for m in (f.matrix(entity), parent_matrix):
        if m is not None:
            p = m @ p
    f.used.add(entity.de)
    return p[:3]


def direction(f, ref, de: int, what: str, parent_matrix=None) -> np.ndarray:
    """(3,) unit vector of a direction entity 123, mapped by the linear parts of the matrices."""
    entity = f.get(ref, de, what, {123})
    params = f.params(entity)
    v = params.reals(3, "a direction component")
    for m in (f.matrix(entity), parent_matrix):
        if m is not None:
            v = m[:3, :3] @ v
    norm = float(np.linalg.norm(v))
    if not norm > 0:
        raise params.fail("the direction is the zero vector")
    f.used.add(entity.de)
    return v / norm

"""IGES surface entities as exact NURBS, with their parametrisations.

:func:`surface` reads a surface entity into a :class:`SurfaceDef`: how to
build its B-spline surface over a parameter box, the maps from the entity's
own (u, v) (in which trim curves are written) to the B-spline's, and, where
one exists, a closed-form inverse from model space to (u, v).

Parametrisations (u, v) as bsrt reads them (IGES 5.3; X, Y, Z is the
right-handed frame of the axis and the reference direction made
perpendicular to it, or any perpendicular one for the unparametrised form 0):

* 128 B-spline surface: its knot domain, cut to U0..U1 x V0..V1 -- unless
  the trim loops leave that rectangle (but not the knot domain); then the
  surface keeps its whole knot domain, so that the loops stay valid.
* 114 parametric spline surface: CTYPE PTYPE M N TU(1..M+1) TV(1..N+1), then
  per patch (u index outer) 16 X, 16 Y and 16 Z coefficients of
  sum a_ij s^i t^j (s fastest), and 48 arbitrary values after each u row:
  bicubic Bezier patches on the same (u, v), exactly.
* 118 ruled surface (forms 0 and 1): C1 C2 DIRFLG DEVFLG; u in [0, 1] pairs points of equal
  relative arc length (form 0) or parameter (form 1: an arc's angle, a line's [0, 1]), v in
  [0, 1] from C1 to C2; DIRFLG 1 joins C1's start to C2's end: see ``bsrt.io.iges.ruled``.
* 120 surface of revolution: L (a line: the axis, from its start to its end
  point) C (generatrix) SA TA (radians): u is the generatrix's parameter, v the
  angle turned from the generatrix, right-handed about the axis.
* 122 tabulated cylinder: DE of the directrix C, LX LY LZ: S(u, v) = C(t) + v (L - C(t0)),
  t = t0 + u (t1 - t0), u, v in [0, 1]; over a segment a parallelogram, inverted affinely.
* 140 offset surface: NX NY NZ D and the base surface: see ``bsrt.io.iges.offset``.
* 108 plane: A B C D (A x + B y + C z = D) PTR X Y Z SIZE: origin the point of
  the plane nearest the definition-space origin, u and v lengths along X, Y.
* 190 plane surface: L + u X + v Y (L: DELOC, normal: DENRML, X: DEREFD).
* 192 cylinder: L + R (cos u X + sin u Y) + v Z, u an angle in radians.
* 194 cone (SANGLE in degrees): L + (R + v tan SANGLE)(cos u X + sin u Y) + v Z.
* 196 sphere: C + R cos v (cos u X + sin u Y) + R sin v Z, v in [-pi/2, pi/2].
* 198 torus: C + (R + r cos u)(cos v X + sin v Y) + r sin u Z: u the minor
  angle, v the major one, as OpenCASCADE writes and reads IGES (a B-rep
  written by OpenCASCADE renders with the same hits as its STEP twin).

The analytic surfaces (108, 190-198) are unbounded or periodic: their
B-spline covers exactly the box their trim loops use (a sphere's and a
torus's whole range when drawn alone). Angles are read in radians; on
190-198 faces whose loops' angles span more than 2 pi (as OCCT writes
them, in degrees), they are read as degrees (see ``iges_topology``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bsrt.io.iges import analytic, offset, ruled
from bsrt.io.iges.bspline import affine, clamp, param_map, reverse
from bsrt.io.iges.curves import CURVE_TYPES, Unsupported, curve, direction, point
from bsrt.io.invert import RevolutionInverse
from bsrt.io.param_map import ParamMap

SURFACE_TYPES = frozenset({108, 114, 118, 120, 122, 128, 140, 190, 192, 194, 196, 198})
TWO_PI = 2 * math.pi


@dataclass
class SurfaceDef:
    """A surface entity ready to become a B-spline surface.

    place(box): (BSplineSurface in model space, map_u, map_v) covering box =
      (u0, u1, v0, v1) in the entity's own parameters (None: its natural range).
    natural: (u0, u1, v0, v1), None entries where the surface is unbounded.
    angular: which of u, v are angles that a file may write in degrees (190-198).
    period: per parameter, the period of a closed (periodic) direction, 0.0 where
      it is not (2 pi for the angles of 192-198 and of a full 120; a 128's knot
      range where its first and last rows of control points coincide): loops
      may be shifted by whole periods there, and ``place`` accepts any window
      of one period (a 128 is split at the seam and put back together).
    poles: (axis, value) pairs of parameter values where the surface collapses to
      a point or an apex (a cone's apex): a loop that goes once round can close
      along them.
    plane: (origin, eu, ev) when model points map to (u, v) affinely (planes).
    invert: closed-form model points (N, 3) -> (u, v) (N, 2), for analytic surfaces.
    fixed: the B-spline does not depend on the box (its trims are checked against
      ``place(None)``'s domain, or the whole knot domain of a 128).
    closed_inverse: model points (N, 3) -> ``inverse_target``'s (x, y) (N, 2) in closed
      form (a 120 turning a segment or a circular arc: :class:`bsrt.io.invert.RevolutionInverse`), else None
      (:class:`bsrt.io.invert.SurfaceInverse` inverts).
    """

    entity: object
    place: Callable
    natural: tuple
    angular: tuple = (False, False)
    period: tuple = (0.0, 0.0)
    poles: tuple = ()
    plane: tuple | None = None
    invert: Callable | None = None
    fixed: bool = True
    whole: object = None  # a 128's uncut surface
    closed_inverse: Callable | None = None  # closed-form points -> inverse_target's (x, y), where there is one

    @property
    def periodic(self) -> tuple:
        return tuple(p > 0 for p in self.period)

    @property
    def bounded(self) -> bool:
        return all(x is not None for x in self.natural)

    def inverse_target(self):
        """(B-spline surface, "iges" or "nurbs"): what model-space curves are inverted onto,
        and whose parameters the result is in."""
        if self.whole is not None:
            return self.whole, "iges"
        s, mu, mv = self.place(None)
        identity = all(m.affine_on(m.x[0], m.x[-1]) == (1.0, 0.0) for m in (mu, mv))
        return s, "iges" if identity else "nurbs"


def surface(f, entity) -> SurfaceDef:
    """The surface entity (memoised); Unsupported for other entity types."""
    key = ("surface", entity.de)
    if key not in f.cache:
        reader = _READERS.get(entity.type)
        if reader is None:
            raise Unsupported(entity, "as a surface")
        f.cache[key] = reader(f, entity, f.params(entity), f.matrix(entity))
        f.used.add(entity.de)
    return f.cache[key]


def _moved(s, m):
    return s if m is None else s.transformed(m)


def _fixed(entity, s, mu: ParamMap, mv: ParamMap, natural=None) -> SurfaceDef:
    nat = natural if natural is not None else (*mu.x[[0, -1]], *mv.x[[0, -1]])
    return SurfaceDef(entity, lambda box: (s, mu, mv), tuple(float(x) for x in nat))


def _bspline(f, entity, params, m) -> SurfaceDef:
    from bsrt.io import build_surface, cut

    which = f"entity 128 (DE {entity.de})"
    k1, k2 = params.int("K1", 0), params.int("K2", 0)
    m1, m2 = params.int("M1", 0), params.int("M2", 0)
    for name in ("PROP1", "PROP2", "PROP3", "PROP4", "PROP5"):
        params.int(name)
    ku = params.reals(k1 + m1 + 2, "a u knot")
    kv = params.reals(k2 + m2 + 2, "a v knot")
    nu, nv = k1 + 1, k2 + 1
    w = params.reals(nu * nv, "a weight").reshape(nv, nu).T
    pts = params.reals(3 * nu * nv, "a control point coordinate").reshape(nv, nu, 3).transpose(1, 0, 2)
    u0, u1, v0, v1 = (params.real(name) for name in ("U0", "U1", "V0", "V1"))
    if np.any(w <= 0):
        raise f.fail(entity, f"every weight must be > 0, found {w.min():g}")
    whole = build_surface(f.path, entity.line, which, (m1, m2), ku, kv, pts, w)
    if m is not None:
        with np.errstate(all="ignore"):  # huge entries give non-finite points, reported by build_surface
            moved = whole.transformed(m).points
        whole = build_surface(
            f.path,
            entity.line,
            f"{which} after its transformation matrix",
            whole.degree,
            whole.knots_u,
            whole.knots_v,
            moved,
            whole.weights,
        )
    part = cut(f.path, entity.line, which, whole, ((u0, u1), (v0, v1)), ("U0 U1", "V0 V1"))
    natural = (*part.domain_u, *part.domain_v)
    full = (*whole.domain_u, *whole.domain_v)

    period = _closed(whole)
    size = math.hypot(full[1] - full[0], full[3] - full[2])
    tol = 1e-7 * size

    def place(box):
        s = part
        if box is not None:
            if (
                box[0] < natural[0] - tol
                or box[1] > natural[1] + tol
                or box[2] < natural[2] - tol
                or box[3] > natural[3] + tol
            ):
                s = whole
                for k in range(2):  # a loop across the seam of a closed direction: the seam moved
                    lo, hi = full[2 * k], full[2 * k + 1]
                    if (
                        period[k]
                        and (box[2 * k] < lo - tol or box[2 * k + 1] > hi + tol)
                        and box[2 * k + 1] - box[2 * k] <= period[k] + tol
                    ):
                        s = rotated(s, k, box[2 * k])
        return s, ParamMap.identity(*s.domain_u), ParamMap.identity(*s.domain_v)

    return SurfaceDef(entity, place, natural, whole=whole, period=period)


def _closed(s) -> tuple:
    """(period_u, period_v) of a clamped B-spline surface: the knot range of a direction
    whose first and last rows of control points coincide (weights in a constant ratio),
    else 0.0."""
    out = []
    h = s.homogeneous()
    size = float(np.linalg.norm(np.ptp(s.points.reshape(-1, 3), axis=0)))
    for k, (knots, p) in enumerate(((s.knots_u, s.degree[0]), (s.knots_v, s.degree[1]))):
        rows = np.moveaxis(h, k, 0)
        first, last = rows[0], rows[-1]
        clamped = np.all(knots[: p + 1] == knots[0]) and np.all(knots[-(p + 1) :] == knots[-1])
        ratio = last[:, 3] / first[:, 3]
        same = np.abs(last[:, :3] / last[:, 3:] - first[:, :3] / first[:, 3:]).max() <= 1e-12 * size
        out.append(float(knots[-1] - knots[0]) if clamped and same and np.ptp(ratio) <= 1e-12 * ratio.max() else 0.0)
    return tuple(out)


def rotated(s, axis: int, a: float):
    """The closed B-spline surface s (``_closed``) over the window [a, a + period] along
    ``axis``: split at a (knot inserted up to the degree) and the part before a moved,
    shifted by the period, after the rest. The same points at parameters equal modulo the
    period; C0 at the old seam."""
    from bsrt.geometry.bspline import insert_knot, make_surface

    knots = (s.knots_u, s.knots_v)[axis]
    p = s.degree[axis]
    lo, hi = float(knots[0]), float(knots[-1])
    period = hi - lo
    a = lo + (a - lo) % period
    if a - lo <= 1e-14 * period or hi - a <= 1e-14 * period:
        return s
    h = np.moveaxis(s.homogeneous(), axis, 0)
    k = knots.copy()
    while np.count_nonzero(k == a) < p:
        k, h = insert_knot(k, h, p, a)
    n = h.shape[0]
    r = int(np.searchsorted(k, a, side="left"))  # a occupies k[r : r + p]
    left, right = h[1:r], h[r - 1 :]
    left = left * (right[-1, :, 3] / h[0, :, 3])[None, :, None]  # the same weights at the old seam
    ctrl = np.concatenate([right, left])
    new = np.concatenate([[a] * (p + 1), k[r + p : n], [hi] * p, k[p + 1 : r] + period, [a + period] * (p + 1)])
    ctrl = np.moveaxis(ctrl, 0, axis)
    w = ctrl[..., 3]
    knots_u, knots_v = (new, s.knots_v) if axis == 0 else (s.knots_u, new)
    return make_surface(s.degree, knots_u, knots_v, ctrl[..., :3] / w[..., None], None if not s.is_rational else w)


def _spline_surface(f, entity, params, m) -> SurfaceDef:
    params.int("the boundary type CTYPE")
    params.int("the patch type PTYPE")
    mu, nv = params.int("the number of u segments M", 1), params.int("the number of v segments N", 1)
    tu, tv = params.reals(mu + 1, "a u breakpoint"), params.reals(nv + 1, "a v breakpoint")
    if np.any(np.diff(tu) <= 0) or np.any(np.diff(tv) <= 0):
        raise params.fail("the breakpoints TU and TV must increase")
    coef = np.zeros((mu, nv, 3, 4, 4))
    for i in range(mu):
        for j in range(nv):
            # 16 coefficients per coordinate, the power of s fastest: index a + 4 b for s^a t^b
            coef[i, j] = params.reals(48, "a patch coefficient").reshape(3, 4, 4).transpose(0, 2, 1)
        if i < mu - 1:
            params.skip(48, "the arbitrary values after a row of patches")
    s = _moved(analytic.bicubic(tu, tv, coef), m)
    return _fixed(entity, s, ParamMap.identity(tu[0], tu[-1]), ParamMap.identity(tv[0], tv[-1]))


def _child_curve(f, params, what, m):
    c = curve(f, f.get(params, params.pointer(what), what, CURVE_TYPES))
    return c if m is None else affine(c, m)


def _ruled(f, entity, params, m) -> SurfaceDef:
    c1 = _child_curve(f, params, "first curve pointer", m)
    c2 = _child_curve(f, params, "second curve pointer", m)
    if params.int("the direction flag DIRFLG") == 1:
        c2 = reverse(c2)
    if entity.form not in (0, 1):
        raise Unsupported(entity, f"form {entity.form} (forms 0 and 1 are ruled surfaces)")
    try:
        s, mu, mv = ruled.ruled(c1, c2, entity.form)
    except ruled.RuledError as e:
        raise Unsupported(entity, str(e)) from None
    return _fixed(entity, s, mu, mv)


def _revolution(f, entity, params, m) -> SurfaceDef:
    axis = f.get(params, params.pointer("axis pointer"), "axis pointer", {110})
    ap = f.params(axis).reals(6, "an axis point coordinate").reshape(2, 3)
    am = f.matrix(axis)
    ends = [x for x in ap]
    for mat in (am, m):
        if mat is not None:
            ends = [mat[:3, :3] @ x + mat[:3, 3] for x in ends]
    f.used.add(axis.de)
    gen = _child_curve(f, params, "generatrix pointer", m)
    sa, ta = params.real("the start angle SA"), params.real("the terminate angle TA")
    if not sa < ta or ta - sa > TWO_PI * (1 + 1e-12):
        raise params.fail(f"the angles SA, TA = {sa:g}, {ta:g} must satisfy SA < TA <= SA + 2 pi")
    direction_ = ends[1] - ends[0]
    if not np.linalg.norm(direction_) > 0:
        raise f.fail(axis, "the axis line has no length")
    axis_dir = direction_ / np.linalg.norm(direction_)
    s, mu, mv = analytic.revolve(gen, ends[0], axis_dir, sa, ta, angle_first=False)
    g = clamp(gen)
    closed = RevolutionInverse.of(
        g.degree, g.knots, g.points, g.weights, ends[0], axis_dir, (sa, ta), mv, mv.inverse, g.pmap
    )
    sd = _fixed(entity, s, mu, mv)
    sd.closed_inverse = closed
    if ta - sa < TWO_PI * (1 - 1e-12):
        return sd
    # a full turn: periodic in v; any window of one turn is the same surface, turned
    size = float(np.linalg.norm(np.ptp(s.points.reshape(-1, 3), axis=0)))
    g0, g1 = gen.ends()
    poles = tuple(
        (0, float(x))
        for x, q in zip(mu.x[[0, -1]], (g0, g1))
        if np.linalg.norm(np.cross(q - ends[0], axis_dir)) <= 1e-12 * size
    )

    def place(box):
        if box is None or box[3] - box[2] > TWO_PI * (1 + 1e-12):
            return s, mu, mv
        return analytic.revolve(gen, ends[0], axis_dir, box[2], box[3], angle_first=False)

    return SurfaceDef(entity, place, sd.natural, period=(0.0, TWO_PI), poles=poles, fixed=False, closed_inverse=closed)


def _tabulated(f, entity, params, m) -> SurfaceDef:
    c = _child_curve(f, params, "directrix pointer", m)
    end = params.reals(3, "a coordinate of L")
    if m is not None:
        end = m[:3, :3] @ end + m[:3, 3]
    pmap = param_map(c)
    t0, t1 = pmap.x[0], pmap.x[-1]
    start = c.ends()[0]
    s, mu, mv = analytic.extrusion(c, end - start, pmap.scaled_x(t1 - t0, t0))
    sd = _fixed(entity, s, mu, mv, natural=(0.0, 1.0, 0.0, 1.0))
    flat, y = clamp(c), end - start
    x = flat.points[-1] - start  # over a segment on an affine parameter: S = start + u x + v y
    segment = flat.n == 2 and flat.weights is None and mu.affine_on(0.0, 1.0) is not None
    if segment and np.linalg.norm(np.cross(x, y)) > 1e-9 * np.linalg.norm(x) * np.linalg.norm(y):
        sd.plane, sd.invert = (start, x, y), _affine_inverse(start, x, y)
    return sd


def _similarity(f, entity, m) -> float:
    """The scale factor of the matrix (1 if none); Unsupported unless it is a similarity."""
    if m is None:
        return 1.0
    r = m[:3, :3]
    k = abs(np.linalg.det(r)) ** (1 / 3)
    if not k > 0 or np.abs(r.T @ r - k * k * np.eye(3)).max() > 1e-9 * k * k:
        raise Unsupported(entity, "with a transformation matrix that is not a rotation, reflection or uniform scale")
    return k


def _affine_inverse(origin, x, y) -> Callable:
    """Points (N, 3) -> (u, v) (N, 2) of their projections origin + u x + v y onto the plane."""
    g = np.linalg.inv(np.array([[x @ x, x @ y], [x @ y, y @ y]]))

    def invert(pts):
        d = pts - origin
        return (g @ np.stack([d @ x, d @ y])).T

    return invert


def _planar(entity, origin, x, y) -> SurfaceDef:
    return SurfaceDef(
        entity,
        lambda box: analytic.plane(origin, x, y, box),
        (None, None, None, None),
        plane=(origin, x, y),
        invert=_affine_inverse(origin, x, y),
        fixed=False,
    )


def _plane(f, entity, params, m) -> SurfaceDef:
    n = params.reals(4, "a plane coefficient")
    normal, d = n[:3], n[3]
    length = float(np.linalg.norm(normal))
    if not length > 0:
        raise params.fail("the plane's normal (A, B, C) is the zero vector")
    x, y, z = analytic.frame(normal)
    origin = d / length * z
    if m is not None:
        origin, x, y = m[:3, :3] @ origin + m[:3, 3], m[:3, :3] @ x, m[:3, :3] @ y
    return _planar(entity, origin, x, y)


def _plane_surface(f, entity, params, m) -> SurfaceDef:
    loc = point(f, params, params.pointer("location pointer DELOC"), "location pointer DELOC", m)
    normal = direction(f, params, params.pointer("normal pointer DENRML"), "normal pointer DENRML", m)
    ref = None
    if entity.form == 1:
        ref = direction(f, params, params.pointer("reference direction DEREFD"), "reference direction DEREFD", m)
    x, y, _ = analytic.frame(normal, ref)
    k = _similarity(f, entity, m)
    return _planar(entity, loc, k * x, k * y)


def _angle(a, b, scale):
    """atan2(b, a), NaN on the axis (a sphere's poles, a cone's apex: any angle will do)."""
    out = np.arctan2(b, a)
    out[np.hypot(a, b) <= 1e-12 * (np.abs(scale) + 1e-300)] = np.nan
    return out


def _axis_surface(f, entity, params, m, kind: str) -> SurfaceDef:
    """192, 194, 196, 198: a frame and radii. With a uniformly scaling matrix (factor k)
    the B-spline is built in model units and the inverse works in definition units."""
    k = _similarity(f, entity, m)
    loc = point(f, params, params.pointer("location pointer DELOC"), "location pointer DELOC", m)
    ref = None
    if kind == "sphere":
        radius = params.real("the radius")
        axis, ref = np.array([0.0, 0, 1]), np.array([1.0, 0, 0])
        if m is not None:
            axis, ref = m[:3, :3] @ axis, m[:3, :3] @ ref
        if entity.form == 1:
            axis = direction(f, params, params.pointer("axis pointer DEAXIS"), "axis pointer DEAXIS", m)
    else:
        axis = direction(f, params, params.pointer("axis pointer DEAXIS"), "axis pointer DEAXIS", m)
        radius = params.real("the major radius" if kind == "torus" else "the radius")
        if kind == "cone":
            angle = params.real("the semi-angle SANGLE (degrees)")
            if not 0 < angle < 90:
                raise params.fail(f"the cone's semi-angle must be between 0 and 90 degrees, got {angle:g}")
            tan = math.tan(math.radians(angle))
        if kind == "torus":
            minor = params.real("the minor radius")
            if not minor > 0:
                raise params.fail(f"the minor radius must be > 0, got {minor:g}")
    if entity.form == 1:
        ref = direction(f, params, params.pointer("reference direction DEREFD"), "reference direction DEREFD", m)
    if not (radius > 0 or (kind == "cone" and radius >= 0)):
        raise params.fail(f"the radius must be > 0, got {radius:g}")
    x, y, z = analytic.frame(axis, ref)
    if kind == "cylinder":
        natural = (0.0, TWO_PI, None, None)
        build = lambda box: analytic.cylinder(loc, x, y, k * z, k * radius, box)  # noqa: E731
        inv = lambda a, b, c: np.stack([np.arctan2(b, a), c], 1)  # noqa: E731
    elif kind == "cone":
        natural = (0.0, TWO_PI, None, None)
        build = lambda box: analytic.cone(loc, x, y, k * z, k * radius, k * tan, box)  # noqa: E731
        inv = lambda a, b, c: np.stack([_angle(a, b, radius + abs(c) * tan), c], 1)  # noqa: E731
    elif kind == "sphere":
        natural = (0.0, TWO_PI, -math.pi / 2, math.pi / 2)
        build = lambda box: analytic.sphere(loc, x, y, z, k * radius, box)  # noqa: E731
        inv = lambda a, b, c: np.stack([_angle(a, b, radius), np.arctan2(c, np.hypot(a, b))], 1)  # noqa: E731
    else:
        natural = (0.0, TWO_PI, 0.0, TWO_PI)
        build = lambda box: analytic.torus(loc, x, y, z, k * radius, k * minor, box)  # noqa: E731
        inv = lambda a, b, c: np.stack([np.arctan2(c, np.hypot(a, b) - radius), np.arctan2(b, a)], 1)  # noqa: E731

    def invert(pts):
        d = (np.asarray(pts, float) - loc) / k
        return inv(d @ x, d @ y, d @ z)

    angular = (True, kind in ("sphere", "torus"))
    poles = ((1, -radius / tan),) if kind == "cone" else ()
    return SurfaceDef(
        entity,
        lambda box: build(box if box is not None else natural),
        natural,
        angular=angular,
        period=(TWO_PI, TWO_PI if kind == "torus" else 0.0),
        poles=poles,
        invert=invert,
        fixed=False,
    )


def _offset(f, entity, params, m) -> SurfaceDef:
    params.reals(3, "an offset indicator component")
    d = params.real("the offset distance D")
    base = f.get(params, params.pointer("the surface pointer"), "surface pointer")
    if base.type not in SURFACE_TYPES:
        raise Unsupported(base, "as a surface")
    try:
        return offset.offset_def(surface(f, base), entity, d, m)
    except offset.OffsetError as e:
        raise Unsupported(entity, str(e)) from None


_READERS = {
    108: _plane,
    114: _spline_surface,
    118: _ruled,
    120: _revolution,
    122: _tabulated,
    128: _bspline,
    140: _offset,
    190: _plane_surface,
    192: lambda f, e, p, m: _axis_surface(f, e, p, m, "cylinder"),
    194: lambda f, e, p, m: _axis_surface(f, e, p, m, "cone"),
    196: lambda f, e, p, m: _axis_surface(f, e, p, m, "sphere"),
    198: lambda f, e, p, m: _axis_surface(f, e, p, m, "torus"),
}

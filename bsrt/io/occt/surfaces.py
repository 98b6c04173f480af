"""A face's surface as an exact, non-periodic B-spline, and the map of its parameters.

``convert_surface(original, bounds, size)`` gives the B-spline over the face's
(u, v) bounds and the :class:`ParamMap` from the original surface's (u, v) to
the B-spline's (x, y).

The conversion. ``GeomConvert::SurfaceToBSplineSurface`` turns planes,
cylinders, cones, spheres, tori, surfaces of revolution and extrusion and
B-spline / Bezier surfaces into exact (rational) B-splines. Circles become
rational quadratic arcs (``Convert_TgtThetaOver2``), lines and B-spline curves
keep their parameter. For some surfaces (cylinders, periodic B-splines) it
returns the whole period however the window is cut. Offsets of free-form
surfaces are approximated here by ``GeomConvert_ApproxSurface`` to
``OFFSET_TOLERANCE`` of the model's size (checked on a grid; the bound is the
measured deviation, reported per model).

The map is separable, x = f(u) and y = g(v), one :class:`~bsrt.io.param_map.ParamMap` per
direction, in closed form:

* ``identity``: x = u + shift (planes' and B-splines' directions, lines);
* ``tan`` (an arc): the B-spline's parameter equals the angle at its knots
  (b_i, b_i+1) and, in between, follows the rational quadratic arc:
  x = b_i + h (1 + tan((u + shift - m) / 2) / tan(h / 4)) / 2 with
  h = b_i+1 - b_i and m the span's middle (measured: 1e-15 of the radius);
* ``table``: anything else (parabolas, hyperbolas, approximations): f
  tabulated per span at Chebyshev points by inverting the B-spline, and
  interpolated (barycentric), to rounding level.

``shift`` is a whole number of periods (OpenCASCADE may convert a torus cut
at -1 rad over [-1 + 2 pi, ...]). Which kind holds is known for planes,
B-splines, cylinders, cones, spheres and tori (from how OpenCASCADE converts
them) and decided per direction for other surfaces by testing points inside
every span; the whole map is checked on a grid against the original surface
(``FaceMap.deviation``; a face of a known kind that fails it has its kinds
tested). The checks evaluate an elementary surface in closed form (NumPy).

The seam. A face of a periodic direction may straddle the B-spline's own
seam (a cylinder face from -60 to +60 degrees, converted over [0, 2 pi]), or
go all the way round with its seam anywhere. Where the B-spline is periodic
in a direction, it is rotated (cut at f(umin) by knot insertion and its two
pieces joined the other way round) so that its domain starts at the face's
own lower bound; then (any direction) it is restricted to [f(umin), f(umax)],
so every pcurve of the face maps inside the domain and no patch lies
outside the face's bounds.
"""

from __future__ import annotations

import numpy as np

from bsrt.errors import InputError
from bsrt.geometry.bspline import BSplineSurface, grid_points, insert_knot, make_surface
from bsrt.io.invert import invert
from bsrt.io.param_map import TABLE_NODES, FaceMap, ParamMap, chebyshev_lobatto

EXACT_TOLERANCE = 1e-9  # the conversion counts as exact below this, as a fraction of the model's size
OFFSET_TOLERANCE = 1e-8  # approximated offsets: the requested tolerance, as a fraction of the model's size


class FaceError(Exception):
    """A face that cannot become a surface at all (the reason is the message)."""


# ---------------------------------------------------------------------------
# One direction's map


def _points(original, u, v) -> np.ndarray:
    """(N, 3) points of the OpenCASCADE surface at (u[i], v[i])."""
    value = original.Value
    coords = [value(a, b).Coord() for a, b in zip(np.asarray(u, float).tolist(), np.asarray(v, float).tolist())]
    return np.array(coords, dtype=np.float64).reshape(-1, 3)


def _checker(original):
    """(u (N,), v (N,)) -> (N, 3) points of the OpenCASCADE surface, for the checks (:func:`_kinds`,
    :func:`_deviation`), which compare them with the B-spline's to a tolerance: a plane, cylinder,
    cone, sphere or torus in closed form (NumPy, all points at once: the same formulas as OpenCASCADE's
    ``ElSLib``, equal to its ``Value`` to rounding), any other surface point by point (:func:`_points`)."""
    from OCP.Geom import (
        Geom_ConicalSurface,
        Geom_CylindricalSurface,
        Geom_Plane,
        Geom_RectangularTrimmedSurface,
        Geom_SphericalSurface,
        Geom_ToroidalSurface,
    )

    while isinstance(original, Geom_RectangularTrimmedSurface):  # (the same parameters: its basis's points)
        original = original.BasisSurface()
    kind = type(original)
    if kind not in (
        Geom_Plane,
        Geom_CylindricalSurface,
        Geom_ConicalSurface,
        Geom_SphericalSurface,
        Geom_ToroidalSurface,
    ):
        return lambda u, v: _points(original, u, v)
    frame = original.Position()
    o, x, y, z = (
        np.array(a.Coord()) for a in (frame.Location(), frame.XDirection(), frame.YDirection(), frame.Direction())
    )

    def at(u, radius, height):
        """o + radius (cos u x + sin u y) + height z, radius and height (N,) (a plane: u x + v y)."""
        u = np.asarray(u, dtype=np.float64)[:, None]
        return o + radius[:, None] * (np.cos(u) * x + np.sin(u) * y) + height[:, None] * z

    if kind is Geom_Plane:

        def plane(u, v):
            return o + np.asarray(u, float)[:, None] * x + np.asarray(v, float)[:, None] * y

        plane.affine = True  # (see _deviation)
        return plane
    if kind is Geom_CylindricalSurface:
        r = original.Radius()
        return lambda u, v: at(u, np.full(len(u), r), np.asarray(v, float))
    if kind is Geom_ConicalSurface:
        r, sin, cos = original.RefRadius(), np.sin(original.SemiAngle()), np.cos(original.SemiAngle())
        return lambda u, v: at(u, r + np.asarray(v, float) * sin, np.asarray(v, float) * cos)
    if kind is Geom_SphericalSurface:
        r = original.Radius()
        return lambda u, v: at(u, r * np.cos(v), r * np.sin(v))
    big, small = original.MajorRadius(), original.MinorRadius()
    return lambda u, v: at(u, big + small * np.cos(v), small * np.sin(v))


def _breaks(knots: np.ndarray, degree: int, n: int) -> np.ndarray:
    k = knots[degree : n + 1]  # sorted: the distinct values are where it steps
    return k[np.concatenate([[True], k[1:] != k[:-1]])]


def _kinds(at, whole: BSplineSurface, all_breaks, size: float, arc_first: tuple[bool, bool]) -> list[str]:
    """Each direction's kind: "identity" or "tan" (an arc) if that model of x = f(t) holds inside every
    span (t = x at the knots), else "table".

    A direction is tested on the iso-lines of the other direction's knots
    (where its own parameter is unchanged), all of them: one may be
    degenerate (a pole), where any model fits. at: the original surface's
    :func:`_checker`; all_breaks: each direction's distinct knots; arc_first:
    per direction, test "tan" before "identity" (a periodic direction's likelier
    kind). One evaluation of the B-spline serves both directions: the grid of
    (samples in the u spans, the u knots) x (samples in the v spans, the v knots).
    """
    s = np.array([0.23, 0.71])
    samples = [(b[:-1, None] + (b[1:] - b[:-1])[:, None] * s).ravel() for b in all_breaks]
    nu, nv = samples[0].size, samples[1].size
    grid = grid_points(whole, np.concatenate([samples[0], all_breaks[0]]), np.concatenate([samples[1], all_breaks[1]]))
    tol = EXACT_TOLERANCE * size
    kinds = []
    for axis in (0, 1):
        breaks, others, x = all_breaks[axis], all_breaks[1 - axis], samples[axis]

        def arc(breaks=breaks) -> np.ndarray:
            h = np.repeat(breaks[1:] - breaks[:-1], s.size)
            m = np.repeat(0.5 * (breaks[:-1] + breaks[1:]), s.size)
            ss = np.tile(s, breaks.size - 1)
            return m + 2.0 * np.arctan((2.0 * ss - 1.0) * np.tan(0.25 * h))

        candidates = {"identity": lambda x=x: x, "tan": arc}  # (each computed only if tested)
        if arc_first[axis]:  # (the same tests, the likelier first)
            candidates = {"tan": candidates["tan"], "identity": candidates["identity"]}
        y = np.repeat(others, x.size)
        # the points (x[j], others[i]) in that order (index i * x.size + j)
        got = (grid[:nu, nv:].transpose(1, 0, 2) if axis == 0 else grid[nu:, :nv]).reshape(-1, 3)
        kind = "table"
        for name, t in candidates.items():
            t_all = np.tile(t(), others.size)
            want = at(t_all, y) if axis == 0 else at(y, t_all)
            if np.max(np.linalg.norm(want - got, axis=1)) <= tol:
                kind = name
                break
        kinds.append(kind)
    return kinds


def _table(original, whole: BSplineSurface, axis: int, breaks: np.ndarray, other: float, size: float):
    """The (t, x) Chebyshev tables of a map with no closed form: t at the breaks by OpenCASCADE's
    projection, x at Chebyshev points of t by inverting the B-spline."""
    from OCP.gp import gp_Pnt
    from OCP.ShapeAnalysis import ShapeAnalysis_Surface

    pts = grid_points(whole, breaks, [other])[:, 0] if axis == 0 else grid_points(whole, [other], breaks)[0]
    analysis = ShapeAnalysis_Surface(original)
    t_breaks = np.empty(breaks.size)
    for k, p in enumerate(pts):
        uv = analysis.ValueOfUV(gp_Pnt(*map(float, p)), EXACT_TOLERANCE * size)
        t_breaks[k] = uv.X() if axis == 0 else uv.Y()
    t_breaks = np.maximum.accumulate(t_breaks)  # rounding at the ends of a periodic range
    t_nodes = chebyshev_lobatto(t_breaks[:-1], t_breaks[1:], TABLE_NODES)  # (K - 1, N)
    x_start = chebyshev_lobatto(breaks[:-1], breaks[1:], TABLE_NODES)
    flat_t = t_nodes.ravel()
    other_t = np.full_like(flat_t, other)
    targets = _points(original, flat_t, other_t) if axis == 0 else _points(original, other_t, flat_t)
    start = (
        (x_start.ravel(), np.full_like(flat_t, other)) if axis == 0 else (np.full_like(flat_t, other), x_start.ravel())
    )
    xs, ys = invert(whole, targets, *start, size)
    x_nodes = (xs if axis == 0 else ys).reshape(t_nodes.shape)
    x_nodes[:, 0], x_nodes[:, -1] = breaks[:-1], breaks[1:]
    return t_nodes, x_nodes


# ---------------------------------------------------------------------------
# Conversion


def convert_surface(original, bounds, size: float) -> tuple[BSplineSurface, FaceMap]:
    """The surface over the face's ``bounds`` as a non-periodic B-spline (local coordinates) and its FaceMap.

    bounds: (umin, umax, vmin, vmax), the face's parameter bounds (at most
    one period long in a periodic direction). size: the model's size in
    local units (the scale of the tolerances). Raises FaceError.
    """
    known = _known_kinds(original)
    bs, approx_error = _to_bspline(original, bounds, size)
    try:
        return _converted(original, bounds, size, bs, approx_error, known)
    except FaceError:
        if approx_error is not None or known is None:
            raise
    # (not expected: OpenCASCADE's conversion of these surfaces follows the known kinds) test the maps after all
    bs, approx_error = _to_bspline(original, bounds, size)
    return _converted(original, bounds, size, bs, approx_error, None)


def _known_kinds(original) -> tuple[str, str] | None:
    """The two directions' map kinds OpenCASCADE's conversion gives a plane, a B-spline or Bezier surface
    (both "identity": it keeps their parameters), a cylinder or a cone (its circles "tan",
    ``Convert_TgtThetaOver2``; its lines "identity") or a sphere or torus (both circles: "tan"),
    trimmed or not; None for other surfaces (their kinds are tested). The deviation still checks
    them: a face that fails it has its kinds tested after all."""
    from OCP.Geom import (
        Geom_BezierSurface,
        Geom_BSplineSurface,
        Geom_ConicalSurface,
        Geom_CylindricalSurface,
        Geom_Plane,
        Geom_RectangularTrimmedSurface,
        Geom_SphericalSurface,
        Geom_ToroidalSurface,
    )

    surface = original
    while isinstance(surface, Geom_RectangularTrimmedSurface):
        surface = surface.BasisSurface()
    if isinstance(surface, (Geom_Plane, Geom_BSplineSurface, Geom_BezierSurface)):
        return ("identity", "identity")
    if isinstance(surface, (Geom_CylindricalSurface, Geom_ConicalSurface)):
        return ("tan", "identity")
    if isinstance(surface, (Geom_SphericalSurface, Geom_ToroidalSurface)):
        return ("tan", "tan")
    return None


def _converted(original, bounds, size: float, bs, approx_error, known: tuple[str, str] | None):
    """convert_surface's work on OpenCASCADE's B-spline ``bs``; known: the two maps' kinds
    (:func:`_known_kinds`), or None: each direction's kind is tested."""
    umin, umax, vmin, vmax = bounds
    approximated = approx_error is not None
    periodic = (bool(bs.IsUPeriodic()), bool(bs.IsVPeriodic()))
    whole = _extract(bs)
    at = _checker(original)
    periods = (
        original.UPeriod() if original.IsUPeriodic() else 0.0,
        original.VPeriod() if original.IsVPeriodic() else 0.0,
    )
    maps = []
    doms = (whole.domain_u, whole.domain_v)
    all_breaks = (
        _breaks(whole.knots_u, whole.degree[0], whole.shape[0]),
        _breaks(whole.knots_v, whole.degree[1], whole.shape[1]),
    )
    if approximated:
        kinds = ("identity", "identity")
    else:
        kinds = known or _kinds(at, whole, all_breaks, size, (periods[0] > 0, periods[1] > 0))
    for axis, kind in enumerate(kinds):
        breaks, other_breaks = all_breaks[axis], all_breaks[1 - axis]
        other = float(other_breaks[other_breaks.size // 2])  # the tables' knot line: a middle one (poles are at ends)
        table = _table(original, whole, axis, breaks, other, size) if kind == "table" else None
        fmap = ParamMap.on_knots(kind, breaks, (doms[axis][1] - doms[axis][0]) if periodic[axis] else 0.0, table)
        lo, hi = (umin, umax) if axis == 0 else (vmin, vmax)
        fmap = fmap.with_shift(_shift(fmap, lo, hi, doms[axis], periods[axis]))
        maps.append(fmap)
    fu, fv = maps
    local = whole
    for axis, fmap in enumerate(maps):
        lo, hi = (umin, umax) if axis == 0 else (vmin, vmax)
        a, b = fmap(np.array([lo, hi])).tolist()
        if fmap.period > 0:
            local = _rotated(local, axis, a)
        local = _restricted(local, axis, a, b)
    pmap = FaceMap(fu, fv, (umin, umax, vmin, vmax), *periods, approximated=approximated)
    pmap.deviation = max(_deviation(at, local, pmap), approx_error or 0.0)
    if pmap.deviation > EXACT_TOLERANCE * size and not approximated:
        raise FaceError(
            f"the conversion of a {type(original).__name__} does not match it "
            f"({pmap.deviation / size:.2g} of the model's size off)"
        )
    return local, pmap


def _to_bspline(original, bounds, size: float):
    """(Geom_BSplineSurface, error): OpenCASCADE's conversion over the bounds (a whole period where the
    face goes all the way round), error None; for an offset of a free-form surface, its approximation
    and the approximation's largest error as OpenCASCADE measured it (local units)."""
    from OCP.Geom import Geom_OffsetSurface, Geom_RectangularTrimmedSurface
    from OCP.GeomConvert import GeomConvert

    umin, umax, vmin, vmax = bounds
    surface = original
    while isinstance(surface, Geom_RectangularTrimmedSurface):  # its bounds are in ``bounds`` already
        surface = surface.BasisSurface()
    if isinstance(surface, Geom_OffsetSurface):
        equivalent = surface.Surface()  # a plane's, cylinder's, ... offset is another such surface
        if equivalent is None or isinstance(equivalent, Geom_OffsetSurface):
            return _approximated(surface, bounds, size)
        surface = equivalent
    # A whole period is converted from the surface's own start: over any other full period OpenCASCADE
    # converts the natural one and cuts it in the B-spline's parameter, which is not the angle.
    window = []
    su0, _, sv0, _ = surface.Bounds()
    for lo, hi, start, periodic, period in (
        (umin, umax, su0, surface.IsUPeriodic(), surface.UPeriod),
        (vmin, vmax, sv0, surface.IsVPeriodic(), surface.VPeriod),
    ):
        full = periodic and hi - lo >= period() * (1 - 1e-12)
        window += [start, start + period()] if full else [lo, hi]
    try:
        return GeomConvert.SurfaceToBSplineSurface_s(Geom_RectangularTrimmedSurface(surface, *window)), None
    except Exception as e:  # noqa: BLE001 - OCP raises Standard_Failure subclasses
        raise FaceError(f"OpenCASCADE cannot convert a {type(surface).__name__}: {e}") from None


def _approximated(surface, bounds, size: float):
    """(B-spline, its largest error): a free-form offset surface approximated over the bounds (in the same
    parameters) to OFFSET_TOLERANCE of the model's size."""
    from OCP.Geom import Geom_RectangularTrimmedSurface
    from OCP.GeomAbs import GeomAbs_C2
    from OCP.GeomConvert import GeomConvert_ApproxSurface

    trimmed = Geom_RectangularTrimmedSurface(surface, *bounds)
    try:
        approx = GeomConvert_ApproxSurface(trimmed, OFFSET_TOLERANCE * size, GeomAbs_C2, GeomAbs_C2, 9, 9, 2000, 0)
    except Exception as e:  # noqa: BLE001
        raise FaceError(f"OpenCASCADE cannot approximate an offset surface: {e}") from None
    if not approx.HasResult():
        raise FaceError("OpenCASCADE cannot approximate an offset surface")
    return approx.Surface(), float(approx.MaxError())


def _shift(fmap: ParamMap, lo: float, hi: float, domain, period: float) -> float:
    """A whole number of periods to add to t so that f([lo, hi]) falls in the B-spline's domain.

    A periodic B-spline (fmap.period > 0) is rotated to start at f(lo), which
    must then lie in [x0, x0 + period): the shift brings it there. Otherwise
    f([lo, hi]) is moved (by the original's period) to meet the domain's middle.
    """
    if fmap.period > 0:
        a = float(fmap(np.array([lo]))[0])
        return -fmap.period * np.floor((a - domain[0]) / fmap.period + 1e-9)  # a rounding below x0 is x0
    if period <= 0:
        return 0.0
    # x = t at the knots, so the domain's middle compares with the bounds' middle directly
    return period * round((0.5 * (domain[0] + domain[1]) - 0.5 * (lo + hi)) / period)


def _rotated(surface: BSplineSurface, axis: int, start: float) -> BSplineSurface:
    """A surface that is periodic in ``axis`` (given over one period [x0, x0 + P]) re-cut to start at
    ``start`` (in [x0, x0 + P)): its domain becomes [start, start + P]."""
    (x0, x1) = surface.domain_u if axis == 0 else surface.domain_v
    period = x1 - x0
    if start - x0 <= 1e-9 * period or x1 - start <= 1e-9 * period:
        return surface  # (the face's pcurves reach past the domain's end by rounding: they are cut there)
    p = surface.degree[axis]
    knots = surface.knots_u if axis == 0 else surface.knots_v
    ctrl = np.moveaxis(surface.homogeneous(), axis, 0)
    while np.count_nonzero(knots == start) < p:
        knots, ctrl = insert_knot(knots, ctrl, p, start)
    first = int(np.searchsorted(knots, start, side="left"))  # index of the first knot equal to start
    # head: [x0, start] uses points [: first], tail: [start, x1] points [first - 1:] (the split point shared)
    tail_knots = np.concatenate([[start], knots[first:]])
    tail = ctrl[first - 1 :]
    head = ctrl[:first]
    head_knots = knots[: first + p]  # ends with p copies of start
    # joined: tail over [start, x1], then head moved by one period over [x1, start + period]
    new_knots = np.concatenate([tail_knots[:-1], head_knots[p + 1 :] + period, [start + period]])
    new_ctrl = np.concatenate([tail, head[1:]], axis=0)
    new_ctrl = np.moveaxis(new_ctrl, 0, axis)
    ku, kv = (new_knots, surface.knots_v) if axis == 0 else (surface.knots_u, new_knots)
    w = new_ctrl[..., 3]
    return make_surface(
        surface.degree, ku, kv, new_ctrl[..., :3] / w[..., None], None if surface.weights is None else w
    )


def _restricted(surface: BSplineSurface, axis: int, a: float, b: float) -> BSplineSurface:
    """The surface cut to [a, b] in ``axis`` where that is inside its domain (knot insertion)."""
    from bsrt.geometry.bspline import restrict

    lo, hi = surface.domain_u if axis == 0 else surface.domain_v
    tol = 1e-12 * max(1.0, abs(lo), abs(hi))
    a, b = max(a, lo), min(b, hi)
    if a - lo <= tol:
        a = lo
    if hi - b <= tol:
        b = hi
    if not a < b or (a == lo and b == hi):
        return surface
    ranges = [(surface.domain_u), (surface.domain_v)]
    ranges[axis] = (a, b)
    return restrict(surface, *ranges)


def _deviation(at, local: BSplineSurface, pmap: FaceMap) -> float:
    """The largest distance between the original surface (its :func:`_checker` ``at``) and the B-spline
    at mapped points of a grid.

    A plane converted to a bilinear patch (2 x 2 poles, parameters kept): their difference is bilinear,
    its length convex along every line of the grid, so largest at a corner of the domain (the grid's
    bounds lie inside it), where the patch is its poles: measured there, exactly.
    """
    if getattr(at, "affine", False) and local.shape == (2, 2) and local.degree == (1, 1) and pmap.identity:
        (x0, x1), (y0, y1) = local.domain_u, local.domain_v
        want = at(np.array([x0, x0, x1, x1]), np.array([y0, y1, y0, y1]))  # the poles' order, (i, j) i-major
        return float(np.max(np.linalg.norm(local.points.reshape(4, 3) - want, axis=1)))
    umin, umax, vmin, vmax = pmap.bounds
    fractions = np.array([0.0, 0.137, 0.291, 0.5, 0.618, 0.853, 1.0])
    us, vs = umin + fractions * (umax - umin), vmin + fractions * (vmax - vmin)
    # the map is separable: the grid's (x, y) is the grid of f(u) and g(v)
    x = np.clip(pmap.fu(us), *local.domain_u)
    y = np.clip(pmap.fv(vs), *local.domain_v)
    want = at(np.repeat(us, vs.size), np.tile(vs, us.size))  # the grid (us[i], vs[j]), i-major
    got = grid_points(local, x, y).reshape(-1, 3)
    return float(np.max(np.linalg.norm(got - want, axis=1)))


def _extract(bs) -> BSplineSurface:
    """A Geom_BSplineSurface (made non-periodic, in place) as a BSplineSurface."""
    if bs.IsUPeriodic():
        bs.SetUNotPeriodic()
    if bs.IsVPeriodic():
        bs.SetVNotPeriodic()
    nu, nv = bs.NbUPoles(), bs.NbVPoles()
    pole, weight = bs.Pole, bs.Weight
    rows, cols = range(1, nu + 1), range(1, nv + 1)
    points = np.array([pole(i, j).Coord() for i in rows for j in cols], dtype=np.float64).reshape(nu, nv, 3)
    weights = None  # (non-rational)
    if bs.IsURational() or bs.IsVRational():
        weights = np.array([weight(i, j) for i in rows for j in cols], dtype=np.float64).reshape(nu, nv)
        if np.all(weights == 1.0):
            weights = None
    knots_u = flat_knots(bs.UKnot, bs.UMultiplicity, bs.NbUKnots())
    knots_v = flat_knots(bs.VKnot, bs.VMultiplicity, bs.NbVKnots())
    try:
        return make_surface((bs.UDegree(), bs.VDegree()), knots_u, knots_v, points, weights)
    except InputError as e:
        raise FaceError(f"the converted surface is invalid ({e})") from None


def flat_knots(knot, multiplicity, n) -> np.ndarray:
    """(K,) float64: the knots of an OpenCASCADE curve or surface direction, each repeated by its multiplicity."""
    return np.array([x for i in range(1, n + 1) for x in [knot(i)] * multiplicity(i)], dtype=np.float64)

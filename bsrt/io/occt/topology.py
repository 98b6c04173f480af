"""A face's wires as closed trim loops in its B-spline's domain.

Every wire of the face (outer and inner alike: bsrt's rule is even-odd)
becomes one or more :class:`~bsrt.geometry.trim.TrimLoop`, in steps:

1. **Edges in order** along the wire (``BRepTools_WireExplorer``, else as
   stored, chained greedily), each edge's pcurve in the original (u, v)
   (:func:`~bsrt.io.occt.curves.pcurve`).
2. **Chained across the seam.** In a periodic direction a pcurve may be
   given a whole period away from its neighbours (seam edges, third-party
   files): each curve is moved by whole periods to start where the previous
   one ends. Where two consecutive ends differ in (u, v) but meet in
   space (a pole, a cone's apex: a degenerate edge the file leaves out),
   the straight iso-segment between them is added. A gap that is a gap in
   space too means the wire does not close: :class:`TrimError`.
3. **Placed in the face's bounds.** A closed loop is moved by whole periods
   into the face's (u, v) bounds; where the face goes all the way round a
   direction and the loop straddles the bounds' end (a hole on the seam),
   a copy one period over is added, each copy cut at the domain's edge.
   A chain that goes once round a periodic direction (a circle bounding a
   band of a cylinder, with no seam edge) ends a whole period from where it
   starts: it is closed along the domain's top edge, and, since the face
   lies left of its wire (FORWARD, in (u, v)), the whole domain is added
   as one more loop when the parity of the region above the topmost such
   chain would come out wrong.
4. **Mapped** into the B-spline's (x, y) (:func:`~bsrt.io.occt.curves.map_curve`),
   the ends of consecutive curves snapped together (they differ by at
   most the vertex tolerances), and excursions out of the domain (third-party
   files have them, by about the edge tolerance) cut off at the domain's edge.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from bsrt.geometry.bspline import BSplineSurface, insert_knot
from bsrt.geometry.trim import TrimCurve, TrimLoop, point_outside
from bsrt.io.occt.curves import (
    FIT_TOLERANCE,
    TrimError,
    bezier_form,
    derivative_bounds,
    map_curve,
    pcurve,
    reversed_curve,
    segment,
    shifted,
)
from bsrt.io.occt.reading import cast
from bsrt.io.param_map import FaceMap

_MEET = 1e-7  # ends closer than this (a fraction of the model's size) meet, in space


def face_loops(face, original, pmap: FaceMap, local: BSplineSurface, size: float) -> list[TrimLoop]:
    """The face's wires as closed loops in ``local``'s (x, y) domain (see the module doc).

    original: the face's OpenCASCADE surface (local coordinates); size: the
    model's size in those units. Raises TrimError.
    """
    from OCP.TopAbs import TopAbs_WIRE
    from OCP.TopExp import TopExp_Explorer

    closed, around = [], []
    explorer = TopExp_Explorer(face, TopAbs_WIRE)
    while explorer.More():
        wire = cast("Wire", explorer.Current())
        edges = wire_edges(wire, face)
        curves = [c for c in (pcurve(e, face) for e in edges) if c is not None]
        if curves:
            meet = functools.cache(lambda edges=edges: max(_MEET * size, 2.0 * _tolerance(edges)))
            chain, gap = _chained(curves, original, pmap, meet)
            (around if gap is not None else closed).append((chain, gap))
        explorer.Next()
    loops = []
    for chain, _ in closed:
        loops.extend(_placed(chain, pmap))
    if around:
        loops.extend(_closed_around(around, pmap))

    @functools.cache
    def tolerance() -> tuple[float, float]:  # only a fitted pcurve needs it: the bounds are computed once, if at all
        lu, lv = derivative_bounds(local)
        tol = FIT_TOLERANCE * size
        return (tol / max(lu, 1e-300), tol / max(lv, 1e-300))

    return [TrimLoop(tuple(_close([map_curve(c, pmap, tolerance) for c in loop], local, size))) for loop in loops]


def wire_edges(wire, face) -> list:
    """The wire's edges in order along the wire, each with its orientation in the face."""
    from OCP.BRepTools import BRepTools_WireExplorer
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer

    edges = []
    try:
        walker = BRepTools_WireExplorer(wire, face)
        while walker.More():
            edges.append(cast("Edge", walker.Current()))
            walker.Next()
    except Exception:  # noqa: BLE001 - OCP raises Standard_Failure subclasses
        edges = []
    if edges and len(edges) == wire.NbChildren():  # (a wire's children are its edges: all walked)
        return edges
    stored = []
    explorer = TopExp_Explorer(wire, TopAbs_EDGE)
    while explorer.More():
        stored.append(cast("Edge", explorer.Current()))
        explorer.Next()
    return edges if len(edges) == len(stored) else stored  # the walker skips edges of odd wires: take them all


def _tolerance(edges) -> float:
    """The largest tolerance of the edges and their vertices (how far apart the file lets ends be)."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_VERTEX
    from OCP.TopExp import TopExp_Explorer

    worst = 0.0
    for edge in edges:
        worst = max(worst, BRep_Tool.Tolerance_s(edge))
        explorer = TopExp_Explorer(edge, TopAbs_VERTEX)
        while explorer.More():
            worst = max(worst, BRep_Tool.Tolerance_s(cast("Vertex", explorer.Current())))
            explorer.Next()
    return worst


def _periods(pmap: FaceMap) -> np.ndarray:
    return np.array([pmap.u_period, pmap.v_period])


def _nearest_shift(frm: np.ndarray, to: np.ndarray, periods: np.ndarray) -> np.ndarray:
    """The whole periods (2,) that bring point ``frm`` nearest ``to``."""
    out = np.zeros(2)
    for axis in (0, 1):
        if periods[axis] > 0:
            out[axis] = periods[axis] * np.round((to[axis] - frm[axis]) / periods[axis])
    return out


def _space_gap(original, a: np.ndarray, b: np.ndarray) -> float:
    pa, pb = original.Value(float(a[0]), float(a[1])), original.Value(float(b[0]), float(b[1]))
    return float(pa.Distance(pb))


def _chained(curves: list[TrimCurve], original, pmap: FaceMap, meet):
    """(curves end to end, across the seam; the closing gap (2,) if it goes once round a period, else None).

    meet: a function of no arguments giving how far apart (model units) two ends may be in space and
    still meet (called only where two ends differ in (u, v)).
    """
    periods = _periods(pmap)
    umin, umax, vmin, vmax = pmap.bounds
    scale = float(np.hypot(umax - umin, vmax - vmin))
    snap = 1e-6 * scale
    periodic = bool(periods.any())
    out = [curves[0]]
    first, end = curves[0].ends()  # the chain's start, and its end so far
    left = list(curves[1:])
    ordered = True
    while left:
        if ordered:
            c = left.pop(0)
            if periodic:
                c = shifted(c, _nearest_shift(c.ends()[0], end, periods))
            start, c_end = c.ends()
            if _hypot(start - end) > snap and _space_gap(original, start, end) > meet():
                ordered = False  # not in order along the wire: chain the rest greedily
                left.insert(0, c)
                continue
        else:
            c = _greedy_next(end, left, periods)
            start, c_end = c.ends()
        if _hypot(start - end) > snap:
            if _space_gap(original, start, end) > meet():
                raise TrimError(
                    f"a wire does not close: consecutive edges are {_space_gap(original, start, end):.3g} apart"
                )
            out.append(segment(end, start))  # a degenerate edge left out (a pole, an apex)
        out.append(c)
        end = c_end
    last = end
    gap = first - last
    back = _nearest_shift(last, first, periods)
    if np.hypot(*(gap - back)) <= snap or _space_gap(original, first, last) <= meet():
        if np.any(back) and np.hypot(*(gap - back)) <= snap:
            return out, back  # ends one period from its start: round the surface
        if np.hypot(*gap) > snap:
            out.append(segment(last, first))
        return out, None
    raise TrimError(f"a wire does not close: its ends are {_space_gap(original, first, last):.3g} apart")


def _hypot(d: np.ndarray) -> float:
    """|d| of a (2,) vector (math.hypot: one call, no array)."""
    x, y = d.tolist()
    return math.hypot(x, y)


def _greedy_next(end: np.ndarray, left: list[TrimCurve], periods: np.ndarray) -> TrimCurve:
    """Pop the curve of ``left`` (reversed and moved by whole periods if that fits better) that starts nearest ``end``."""
    best, k, flip, move = np.inf, 0, False, np.zeros(2)
    for i, c in enumerate(left):
        e = c.ends()
        for f, p in ((False, e[0]), (True, e[1])):
            s = _nearest_shift(p, end, periods)
            d = np.hypot(*(p + s - end))
            if d < best:
                best, k, flip, move = d, i, f, s
    c = left.pop(k)
    return shifted(reversed_curve(c) if flip else c, move)


def _box(chain: list[TrimCurve]) -> np.ndarray:
    pts = np.concatenate([c.points for c in chain])
    return np.array([pts[:, 0].min(), pts[:, 0].max(), pts[:, 1].min(), pts[:, 1].max()])


def _placed(chain: list[TrimCurve], pmap: FaceMap) -> list[list[TrimCurve]]:
    """A closed chain moved by whole periods into the face's bounds (and a copy a period over where it
    straddles the end of a direction the face goes all the way round)."""
    periods = _periods(pmap)
    if not periods.any():  # nothing to move
        return [list(chain)]
    bounds = np.array(pmap.bounds)
    box = _box(chain)
    move = np.zeros(2)
    for axis in (0, 1):
        p = periods[axis]
        if p > 0:
            lo, hi = bounds[2 * axis], bounds[2 * axis + 1]
            mid = 0.5 * (box[2 * axis] + box[2 * axis + 1])
            move[axis] = p * np.round((0.5 * (lo + hi) - mid) / p)
    chain = [shifted(c, move) for c in chain]
    box = _box(chain)
    copies = [chain]
    for axis in (0, 1):
        p = periods[axis]
        lo, hi = bounds[2 * axis], bounds[2 * axis + 1]
        if p > 0 and hi - lo >= p * (1 - 1e-9):
            slack = 1e-9 * p
            offset = np.zeros(2)
            if box[2 * axis] < lo - slack:
                offset[axis] = p
            elif box[2 * axis + 1] > hi + slack:
                offset[axis] = -p
            if offset.any():
                copies.append([shifted(c, offset) for c in chain])
    return copies


def _closed_around(around, pmap: FaceMap) -> list[list[TrimCurve]]:
    """Chains that go once round a periodic direction, closed along the domain's edge (see the module doc)."""
    umin, umax, vmin, vmax = pmap.bounds
    loops = []
    directions = []
    axes = {int(np.flatnonzero(gap)[0]) if np.count_nonzero(gap) == 1 else -1 for _, gap in around}
    if axes != {0} and axes != {1}:
        raise TrimError("a wire goes round both periodic directions of the surface")
    axis = axes.pop()
    other = 1 - axis
    top = (vmax, umax)[other]
    for chain, gap in around:
        # start inside the bounds along ``axis``
        lo = (umin, vmin)[axis]
        start = chain[0].ends()[0]
        move = np.zeros(2)
        p = abs(gap[axis])
        move[axis] = -p * np.floor((start[axis] - lo) / p)
        chain = [shifted(c, move) for c in chain]
        a, b = chain[0].ends()[0], chain[-1].ends()[1]
        corner_b, corner_a = b.copy(), a.copy()
        corner_b[other] = top
        corner_a[other] = top
        closing = [segment(b, corner_b), segment(corner_b, corner_a), segment(corner_a, a)]
        loop = chain + closing
        directions.append(
            (float(np.mean([c.points[:, other].mean() for c in chain])), float(np.sign(b[axis] - a[axis])))
        )
        offset = np.zeros(2)
        offset[axis] = a[axis] - b[axis]  # the copy one period back along the chain covers the rest
        loops.append(loop)
        loops.append([shifted(c, offset) for c in loop])
    # the face lies left of its wires: above a chain running +u (axis 0), below one running -u; for
    # chains round v (axis 1) left of +v is -u, so the sense flips
    topmost = max(directions)[1]
    above_is_face = topmost > 0 if axis == 0 else topmost < 0
    if (len(around) % 2 == 1) != above_is_face:
        corners = np.array([[umin, vmin], [umax, vmin], [umax, vmax], [umin, vmax]])
        loops.append([segment(corners[i], corners[(i + 1) % 4]) for i in range(4)])
    return loops


def _close(curves: list[TrimCurve], surface: BSplineSurface, size: float) -> list[TrimCurve]:
    """Snap the ends of consecutive curves together and cut off their excursions out of the domain."""
    n = len(curves)
    ends = np.stack([c.ends() for c in curves])  # (n, 2, 2)
    domain = (*surface.domain_u, *surface.domain_v)
    mids = 0.5 * (ends[:, 1] + np.concatenate([ends[1:, 0], ends[:1, 0]]))  # where curve i ends and curve i + 1 starts
    pts = [c.points.copy() for c in curves]
    for i in range(n):
        pts[i][-1] = mids[i]
        pts[(i + 1) % n][0] = mids[i]
    boxes = _boxes(pts)
    snapped = [TrimCurve(c.degree, c.knots, p, c.weights) for c, p in zip(curves, pts)]
    inside = [_inside_domain(c, domain, box) for c, box in zip(snapped, boxes)]
    # (a curve _inside_domain returns as it is keeps its box)
    return _off_the_edges(inside, domain, [box if a is b else None for a, b, box in zip(inside, snapped, boxes)])


def _boxes(pts: list[np.ndarray]) -> list[tuple[list[float], list[float]]]:
    """Each (n_k, 2) point array's ([x_min, y_min], [x_max, y_max]), all in a few NumPy calls."""
    if len(pts) == 1:
        return [(pts[0].min(axis=0).tolist(), pts[0].max(axis=0).tolist())]
    starts = np.cumsum([0] + [p.shape[0] for p in pts[:-1]])
    every = np.concatenate(pts)
    return list(zip(np.minimum.reduceat(every, starts).tolist(), np.maximum.reduceat(every, starts).tolist()))


def _off_the_edges(curves: list[TrimCurve], domain, boxes=None) -> list[TrimCurve]:
    """The curves that run along an edge of the domain (a seam, the side of a face that fills its
    bounds) moved just outside it, their neighbours' ends with them.

    On the loop itself the even-odd test may go either way, and a hit on a
    seam lies on the domain's edge, where its (u, v) is clamped: a loop a
    rounding error inside would leave a crack one ray wide. Outside the
    domain there is no surface, so the loop may run there. boxes: each
    curve's control points' ([x_min, y_min], [x_max, y_max]) where known, else None.
    """
    a0, a1, b0, b1 = domain
    span = np.array([a1 - a0, b1 - b0])
    near = (1e-9 * span).tolist()
    push = (1e-9 * span).tolist()
    pts = [c.points for c in curves]
    moved = []
    for k, p in enumerate(pts):
        along = False
        box = boxes[k] if boxes is not None else None
        lows, highs = box if box is not None else (p.min(axis=0).tolist(), p.max(axis=0).tolist())
        for axis, (lo, hi) in enumerate(((a0, a1), (b0, b1))):
            # every |x - lo| <= near: |x - lo| (rounded too) is largest at the smallest or the largest x
            if abs(lows[axis] - lo) <= near[axis] and abs(highs[axis] - lo) <= near[axis]:
                p = p.copy() if p is curves[k].points else p
                p[:, axis], along = lo - push[axis], True
            elif abs(lows[axis] - hi) <= near[axis] and abs(highs[axis] - hi) <= near[axis]:
                p = p.copy() if p is curves[k].points else p
                p[:, axis], along = hi + push[axis], True
        pts[k] = p
        moved.append(along)
    if not any(moved):
        return curves
    pts = [p.copy() if p is c.points else p for p, c in zip(pts, curves)]
    n = len(pts)
    for i in range(n):  # a moved curve's ends carry its neighbours' ends along
        j = (i + 1) % n
        if moved[i] and not moved[j]:
            pts[j][0] = pts[i][-1]
        elif moved[j] and not moved[i]:
            pts[i][-1] = pts[j][0]
        elif moved[i] and moved[j]:  # two edges meeting at a corner: both ends at the pushed corner
            corner = _outer(pts[i][-1], pts[j][0], domain)
            pts[i][-1] = corner
            pts[j][0] = corner
    return [TrimCurve(c.degree, c.knots, p, c.weights) for c, p in zip(curves, pts)]


def _outer(a: np.ndarray, b: np.ndarray, domain) -> np.ndarray:
    """Of two nearly equal points near a corner of the domain, coordinate by coordinate the one farther out."""
    a0, a1, b0, b1 = domain
    mid = np.array([0.5 * (a0 + a1), 0.5 * (b0 + b1)])
    return np.where(np.abs(a - mid) >= np.abs(b - mid), a, b)


def _inside_domain(curve: TrimCurve, domain, box=None) -> TrimCurve:
    """The curve with its excursions out of the surface's domain moved onto the domain's edge.

    Only the part inside the domain matters (the surface has nothing
    outside it), so each excursion is cut off exactly (its ends found by
    bisection, the curve split there by knot insertion) and its control
    points clipped onto the domain's edge. If the curve still leaves the
    domain (:func:`~bsrt.geometry.trim.point_outside`, exact), it weaves along
    the edge between the samples, by about the file's tolerance: its
    control points outside are clipped too. A curve out by no more than
    1e-9 of the domain's diagonal is kept as it is. box: the control points'
    ([x_min, y_min], [x_max, y_max]) if known.
    """
    a0, a1, b0, b1 = domain
    eps = 1e-12 * np.hypot(a1 - a0, b1 - b0)  # a curve along the edge is inside, rounding aside
    p_all = curve.points
    (x_lo, y_lo), (x_hi, y_hi) = box if box is not None else (p_all.min(axis=0).tolist(), p_all.max(axis=0).tolist())
    if x_lo >= a0 - eps and x_hi <= a1 + eps and y_lo >= b0 - eps and y_hi <= b1 + eps:
        return curve  # the control points are inside: so is the curve (convex hull)
    near = 1e-9 * np.hypot(a1 - a0, b1 - b0)
    if (
        x_lo >= a0 - near and x_hi <= a1 + near and y_lo >= b0 - near and y_hi <= b1 + near
    ):  # out by rounding of the bounds: onto the edge, moved <= that
        return TrimCurve(curve.degree, curve.knots, np.clip(p_all, [a0, b0], [a1, b1]), curve.weights)
    if point_outside(bezier_form(curve), (a0 - near, a1 + near, b0 - near, b1 + near)) is None:
        # the curve itself is out by rounding only, while control points lie far past the edge (an arc
        # touching it): kept as it is; clipping them would bend it (a Pro/E part's 145.6-degree arc,
        # 1.78e-9 past its plane's bound, lost 43 units of its middle)
        return curve
    lo, hi = curve.domain
    t = np.linspace(lo, hi, 64 * (curve.points.shape[0] + 1))
    curve_at = curve.evaluator()

    def inside(x):
        uv = curve_at(np.atleast_1d(x))
        return (uv[:, 0] >= a0 - eps) & (uv[:, 0] <= a1 + eps) & (uv[:, 1] >= b0 - eps) & (uv[:, 1] <= b1 + eps)

    uv = curve_at(t)
    state = (uv[:, 0] >= a0 - eps) & (uv[:, 0] <= a1 + eps) & (uv[:, 1] >= b0 - eps) & (uv[:, 1] <= b1 + eps)
    k = np.flatnonzero(state[:-1] != state[1:])
    # each crossing is of one edge line, the one the outside sample is past: solve coordinate = line there
    outer = np.where(state[k], k + 1, k)
    lines = np.array([a0 - eps, a1 + eps, b0 - eps, b1 + eps])
    past = np.stack(
        [uv[outer, 0] < lines[0], uv[outer, 0] > lines[1], uv[outer, 1] < lines[2], uv[outer, 1] > lines[3]], axis=1
    )
    which = np.argmax(past, axis=1)
    axis, line = which // 2, lines[which]
    a, b = t[k], t[k + 1]
    fa = uv[k, axis] - line
    fb = uv[k + 1, axis] - line
    scale = 1e-15 * max(1.0, abs(a0), abs(a1), abs(b0), abs(b1))
    best = np.where(np.abs(fa) <= np.abs(fb), a, b)
    best_f = np.minimum(np.abs(fa), np.abs(fb))
    for _ in range(60):  # modified regula falsi (Illinois), all crossings at once, to rounding
        if np.all((best_f <= scale) | (b - a <= 1e-15 * (hi - lo))):
            break
        with np.errstate(all="ignore"):
            m = b - fb * (b - a) / (fb - fa)
        m = np.where((m > a) & (m < b), m, 0.5 * (a + b))
        fm = curve_at(m)[np.arange(m.size), axis] - line
        better = np.abs(fm) < best_f
        best, best_f = np.where(better, m, best), np.where(better, np.abs(fm), best_f)
        right = np.sign(fm) == np.sign(fa)  # the crossing is in [m, b]: b kept, its value halved
        a, b, fa, fb = (
            np.where(right, m, a),
            np.where(right, b, m),
            np.where(right, fm, 0.5 * fa),
            np.where(right, 0.5 * fb, fm),
        )
    cuts = best

    p = curve.degree
    knots, ctrl = curve.knots, curve.homogeneous()
    for x in cuts:
        for _ in range(p - int(np.count_nonzero(knots == x))):
            knots, ctrl = insert_knot(knots, ctrl, p, x)
    points = ctrl[:, :2] / ctrl[:, 2:3]
    weights = ctrl[:, 2]
    bounds = np.concatenate([[lo], cuts, [hi]])
    middles_inside = inside(0.5 * (bounds[:-1] + bounds[1:])).tolist()
    for a, b, middle_inside in zip(bounds[:-1], bounds[1:], middles_inside):
        if not middle_inside:  # an excursion: its control points onto the edge
            first = int(np.searchsorted(knots, a, side="right")) - 1 - p
            last = int(np.searchsorted(knots, b, side="left"))
            piece = points[max(first, 0) : last]
            piece[:, 0] = np.clip(piece[:, 0], a0, a1)
            piece[:, 1] = np.clip(piece[:, 1], b0, b1)
    out = TrimCurve(p, knots, points, None if curve.weights is None else weights)
    if point_outside(bezier_form(out), (a0 - eps, a1 + eps, b0 - eps, b1 + eps)) is not None:
        # it weaves along the edge (within the file's tolerance of it) and pokes out between the samples:
        # its control points outside go onto the edge, which moves it by less than it pokes out
        points[:, 0] = np.clip(points[:, 0], a0, a1)
        points[:, 1] = np.clip(points[:, 1], b0, b1)
        out = TrimCurve(p, knots, points, None if curve.weights is None else weights)
    return out

"""Trim loops of one trimmed surface or face: from IGES curves to TrimLoops on its B-spline.

Loops, in this order:

1. Parameter-space curves are taken as written (a composite's members one by
   one); model-space ones are carried into (u, v) (``pcurves``, ``bsrt.io.invert``: exactly for
   planes and parallelograms (a 122 over a segment), polylines within ``INVERSION_TOL`` otherwise, one warning per file).
   On a B-spline closed in a direction (its two edges across it coincide), a
   carried curve's samples on the seam take the side of their neighbours, and a
   carried curve lying wholly on the seam the side where the previous curve of
   its loop ends (the first curve: where the second one meets it).
2. On 190-198 surfaces, loops whose angles span more than 2 pi (or pass 4 pi)
   are in degrees (OCCT writes them so) and become radians; curves along an
   angle are shifted by whole turns to continue the previous one.
3. The surface's B-spline is built over the box of the loops' control points
   (a 128 keeps its U0..U1 x V0..V1 cut when the loops stay inside it, else its
   whole knot domain; with no outer loop, the natural range), and the loops are
   mapped onto its parameters (exact where the maps are affine or the curve is
   an iso-line, otherwise within ``MAP_TOL``).
4. The curves are chained end to end; a curve whose far end meets the chain is
   turned round (writers disagree on edge senses). A gap up to ``GAP`` x the
   domain's diagonal is closed by moving both ends to their midpoint (an edited
   end control point: the files' own tolerances are looser than bsrt's 1e-9
   closure check; bearing.iges needs 7e-7, hammer.iges 2.5e-6). A wider gap
   whose ends meet in model space, within the file's resolution (Global
   parameter 19) -- a collapsed edge, a pole -- is crossed by a straight
   segment; any other is an open loop (``OpenLoop``: the surface is left out with one
   warning naming the entity). Periodic surfaces: see ``iges_seams``. Curves that stray out of the
   domain by up to ``OVERSHOOT`` x its diagonal are pulled back (their outside
   control points clamped to the domain; hammer.iges needs 6.4e-5); further,
   an error (``OffDomain``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from bsrt.errors import InputError
from bsrt.geometry.bspline import evaluate as evaluate_surface
from bsrt.geometry.trim import TrimCurve, TrimLoop, make_trim_curve
from bsrt.io.iges.bspline import clamp, line_curve, reverse
from bsrt.io.iges.curves import CURVE_TYPES, Unsupported, pieces
from bsrt.io.iges.pcurves import invert_curves, map_curve
from bsrt.io.iges.seams import Open, close_once_round
from bsrt.io.iges.surfaces import SurfaceDef
from bsrt.io.invert import CurveInverse

GAP = 1e-4  # largest loop gap closed, as a fraction of the domain's diagonal
OVERSHOOT = 1e-3  # largest excursion out of the domain pulled back, likewise
INVERSION_TOL = 1e-6  # polyline accuracy of inverted curves, as a fraction of the domain's diagonal
MAP_TOL = 1e-9  # accuracy of trim curves mapped onto an analytic surface's B-spline


@dataclass
class Piece:
    """A 2-D trim curve. space: "iges" (the entity's own parameters) or "nurbs"."""

    curve: TrimCurve
    space: str
    source: int  # DE of the entity it came from
    inverted: bool = False  # carried from model space (not written by the file in (u, v))


BRIDGE = "bridge"  # a vertex edge without a parameter-space curve


class OpenLoop(InputError):
    """A trim loop that does not close (the message names the entity and says why)."""


class OffDomain(InputError):
    """A trim curve that leaves the surface's domain (the message names the entity and the curve)."""


class Unbounded(Exception):
    """An unbounded surface (a plane, cylinder, cone) with no loop to bound it."""


@dataclass
class RawLoop:
    items: list  # Piece or BRIDGE
    label: str  # how messages name the loop


@dataclass
class Face:
    """What one 144/143/510 became."""

    surface: object  # BSplineSurface
    loops: int
    inverted: int  # curves carried into (u, v) by inversion
    note: str | None = None  # how it was drawn otherwise than written (a warning), if it was


class LoopBuilder:
    """Collects the loops of one trimmed surface or face and makes its trimmed B-spline."""

    def __init__(self, f, entity, sd: SurfaceDef):
        self.f, self.entity, self.sd = f, entity, sd
        self.inverted = 0

    def fail(self, message: str, line: int | None = None):
        return self.f.fail(self.entity, message, line)

    # -- curves -------------------------------------------------------------

    def param_pieces(self, ref, de: int, what: str) -> list[Piece]:
        target = self.f.get(ref, de, what)
        if target.type not in CURVE_TYPES:
            raise Unsupported(target, "as a parameter-space curve")
        return [
            Piece(TrimCurve(c.degree, c.knots, c.points[:, :2].copy(), c.weights), "iges", target.de)
            for c in pieces(self.f, target)
        ]

    def model_pieces(self, ref, de: int, what: str, backwards: bool = False) -> list[Piece]:
        """A model-space curve carried into the surface's parameters, a composite's members
        one by one (the loop's chaining orients them)."""
        target = self.f.get(ref, de, what)
        if target.type not in CURVE_TYPES:
            raise Unsupported(target, "as a model-space curve")
        out = self._invert(pieces(self.f, target), target.de)
        out = [BRIDGE if x.curve is None else x for x in out]  # a collapsed edge: crossed straight
        if backwards:
            out = [x if x is BRIDGE else replace(x, curve=reverse(x.curve)) for x in out[::-1]]
        return out

    def _invert(self, curves: list[TrimCurve], source: int) -> list[Piece]:
        """The 3-D curves in the surface's parameters (all carried together)."""
        sd = self.sd
        if sd.plane is not None:  # affine: exact
            return [Piece(TrimCurve(c.degree, c.knots, sd.invert(c.points), c.weights), "iges", source) for c in curves]
        self.inverted += len(curves)

        def tol(uv):  # the curve's own extent: the domain, which holds it, is no smaller
            return INVERSION_TOL * max(math.hypot(*np.ptp(uv, axis=0)), 1e-300)

        if sd.invert is not None:
            out = invert_curves(curves, lambda p, hint: sd.invert(p), tol, sd.periodic)
            return [Piece(c, "iges", source, True) for c in out]
        key = ("inverse", sd.entity.de)
        if key not in self.f.cache:
            s, space = sd.inverse_target()
            self.f.cache[key] = (sd.closed_inverse or CurveInverse(s), space)
        inverse, space = self.f.cache[key]
        return [Piece(c, space, source, True) for c in invert_curves(curves, inverse, tol)]

    # -- loops --------------------------------------------------------------

    def build(self, raw: list[RawLoop], outer_is_domain: bool = False) -> Face:
        raw = [r for r in raw if any(isinstance(x, Piece) for x in r.items)]
        sd = self.sd
        if (outer_is_domain or not raw) and not sd.bounded:
            raise Unbounded()
        self._degrees(raw)
        if any(sd.periodic):
            for r in raw:
                self._align(r)
            raw = self._seams(raw)
        box = None if outer_is_domain else self._box(raw)  # the outer boundary is the natural one
        try:
            s, mu, mv = sd.place(box)
        except InputError as e:
            raise self.fail(str(e)) from None
        (u0, u1), (v0, v1) = s.domain_u, s.domain_v
        size = math.hypot(u1 - u0, v1 - v0)
        loops = []
        for r in raw:
            items = []
            for x in r.items:
                if isinstance(x, Piece) and x.space == "iges":
                    x = replace(x, curve=map_curve(x.curve, mu, mv, MAP_TOL * size)[0], space="nurbs")
                items.append(x)
            loops.append(self._chain(items, r.label, s))
        if outer_is_domain:
            corners = [(u0, v0), (u1, v0), (u1, v1), (u0, v1), (u0, v0)]
            loops.insert(
                0, TrimLoop(tuple(make_trim_curve(1, [0, 0, 1, 1], [a, b]) for a, b in zip(corners[:-1], corners[1:])))
            )
        try:
            return Face(s.with_trims(loops), len(loops), self.inverted)
        except InputError as e:
            raise self.fail(str(e)) from None

    def _degrees(self, raw: list[RawLoop]) -> None:
        """Angles of 190-198 faces written in degrees (a span over 2 pi) become radians."""
        if not any(self.sd.angular):
            return
        axes = [k for k in range(2) if self.sd.angular[k]]
        degrees = False
        for r in raw:  # loop by loop: loops may lie in different turns
            file_pieces = [x for x in r.items if isinstance(x, Piece) and not x.inverted]
            if file_pieces:
                pts = np.concatenate([p.curve.points for p in file_pieces])
                degrees |= any(
                    np.ptp(pts[:, k]) > 2 * math.pi * (1 + 1e-6) or np.abs(pts[:, k]).max() > 4 * math.pi for k in axes
                )
        if not degrees:
            return
        scale = np.ones(2)
        scale[axes] = math.pi / 180
        for r in raw:
            for i, x in enumerate(r.items):
                if isinstance(x, Piece) and not x.inverted:
                    r.items[i] = replace(x, curve=replace(x.curve, points=x.curve.points * scale))

    def _align(self, r: RawLoop) -> None:
        """Turn the loop's curves end to end and shift them by whole turns along periodic
        (angle) parameters so that each starts where the previous one ends (curves
        inverted from model space come with angles in (-pi, pi]); not across vertex edges."""
        idx = [i for i, x in enumerate(r.items) if isinstance(x, Piece)]
        if len(idx) < 2 or any(r.items[i].space != "iges" for i in idx):
            return
        per = np.array(self.sd.period, float)

        def wrapped(d):
            return np.where(per > 0, d - per * np.round(d / np.where(per > 0, per, 1)), d)

        def gap(p, q):
            return float(np.hypot(*wrapped(p - q)))

        curves = [clamp(r.items[i].curve) for i in idx]
        bridged = [False] + [any(x is BRIDGE for x in r.items[i + 1 : j]) for i, j in zip(idx[:-1], idx[1:])]
        (a0, b0), (a1, b1) = curves[0].ends(), curves[1].ends()
        # a curve closed across the seam (a full circle) meets its neighbour at both ends
        # modulo the period: then the nearer end as written (unwrapped) decides
        tie = 1e-9 * float(per.max())

        def nearer(d_first, d_second, u_first, u_second):  # is the second end the one that meets?
            if abs(d_first - d_second) <= tie:
                return u_second < u_first
            return d_second < d_first

        raw_gap = lambda p, q: float(np.hypot(*(p - q)))  # noqa: E731
        if not bridged[1] and nearer(
            min(gap(b0, a1), gap(b0, b1)),
            min(gap(a0, a1), gap(a0, b1)),
            min(raw_gap(b0, a1), raw_gap(b0, b1)),
            min(raw_gap(a0, a1), raw_gap(a0, b1)),
        ):
            curves[0] = reverse(curves[0])
        for k in range(1, len(curves)):
            if bridged[k]:  # a pole or apex lies between: the chain joins them as they are
                continue
            prev = curves[k - 1].ends()[1]
            a, b = curves[k].ends()
            if nearer(gap(prev, a), gap(prev, b), raw_gap(prev, a), raw_gap(prev, b)):
                curves[k] = reverse(curves[k])
                a = b
            shift = (prev - a) - wrapped(prev - a)
            if np.any(shift != 0):
                curves[k] = replace(curves[k], points=curves[k].points + shift)
        for i, c in zip(idx, curves):
            r.items[i] = replace(r.items[i], curve=c)

    def _seams(self, raw: list[RawLoop]) -> list[RawLoop]:
        """Loops that go once round a periodic surface joined or closed along the domain's
        edges, and all shifted into one window of each period (``iges_seams``)."""
        if any(isinstance(x, Piece) and x.space != "iges" for r in raw for x in r.items):
            return raw
        loops = [[x.curve if isinstance(x, Piece) else x for x in r.items] for r in raw]
        sources = [[x.source for x in r.items if isinstance(x, Piece)] for r in raw]
        try:
            loops, labels = close_once_round(
                loops, [r.label for r in raw], self.sd.period, self.sd.natural, self.sd.poles
            )
        except Open as e:
            raise self.open(str(e)) from None
        by_label = {r.label: s for r, s in zip(raw, sources)}
        out = []
        for loop, label in zip(loops, labels):
            src = iter(by_label[label] * 2)
            out.append(RawLoop([x if x is BRIDGE else Piece(x, "iges", next(src, -1)) for x in loop], label))
        return out

    def open(self, message: str):
        return OpenLoop(str(self.fail(message)))

    def off_domain(self, message: str):
        return OffDomain(str(self.fail(message)))

    def _box(self, raw: list[RawLoop]):
        """(u0, u1, v0, v1) the loops use, in the entity's parameters (None: natural)."""
        iges = [x.curve for r in raw for x in r.items if isinstance(x, Piece) and x.space == "iges"]
        if not iges:
            return None
        pts = np.concatenate([c.points for c in iges])  # their box holds the curves
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        nat = self.sd.natural
        if self.sd.fixed and (lo[0] < nat[0] or hi[0] > nat[1] or lo[1] < nat[2] or hi[1] > nat[3]):
            # it only decides whether a 128 is cut: a tight, sampled box
            pts = np.concatenate([c.evaluate(np.linspace(*c.domain, 16 * c.n + 1)) for c in iges])
            lo, hi = pts.min(axis=0), pts.max(axis=0)
        box = [lo[0], hi[0], lo[1], hi[1]]
        for k in range(2):
            a, b = nat[2 * k], nat[2 * k + 1]
            if a is not None and not self.sd.periodic[k] and not self.sd.fixed:  # a sphere's latitudes
                box[2 * k], box[2 * k + 1] = max(box[2 * k], a), min(box[2 * k + 1], b)
            if not box[2 * k] < box[2 * k + 1]:
                raise self.fail(f"its trim loops do not span any {'uv'[k]} range (they are degenerate)")
        return tuple(float(x) for x in box)

    def _chain(self, items: list, label: str, s) -> TrimLoop:
        """The loop's curves end to end, turned round where needed, gaps closed (s: the surface).

        (Long: orienting, gap measuring and closing depend on each other curve by curve.)
        """
        (u0, u1), (v0, v1) = s.domain_u, s.domain_v
        size = math.hypot(u1 - u0, v1 - v0)
        gap = GAP * size
        seq = []  # [curve, source DE, a vertex edge (bridge) comes before it, inverted from model space]
        pending = False
        for x in items:
            if x is BRIDGE:
                pending = True
            else:
                seq.append([clamp(x.curve), x.source, pending, x.inverted])
                pending = False
        if pending:
            seq[0][2] = True
        dist = lambda p, q: float(np.hypot(*(p - q)))  # noqa: E731
        closed = [k for k in range(2) if _closed(s, k)]
        if len(seq) > 1 and seq[0][3] and not seq[1][2]:  # the first curve's seam side, from its neighbour
            seq[0][0] = _seam_side(seq[0][0], _meeting_end(seq[1][0], seq[0][0], closed, s), closed, s)
        if len(seq) > 1 and not seq[1][2]:  # the first curve's sense, from its neighbour
            (a0, b0), (a1, b1) = seq[0][0].ends(), seq[1][0].ends()
            if min(dist(a0, a1), dist(a0, b1)) < min(dist(b0, a1), dist(b0, b1)):
                seq[0][0] = reverse(seq[0][0])
        for k in range(1, len(seq)):
            prev = seq[k - 1][0].ends()[1]
            if seq[k][3]:  # a model-space curve on the seam: its side was arbitrary
                seq[k][0] = _seam_side(seq[k][0], prev, closed, s)
            a, b = seq[k][0].ends()
            if dist(prev, b) < dist(prev, a):
                seq[k][0] = reverse(seq[k][0])
        curves: list[tuple[TrimCurve, int]] = []
        for k, (c, src, bridge, _) in enumerate(seq):
            if bridge:
                prev, start = seq[k - 1][0].ends()[1], c.ends()[0]
                if dist(prev, start) > 0:
                    curves.append((line_curve(prev, start), -1))
            curves.append((c, src))
        # close the gaps: small ones by moving both ends; wider ones that are no gap in model
        # space (a degenerate edge, or model-space curves meeting within the file's
        # resolution) by a straight segment in (u, v)
        out = [c for c, _ in curves]
        bridges = {}
        for j in range(len(out)):
            i = j - 1
            end, start = out[i].ends()[1], out[j].ends()[0]
            g = float(np.hypot(*(end - start)))
            if g > gap:
                p, q = evaluate_surface(s, np.array([end[0], start[0]]), np.array([end[1], start[1]]))[0]
                model_size = float(np.linalg.norm(np.ptp(s.points.reshape(-1, 3), axis=0)))
                if np.linalg.norm(p - q) <= max(self.f.resolution, 1e-9 * model_size):
                    bridges[j] = line_curve(end, start)
                    continue
                src_i, src_j = (f"DE {curves[n][1]}" if curves[n][1] > 0 else "a vertex" for n in (i, j))
                raise self.open(
                    f"{label} is open: the curve from {src_i} ends at ({end[0]:.9g}, {end[1]:.9g}) but the "
                    f"curve from {src_j} starts at ({start[0]:.9g}, {start[1]:.9g}), {g:.3g} apart "
                    f"(more than {GAP:g} x the domain's size), {np.linalg.norm(p - q):.3g} apart in model "
                    f"space (more than the file's resolution {self.f.resolution:g})"
                )
            if g > 0:
                mid = 0.5 * (end + start)
                out[i] = _set_end(out[i], mid, last=True)
                out[j] = _set_end(out[j], mid, last=False)
        sources = [src for _, src in curves]
        for j in sorted(bridges, reverse=True):
            out.insert(j, bridges[j])
            sources.insert(j, -1)
        trims = []
        for c, src in zip(out, sources):
            pts = c.points
            over = max(u0 - pts[:, 0].min(), pts[:, 0].max() - u1, v0 - pts[:, 1].min(), pts[:, 1].max() - v1)
            if over > 0:
                sampled = c.evaluate(np.linspace(*c.domain, 16 * c.n + 1))
                far = max(
                    u0 - sampled[:, 0].min(),
                    sampled[:, 0].max() - u1,
                    v0 - sampled[:, 1].min(),
                    sampled[:, 1].max() - v1,
                )
                if far > OVERSHOOT * size:
                    which = f"DE {src}" if src > 0 else "a vertex"
                    raise self.off_domain(
                        f"{label}: the curve from {which} leaves the surface's domain "
                        f"[{u0:.9g}, {u1:.9g}] x [{v0:.9g}, {v1:.9g}] by {far:.3g}"
                    )
                if far > 1e-10 * size:
                    c = replace(c, points=np.clip(pts, [u0, v0], [u1, v1]))
            try:
                trims.append(make_trim_curve(c.degree, c.knots, c.points, c.weights))
            except InputError as e:
                raise self.fail(f"{label}: the curve from DE {src}: {e}") from None
        return TrimLoop(tuple(trims))


def _closed(s, k: int) -> bool:
    """Do the surface's two edges across direction k (0: u, 1: v) coincide (a seam)?"""
    pts = s.points
    a, b = (pts[0], pts[-1]) if k == 0 else (pts[:, 0], pts[:, -1])
    w = s.weights
    same_w = w is None or np.array_equal(w[0] if k == 0 else w[:, 0], w[-1] if k == 0 else w[:, -1])
    size = float(np.linalg.norm(np.ptp(pts.reshape(-1, 3), axis=0)))
    return bool(same_w and np.abs(a - b).max() <= 1e-9 * size)


def _seam_side(c: TrimCurve, prev, closed: list, s) -> TrimCurve:
    """A curve lying wholly on the seam of a closed direction, moved to the seam's other
    side when that is where the previous curve ends (prev: its end, (2,))."""
    for k in closed:
        lo, hi = (s.domain_u, s.domain_v)[k]
        x = c.points[:, k]
        for here, there in ((lo, hi), (hi, lo)):
            if np.all(np.abs(x - here) <= 1e-12 * (hi - lo)) and abs(prev[k] - there) < abs(prev[k] - here):
                pts = c.points.copy()
                pts[:, k] = there
                c = replace(c, points=pts)
                break
    return c


def _meeting_end(c: TrimCurve, other: TrimCurve, closed: list, s):
    """The end of c (2,) nearest an end of ``other`` with the closed directions' seams
    identified (where a loop's first curve, on a seam, meets its second)."""
    period = np.array(
        [(s.domain_u, s.domain_v)[k][1] - (s.domain_u, s.domain_v)[k][0] if k in closed else 0 for k in range(2)]
    )

    def gap(p, q):
        d = np.abs(p - q)
        return float(np.hypot(*np.where(period > 0, np.minimum(d, period - d), d)))

    a, b = c.ends()
    return min((a, b), key=lambda p: min(gap(p, q) for q in other.ends()))


def _set_end(c: TrimCurve, point, last: bool) -> TrimCurve:
    pts = c.points.copy()
    pts[-1 if last else 0] = point
    return replace(c, points=pts)

"""Trim loops on periodic surfaces: across the seam, once round, and into one window.

A closed direction of a surface (the angle of a 120 turned a full turn or of a
192-198, a closed 128) has a period P: (u, v) and (u + P, v) are the same point.
Files write loops with pieces in any period; ``iges_loops`` first shifts each
piece by whole periods to continue the previous one. What is left is done here,
on the loops of one face in the entity's own parameters:

* A loop whose end is its start plus P (it goes once round: a circle on a
  cylinder, a latitude on a sphere) is rotated to start on the seam a (the
  first such loop's start; a curve is split where it crosses a + m P), so it
  runs from (a, c0) to (a + P, c1) exactly. Two such loops (a band between
  two circles) become one: the first, the seam at a + P, the second (turned
  round if it runs the same way), the seam at a -- the domain's edges, which
  meet in model space. One alone is closed along the domain's edge on its
  left (where the face is, for a counterclockwise outer loop): the natural
  bound of the other parameter there (a sphere's pole, a 120's generatrix end)
  or a pole (a cone's apex); with neither, the loop is open (an error).
* Every loop is then shifted by whole periods into the window [a, a + P]
  (a: the seam above, or the start of a loop's box where every loop fits),
  so the surface built over the loops' box covers one period at most.
"""

from __future__ import annotations

import math

import numpy as np

from bsrt.geometry.trim import TrimCurve
from bsrt.io.iges.bspline import clamp, line_curve, restrict, reverse


class Open(Exception):
    """A loop on a periodic surface that cannot be closed (the message says why)."""


def _shift(c: TrimCurve, k: int, d: float) -> TrimCurve:
    if d == 0:
        return c
    pts = c.points.copy()
    pts[:, k] += d
    return TrimCurve(c.degree, c.knots, pts, c.weights, c.pmap)


def _set(c: TrimCurve, k: int, value: float, last: bool) -> TrimCurve:
    pts = c.points.copy()
    pts[-1 if last else 0, k] = value
    return TrimCurve(c.degree, c.knots, pts, c.weights, c.pmap)


def _crossing(c: TrimCurve, k: int, x: float):
    """A parameter t of c where its coordinate k equals x (None if none is found)."""
    lo, hi = c.domain
    t = np.linspace(lo, hi, 64 * max(c.n, 2) + 1)
    f = c.evaluate(t)[:, k] - x
    sign = np.flatnonzero(np.sign(f[:-1]) * np.sign(f[1:]) <= 0)
    if not len(sign):
        return None
    a, b = t[sign[0]], t[sign[0] + 1]
    fa = f[sign[0]]
    for _ in range(200):
        m = 0.5 * (a + b)
        fm = c.evaluate(np.array([m]))[0, k] - x
        if (fm <= 0) == (fa <= 0):
            a, fa = m, fm
        else:
            b = m
        if b - a <= 1e-16 * (abs(lo) + abs(hi) + 1):
            break
    return 0.5 * (a + b)


def _curves(loop: list) -> list[TrimCurve]:
    return [c for c in loop if isinstance(c, TrimCurve)]


def winding(loop: list, period) -> np.ndarray:
    """(2,) whole periods between the loop's start and end (0 where not periodic; and
    for loops through a vertex edge, whose straight segments the chain adds later)."""
    curves = _curves(loop)
    if len(curves) < len(loop):
        return np.zeros(2, int)
    d = curves[-1].ends()[1] - curves[0].ends()[0]
    return np.array([round(d[k] / period[k]) if period[k] else 0 for k in range(2)])


def rotate(curves: list[TrimCurve], k: int, a: float, period: float, w: int) -> list[TrimCurve]:
    """The loop (going w = +-1 times round along k) starting at coordinate a exactly."""
    tol = 1e-12 * period
    for i, c in enumerate(curves):  # a piece that starts on the seam: no split needed
        x = c.ends()[0][k]
        m = round((x - a) / period)
        if abs(x - a - m * period) <= tol:
            out = curves[i:] + [_shift(c, k, w * period) for c in curves[:i]]
            out = [_shift(c, k, -m * period) for c in out]
            break
    else:
        for i, c in enumerate(curves):
            pts = c.evaluate(np.linspace(*c.domain, 16 * c.n + 1))[:, k]
            m = math.ceil((pts.min() - a) / period)
            x = a + m * period
            if x > pts.max():
                continue
            t = _crossing(c, k, x)
            if t is None:
                continue
            lo, hi = c.domain
            before, after = restrict(c, lo, t), restrict(c, t, hi)
            rest = curves[i + 1 :] + [_shift(c, k, w * period) for c in curves[:i]]
            out = [after] + rest + [_shift(before, k, w * period)]
            out = [_shift(c, k, -m * period) for c in out]
            break
        else:
            raise Open("it goes once round the surface but never crosses its seam")  # cannot happen
    out = [clamp(c) for c in out]
    out[0] = _set(out[0], k, a, last=False)
    out[-1] = _set(out[-1], k, a + w * period, last=True)
    return out


def close_once_round(loops: list[list[TrimCurve]], labels: list[str], period, natural, poles):
    """The loops of one face (each a list of curves, or ``"bridge"`` for a vertex edge,
    chained end to end, in the
    entity's parameters) with those that go once round joined in pairs or closed
    along the domain's edge, and every loop shifted into one window of each period.
    Returns (loops, labels)."""
    turns = [winding(c, period) for c in loops]
    for lab, w in zip(labels, turns):
        if np.count_nonzero(w) > 1 or np.abs(w).max() > 1:
            raise Open(f"{lab} goes {abs(w[0])} times round in u and {abs(w[1])} times in v")
    windows = [None, None]
    round_ = [i for i, w in enumerate(turns) if w.any()]
    out, out_labels = [], []
    if round_:
        k = int(np.flatnonzero(turns[round_[0]])[0])
        if any(not turns[i][k] for i in round_):
            raise Open(f"{labels[round_[-1]]} goes round in the other direction than {labels[round_[0]]}")
        a = float(loops[round_[0]][0].ends()[0][k])
        windows[k] = a
        j = 1 - k
        rotated = {i: rotate(loops[i], k, a, period[k], int(turns[i][k])) for i in round_}
        # pairs, in the order of their other parameter
        order = sorted(round_, key=lambda i: float(np.mean(np.concatenate([c.points[:, j] for c in rotated[i]]))))
        done = set()
        for x, y in zip(order[::2], order[1::2]):
            first, second = rotated[x], rotated[y]
            if turns[x][k] == turns[y][k]:
                second = [reverse(c) for c in second[::-1]]
            if turns[x][k] < 0:
                first, second = second, first
            # first: a -> a + P; second: a + P -> a (shifted by P where it starts at a)
            if abs(second[0].ends()[0][k] - a) < 0.5 * period[k]:
                second = [_shift(c, k, period[k]) for c in second]
            e1, s2 = first[-1].ends()[1], second[0].ends()[0]
            e2, s1 = second[-1].ends()[1], first[0].ends()[0]
            loop = first + [line_curve(e1, s2)] + second + [line_curve(e2, s1)]
            out.append(loop)
            out_labels.append(labels[x])
            done |= {x, y}
        for i in round_:
            if i in done:
                continue
            w = int(turns[i][k])
            side = w if k == 0 else -w  # the left of the direction of travel, along j
            c = rotated[i]
            along = np.concatenate([cc.points[:, j] for cc in c])
            bound = natural[2 * j + (1 if side > 0 else 0)]
            if bound is None:
                cands = [v for ax, v in poles if ax == j and (v - along.mean()) * side > 0]
                bound = min(cands, key=lambda v: abs(v - along.mean())) if cands else None
            if bound is None:
                raise Open(
                    f"{labels[i]} goes once round the surface and nothing bounds the surface on its "
                    f"{'upper' if side > 0 else 'lower'} {'uv'[j]} side (no pole or edge to close it along)"
                )
            e, s = c[-1].ends()[1], c[0].ends()[0]
            p1, p2 = e.copy(), s.copy()
            p1[j] = p2[j] = bound
            out.append(c + [line_curve(e, p1), line_curve(p1, p2), line_curve(p2, s)])
            out_labels.append(labels[i])
    keep = [i for i, w in enumerate(turns) if not w.any()]
    rest = [loops[i] for i in keep]
    # one window per periodic direction where every remaining loop fits
    for k in range(2):
        if not period[k] or not rest:
            continue
        boxes = [
            (min(c.points[:, k].min() for c in _curves(lp)), max(c.points[:, k].max() for c in _curves(lp)))
            for lp in rest
        ]
        cands = [windows[k]] if windows[k] is not None else [lo for lo, _ in boxes]
        tol = 1e-9 * period[k]
        for a in cands:
            shifts = [period[k] * math.ceil((a - lo) / period[k] - 1e-9) for lo, _ in boxes]
            if all(hi + s <= a + period[k] + tol for (_, hi), s in zip(boxes, shifts)):
                rest = [[_shift(c, k, s) if isinstance(c, TrimCurve) else c for c in lp] for lp, s in zip(rest, shifts)]
                break
    return out + rest, out_labels + [labels[i] for i in keep]

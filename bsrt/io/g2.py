"""GoTools ``.g2`` files (SINTEF GoTools / Splipy): spline surfaces, class 200.

A file is a sequence of objects, each starting with a header
``class major minor naux [naux integers]`` (e.g. ``200 1 0 0``). Everything
is whitespace-separated; line breaks carry no meaning. A class-200
SplineSurface continues::

    dim rational                 dim must be 3; rational is 0 or 1
    n_u order_u                  order = degree + 1
    n_u + order_u knots
    n_v order_v
    n_v + order_v knots
    n_u * n_v control points, u fastest: point k is P[k % n_u][k // n_u],
    each dim numbers, or dim + 1 homogeneous numbers (w x, w y, w z, w)
    when rational; the reader divides by w.

Class-100 SplineCurves are parsed (same layout, one direction) and counted
as skipped. Other classes have layouts this reader does not know: they are
skipped by scanning to the next line that starts with a header (a known
class number followed by ``1 0``) and counted.
"""

from __future__ import annotations

import os

import numpy as np

from bsrt.io import Model, Tokens, build_surface, fail, read_text

_CLASS_NAMES = {
    100: "spline curve",
    110: "curve on surface",
    120: "line",
    130: "circle",
    140: "ellipse",
    150: "bounded curve",
    160: "hyperbola",
    170: "parabola",
    200: "spline surface",
    210: "bounded surface",
    211: "surface on volume",
    220: "barycentric polynomial surface",
    230: "hierarchical B-spline surface",
    240: "composite surface",
    250: "plane",
    260: "cylinder",
    261: "surface of linear extrusion",
    270: "sphere",
    280: "cone",
    290: "torus",
    291: "surface of revolution",
    292: "disc",
    293: "LR-spline surface",
    294: "T-spline surface",
    300: "3ds object",
    310: "triangulation",
    320: "triangulation",
    330: "quad mesh",
    340: "hybrid mesh",
    350: "parametric triangulation",
    360: "VRML geometry",
    400: "point cloud",
    410: "line cloud",
    500: "triangle sets",
    510: "rectangular grid",
    700: "spline volume",
    710: "bounded volume",
}


def _skip_description(cls: int) -> str:
    name = _CLASS_NAMES.get(cls)
    return f"GoTools class {cls}" + (f" ({name})" if name else "")


def _read_knots(t: Tokens, direction: str) -> tuple[int, int, np.ndarray]:
    """n, degree and the (n + degree + 1,) knots of one direction."""
    n = t.int(f"the number of control points along {direction}", minimum=1)
    order = t.int(f"the order along {direction}", minimum=2)
    knots = t.floats(n + order, f"a knot along {direction}")
    return n, order - 1, knots


def _read_coefs(t: Tokens, count: int, dim: int, rational: bool, what: str) -> tuple[np.ndarray, np.ndarray | None]:
    """(count, dim) points and (count,) weights (None if not rational), w divided out."""
    width = dim + rational
    rows = []
    for k in range(count):
        line = t.line()
        rows.append(t.floats(width, what))
        if rational and rows[-1][dim] <= 0:
            raise fail(t.path, line, f"{what} {k + 1} has weight {rows[-1][dim]:g}; weights must be > 0")
    values = np.array(rows, dtype=np.float64).reshape(count, width)
    if not rational:
        return values, None
    w = values[:, dim]
    with np.errstate(over="ignore"):  # a tiny w overflows to inf, which make_surface reports
        return values[:, :dim] / w[:, None], w


def _is_header_line(t: Tokens) -> bool:
    """Whether the next token starts a line of the form 'known_class 1 0 naux'."""
    line = t.items[t.pos][1]
    if t.pos > 0 and t.items[t.pos - 1][1] == line:
        return False
    head = [tok for tok, ln in t.items[t.pos : t.pos + 4] if ln == line]
    return (
        len(head) == 4
        and (head[0].isascii() and head[0].isdigit())
        and int(head[0]) in _CLASS_NAMES
        and head[1:3] == ["1", "0"]
    )


def read(path: str) -> Model:
    t = Tokens(path, read_text(path))
    base = os.path.basename(path)
    surfaces, names, skipped = [], [], {}
    if t.at_end():
        raise fail(path, 1, "the file is empty")
    while not t.at_end():
        start = t.line()
        cls = t.int("a GoTools class number (e.g. 200 for a spline surface)", minimum=1)
        t.int("the major version", minimum=0)
        t.int("the minor version", minimum=0)
        naux = t.int("the number of auxiliary header values", minimum=0)
        for _ in range(naux):
            t.int("an auxiliary header value")
        if cls in (100, 200):
            dim = t.int("the dimension", minimum=1)
            rational = t.int("the rational flag (0 or 1)", minimum=0)
            if rational > 1:
                raise fail(path, t.line(), f"the rational flag must be 0 or 1, got {rational}")
        if cls == 200:
            which = f"surface {len(surfaces) + 1}"
            if dim != 3:
                raise fail(path, start, f"{which}: only 3-D surfaces are supported, this one has dimension {dim}")
            nu, p, ku = _read_knots(t, "u")
            nv, q, kv = _read_knots(t, "v")
            pts, w = _read_coefs(t, nu * nv, 3, bool(rational), "control point")
            # the file lists u fastest: reshape to (nv, nu) then swap to points[i, j]
            grid = pts.reshape(nv, nu, 3).transpose(1, 0, 2)
            weights = None if w is None else w.reshape(nv, nu).T
            surfaces.append(build_surface(path, start, which, (p, q), ku, kv, grid, weights))
            names.append(f"{base}#{len(surfaces)}")
        elif cls == 100:
            n, _, _ = _read_knots(t, "the curve")
            _read_coefs(t, n, dim, bool(rational), "curve control point")
            skipped[_skip_description(cls)] = skipped.get(_skip_description(cls), 0) + 1
        else:
            skipped[_skip_description(cls)] = skipped.get(_skip_description(cls), 0) + 1
            while not t.at_end() and not _is_header_line(t):
                t.pos += 1
    if not surfaces:
        raise fail(path, None, "the file holds no spline surfaces (class 200)")
    return Model(path, surfaces, names, skipped, [])

"""GLScene ``.nurbs`` files: one NURBS surface in VRML97 NurbsSurface style.

The file is a list of ``field value`` pairs, in any order::

    uOrder 4                     order = degree + 1 (required)
    vOrder 4                     (required)
    uDimension 13                number of control points along u (required)
    vDimension 14                (required)
    uKnot [ k, k, ... ]          uDimension + uOrder knots (required)
    vKnot [ ... ]                vDimension + vOrder knots (required)
    controlPoint [ x y z, ... ]  uDimension * vDimension points, u fastest:
                                 point k is P[k % uDimension][k // uDimension] (required)
    weight [ w, ... ]            optional, same order; all > 0
    ccw TRUE|FALSE               accepted and ignored (VRML face orientation)
    solid TRUE|FALSE             accepted and ignored
    uTessellation n, vTessellation n   accepted and ignored

Commas and whitespace both separate numbers. ``#`` starts a comment.
"""

from __future__ import annotations

import os

import numpy as np

from bsrt.io import Model, Tokens, build_surface, fail, parse_float, read_text, split_lines

_SCALARS = ("uOrder", "vOrder", "uDimension", "vDimension")
_ARRAYS = ("uKnot", "vKnot", "controlPoint", "weight")
_IGNORED = {"ccw": "bool", "solid": "bool", "uTessellation": "int", "vTessellation": "int"}


def _strip_comments(text: str) -> str:
    return "\n".join(line.split("#", 1)[0] for line in split_lines(text))


def _read_array(t: Tokens, key: str) -> tuple[int, np.ndarray]:
    """The numbers of ``[ ... ]`` after ``key``; returns (line of '[', values)."""
    token, line = t.next(f"'[' after {key}")
    if token != "[":
        raise fail(t.path, line, f"expected '[' after {key}, got {token!r}")
    values = []
    while True:
        token, at = t.next(f"a number or ']' in {key} (opened on line {line})")
        if token == "]":
            return line, np.array(values, dtype=np.float64)
        values.append(parse_float(t.path, at, token, f"a number or ']' in {key}"))


def read(path: str) -> Model:
    t = Tokens(path, _strip_comments(read_text(path)), separators=r"[\s,]+|(?=[\[\]])|(?<=[\[\]])")
    scalars: dict[str, int] = {}
    arrays: dict[str, tuple[int, np.ndarray]] = {}
    seen: dict[str, int] = {}
    if t.at_end():
        raise fail(path, 1, "the file is empty")
    while not t.at_end():
        key, line = t.next("a field name")
        if key in seen:
            raise fail(path, line, f"{key} is given twice (first on line {seen[key]})")
        seen[key] = line
        if key in _SCALARS:
            scalars[key] = t.int(f"the value of {key}", minimum=1)
        elif key in _ARRAYS:
            arrays[key] = _read_array(t, key)
        elif key in _IGNORED:
            value, at = t.next(f"the value of {key}")
            ok = value in ("TRUE", "FALSE") if _IGNORED[key] == "bool" else value.lstrip("+-").isdigit()
            if not ok:
                raise fail(path, at, f"unexpected value {value!r} for {key}")
        else:
            known = ", ".join(_SCALARS + _ARRAYS + tuple(_IGNORED))
            raise fail(path, line, f"unknown field {key!r}; the fields of a .nurbs file are {known}")
    missing = [k for k in _SCALARS + _ARRAYS[:3] if k not in seen]
    if missing:
        raise fail(path, t.last_line, f"the file ends without {', '.join(missing)}")

    nu, nv = scalars["uDimension"], scalars["vDimension"]
    p, q = scalars["uOrder"] - 1, scalars["vOrder"] - 1
    for key, n, order in (("uKnot", nu, p + 1), ("vKnot", nv, q + 1)):
        line, knots = arrays[key]
        if knots.size != n + order:
            raise fail(
                path,
                line,
                f"{key} has {knots.size} values, expected {n + order} ({key[0]}Dimension + {key[0]}Order)",
            )
    line, coords = arrays["controlPoint"]
    if coords.size != 3 * nu * nv:
        raise fail(
            path,
            line,
            f"controlPoint has {coords.size} numbers, expected {3 * nu * nv} (3 per point, {nu} x {nv} points)",
        )
    # u fastest in the file: (nv, nu, 3) -> points[i, j]
    grid = coords.reshape(nv, nu, 3).transpose(1, 0, 2)
    weights = None
    if "weight" in arrays:
        line, w = arrays["weight"]
        if w.size != nu * nv:
            raise fail(path, line, f"weight has {w.size} values, expected {nu * nv} (one per control point)")
        weights = w.reshape(nv, nu).T
    surface = build_surface(
        path, seen["uOrder"], "surface", (p, q), arrays["uKnot"][1], arrays["vKnot"][1], grid, weights
    )
    return Model(path, [surface], [os.path.basename(path)], {}, [])

"""Bezier patch text files (``.bpt``, Ryan Holmes' teapot/teacup/teaspoon format).

Layout (blank lines are ignored)::

    N                   number of patches
    du dv               per patch: its degrees along u and v (each >= 1)
    x y z               then (du + 1)(dv + 1) control points, one per line,
    ...                 listed u-row by u-row: point k is P[k // (dv + 1)][k % (dv + 1)]

Each patch becomes a Bezier surface of degree (du, dv) with knots
[0]*(d+1) + [1]*(d+1) in each direction.
"""

from __future__ import annotations

import os

import numpy as np

from bsrt.io import Model, bezier_knots, build_surface, fail, parse_float, parse_int, read_text, split_lines


def read(path: str) -> Model:
    text = read_text(path)
    all_lines = split_lines(text)
    body = [(n, s.split()) for n, s in enumerate(all_lines, start=1) if s.strip()]
    last = max(1, len(all_lines))
    pos = 0

    def take(what: str, count: int) -> tuple[int, list[str]]:
        nonlocal pos
        if pos >= len(body):
            raise fail(path, last, f"the file ends early, expected {what}")
        line, f = body[pos]
        pos += 1
        if len(f) != count:
            raise fail(path, line, f"expected {what} ({count} numbers on the line), got {len(f)}")
        return line, f

    line, (tok,) = take("the number of patches", 1)
    n_patches = parse_int(path, line, tok, "the number of patches", minimum=1)
    base = os.path.basename(path)
    surfaces, names = [], []
    for k in range(1, n_patches + 1):
        start, f = take(f"the degrees 'du dv' of patch {k} of {n_patches}", 2)
        du, dv = (parse_int(path, start, t, "a patch degree", minimum=1) for t in f)
        points = []
        for i in range((du + 1) * (dv + 1)):
            line, f = take(f"control point {i + 1} of {(du + 1) * (dv + 1)} of patch {k}", 3)
            points.append([parse_float(path, line, t, "a coordinate") for t in f])
        grid = np.array(points, dtype=np.float64).reshape(du + 1, dv + 1, 3)
        surfaces.append(
            build_surface(path, start, f"patch {k}", (du, dv), bezier_knots(du, [0, 1]), bezier_knots(dv, [0, 1]), grid)
        )
        names.append(f"{base}#{k}")
    if pos < len(body):
        line = body[pos][0]
        raise fail(path, line, f"unexpected text after the last of the {n_patches} patches (is the patch count right?)")
    return Model(path, surfaces, names, {}, [])

"""Newell/Utah indexed Bezier patches (``.bez``, the Qt3D 1.x tea-set files).

Layout (blank lines are ignored)::

    N                               number of patches
    i1,i2,...,i16[,depth]           N lines: 1-based vertex indices, 4 rows of 4,
                                    optionally a subdivision depth (ignored)
    V                               number of vertices
    x,y,z[,nx,ny,nz]                V lines: a vertex, optionally a normal (ignored)
    # option option ...             optional trailing line(s)

Each patch is bicubic Bezier: degree (3, 3), knots [0,0,0,0,1,1,1,1] both
ways; index row r (0..3) is the u row, ``points[r][c]``. Options (as in Qt3D's
reader): ``reverse-patches`` reverses each row (c -> 3 - c), turning the
clockwise teacup/teaspoon patches anti-clockwise; ``teapot-adjust`` applies
the change of coordinates described below. Unknown options give a warning.

Coordinates are used as they are in the file. The qt3d ``teapot.bez``
(and teapot-body/-handle/-spout) were already stored "adjusted":
``(x, y, z)_file = (x / 2, (z - 1.5) / 2, -y / 2)`` of Newell's values, i.e.
z-up turned into y-up, halved and centred. :func:`newell_from_qt3d` undoes
it: ``(x, y, z) = (2 x_f, -2 z_f, 2 y_f + 1.5)``.
"""

from __future__ import annotations

import os

import numpy as np

from bsrt.io import Model, build_surface, fail, parse_float, parse_int, read_text, split_lines

_KNOTS = np.array([0, 0, 0, 0, 1, 1, 1, 1], dtype=np.float64)


def newell_from_qt3d(points) -> np.ndarray:
    """Undo Qt3D's "teapot-adjust": (..., 3) file coordinates -> Newell's."""
    p = np.asarray(points, dtype=np.float64)
    return np.stack([2 * p[..., 0], -2 * p[..., 2], 2 * p[..., 1] + 1.5], axis=-1)


def qt3d_from_newell(points) -> np.ndarray:
    """Qt3D's "teapot-adjust": (..., 3) Newell coordinates -> (x/2, (z-1.5)/2, -y/2)."""
    p = np.asarray(points, dtype=np.float64)
    return np.stack([p[..., 0] / 2, (p[..., 2] - 1.5) / 2, -p[..., 1] / 2], axis=-1)


def read(path: str) -> Model:
    text = read_text(path)
    lines = [(n, s.strip()) for n, s in enumerate(split_lines(text), start=1)]
    body = [(n, s) for n, s in lines if s]
    last = lines[-1][0] if lines else 1
    pos = 0

    def take(what: str) -> tuple[int, str]:
        nonlocal pos
        if pos >= len(body):
            raise fail(path, last, f"the file ends early, expected {what}")
        pos += 1
        return body[pos - 1]

    def fields(s: str) -> list[str]:
        return [f.strip() for f in s.split(",")]

    line, s = take("the number of patches")
    n_patches = parse_int(path, line, s, "the number of patches", minimum=1)
    patches = []  # (line, (16,) 0-based indices)
    for k in range(n_patches):
        line, s = take(f"the vertex indices of patch {k + 1} of {n_patches}")
        f = fields(s)
        if len(f) not in (16, 17):
            raise fail(path, line, f"expected 16 vertex indices (and an optional subdivision depth), got {len(f)}")
        idx = [parse_int(path, line, t, "a vertex index") for t in f[:16]]
        if len(f) == 17:
            parse_int(path, line, f[16], "the subdivision depth", minimum=0)
        patches.append((line, np.array(idx) - 1))

    line, s = take("the number of vertices")
    n_verts = parse_int(path, line, s, "the number of vertices", minimum=1)
    verts = []
    for k in range(n_verts):
        line, s = take(f"vertex {k + 1} of {n_verts}")
        f = fields(s)
        if len(f) not in (3, 6):
            raise fail(path, line, f"expected a vertex x,y,z (optionally followed by a normal), got {len(f)} numbers")
        verts.append([parse_float(path, line, t, "a coordinate") for t in f][:3])
    verts = np.array(verts, dtype=np.float64)  # (V, 3)

    options, warnings = set(), []
    for line, s in body[pos:]:
        if not s.startswith("#"):
            raise fail(path, line, f"unexpected text after the {n_verts} vertices (is the vertex count right?)")
        options.update(s[1:].split())
    unknown = options - {"reverse-patches", "teapot-adjust"}
    if unknown:
        warnings.append(f"{path}: ignored unknown options {', '.join(sorted(unknown))}")
    if "teapot-adjust" in options:
        verts = qt3d_from_newell(verts)

    base = os.path.basename(path)
    surfaces, names = [], []
    for k, (line, idx) in enumerate(patches, start=1):
        bad = (idx < 0) | (idx >= n_verts)
        if bad.any():
            raise fail(path, line, f"patch {k}: vertex index {idx[bad][0] + 1} is out of range 1..{n_verts}")
        grid = verts[idx].reshape(4, 4, 3)
        if "reverse-patches" in options:
            grid = grid[:, ::-1]
        surfaces.append(build_surface(path, line, f"patch {k}", (3, 3), _KNOTS, _KNOTS, grid))
        names.append(f"{base}#{k}")
    return Model(path, surfaces, names, {}, warnings)

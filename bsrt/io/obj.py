"""Wavefront OBJ free-form surfaces (``cstype``/``deg``/``surf``/``parm``/``end``).

Supported statements::

    v x y z [w]                  control vertex; w (default 1) is the weight of a
                                 rational surface; x y z are Cartesian (not w-multiplied);
                                 "v x y z r g b" (vertex colours) is read as x y z
    cstype [rat] bezier|bspline  surface type for the following surf statements
    deg du dv                    degrees
    surf s0 s1 t0 t1 v1 v2 ...   a surface over [s0, s1] x [t0, t1]; v may be
                                 v/vt/vn; negative v counts back from the last vertex
    parm u p1 p2 ...             bspline: the u knot vector; bezier: the segment
    parm v p1 p2 ...             breaks (each inner break gets multiplicity = degree)
    end                          ends the surface body

Control vertices are listed u fastest: vertex k is P[k % nu][k // nu], with
nu = len(parm u) - du - 1 (bspline) or segments * du + 1 (bezier). A bezier
surface without ``parm`` is one segment over [s0, s1] x [t0, t1]. When
[s0, s1] x [t0, t1] is smaller than the knot domain, the surface is cut to it.

Trimming (``trim``, ``hole``, ``scrv``, ``sp``) is ignored with one warning;
``curv``/``curv2`` curves, polygonal ``p``/``l``/``f`` elements and
surfaces of other types (bmatrix, cardinal, taylor) are counted as skipped.
Other vertex data (``vt``, ``vn``, ``vp``), grouping and display statements
are ignored; unknown statements are listed in a warning.
"""

from __future__ import annotations

import os

import numpy as np

from bsrt.io import Model, bezier_knots, build_surface, cut, fail, parse_float, parse_int, read_text, split_lines

_IGNORED = {
    "vt",
    "vn",
    "vp",
    "bmat",
    "step",
    "con",
    "g",
    "o",
    "s",
    "mg",
    "usemtl",
    "mtllib",
    "lod",
    "bevel",
    "c_interp",
    "d_interp",
    "shadow_obj",
    "trace_obj",
    "ctech",
    "stech",
    "usemap",
    "maplib",
}
_TRIM = ("trim", "hole", "scrv", "sp")
_TYPES = ("bmatrix", "bezier", "bspline", "cardinal", "taylor")


def _statements(text: str):
    """(line, keyword, args) per statement; joins '\\' continuations, drops comments."""
    pending, start = [], 0
    for number, raw in enumerate(split_lines(text), start=1):
        line = raw.split("#", 1)[0].rstrip()
        if not pending:
            start = number
        if line.endswith("\\"):
            pending.append(line[:-1])
            continue
        words = " ".join(pending + [line]).split()
        pending = []
        if words:
            yield start, words[0], words[1:]
    if pending:
        words = " ".join(pending).split()
        if words:
            yield start, words[0], words[1:]


class _Body:
    """A surf ... end block being read."""

    def __init__(self, line, kind, rational, degree, ranges, refs):
        self.line, self.kind, self.rational, self.degree = line, kind, rational, degree
        self.ranges, self.refs = ranges, refs
        self.parm: dict[str, tuple[int, list[float]]] = {}
        self.trimmed = False


def read(path: str) -> Model:
    """A .obj file's free-form surfaces (cstype/deg/surf/parm/end).

    (Long: one pass over the lines, each statement a short branch sharing the
    reader's state: the current curve type, degree and vertex lists.)
    """
    text = read_text(path)
    base = os.path.basename(path)
    verts: list[list[float]] = []  # (x, y, z, w)
    cstype: tuple[bool, str] | None = None
    degree: tuple[int, ...] | None = None
    body: _Body | None = None
    curve_line = 0  # line of an open curv/curv2, or 0
    surfaces, names, skipped, unknown = [], [], {}, set()
    n_trimmed = 0
    last = 1

    def skip(what: str) -> None:
        skipped[what] = skipped.get(what, 0) + 1

    for line, key, args in _statements(text):
        last = line
        if key == "v":
            if len(args) not in (3, 4, 6):
                raise fail(path, line, f"expected 'v x y z [w]', got {len(args)} numbers")
            xyzw = [parse_float(path, line, a, "a vertex coordinate") for a in args]
            verts.append(xyzw[:3] + [xyzw[3] if len(args) == 4 else 1.0])
        elif key == "cstype":
            rat = bool(args) and args[0] == "rat"
            kind = args[1:] if rat else args
            if len(kind) != 1 or kind[0] not in _TYPES:
                raise fail(path, line, f"expected 'cstype [rat] TYPE' with TYPE one of {', '.join(_TYPES)}")
            cstype = (rat, kind[0])
        elif key == "deg":
            if len(args) not in (1, 2):
                raise fail(path, line, f"expected 'deg du [dv]', got {len(args)} values")
            degree = tuple(parse_int(path, line, a, "a degree", minimum=1) for a in args)
        elif key == "surf":
            if body is not None or curve_line:
                raise fail(
                    path,
                    line,
                    f"a new surf starts before the 'end' of the element on line {body.line if body else curve_line}",
                )
            if cstype is None:
                raise fail(path, line, "surf comes before any 'cstype' statement")
            if degree is None or len(degree) != 2:
                raise fail(path, line, "surf needs a preceding 'deg du dv' with two degrees")
            if len(args) < 5:
                raise fail(path, line, "expected 'surf s0 s1 t0 t1 v1 v2 ...'")
            s0, s1, t0, t1 = (parse_float(path, line, a, "a surface parameter") for a in args[:4])
            refs = []
            for a in args[4:]:
                k = parse_int(path, line, a.split("/", 1)[0], "a control vertex number")
                if k == 0 or -k > len(verts):
                    raise fail(path, line, f"control vertex {k} does not exist ({len(verts)} vertices so far)")
                refs.append(k - 1 if k > 0 else len(verts) + k)
            body = _Body(line, cstype[1], cstype[0], degree, ((s0, s1), (t0, t1)), refs)
        elif key in ("curv", "curv2"):
            if body is not None or curve_line:
                raise fail(
                    path,
                    line,
                    f"a new {key} starts before the 'end' of the element on line {body.line if body else curve_line}",
                )
            curve_line = line
            skip(f"OBJ curve ({key})")
        elif key == "parm":
            if body is None and not curve_line:
                raise fail(path, line, "parm outside a surf ... end body")
            if not args or args[0] not in ("u", "v"):
                raise fail(path, line, "expected 'parm u ...' or 'parm v ...'")
            if body is not None:
                body.parm[args[0]] = (line, [parse_float(path, line, a, "a parameter value") for a in args[1:]])
        elif key in _TRIM:
            if body is None and not curve_line:
                raise fail(path, line, f"{key} outside a surf ... end body")
            if body is not None:
                body.trimmed = True
        elif key == "end":
            if body is None and not curve_line:
                raise fail(path, line, "'end' without a surf or curv before it")
            if body is not None:
                if body.kind in ("bezier", "bspline"):
                    surfaces.append(_build(path, body, verts, len(surfaces) + 1))
                    names.append(f"{base}#{len(surfaces)}")
                    n_trimmed += body.trimmed
                else:
                    skip(f"OBJ {body.kind} surface (cstype {body.kind})")
            body, curve_line = None, 0
        elif key in ("p", "l", "f"):
            skip({"p": "OBJ point elements (p)", "l": "OBJ line elements (l)", "f": "OBJ polygon faces (f)"}[key])
        elif key not in _IGNORED:
            unknown.add(key)
    if body is not None or curve_line:
        raise fail(
            path,
            last,
            f"the file ends inside the element that starts on line {body.line if body else curve_line} (missing 'end')",
        )
    if not surfaces:
        raise fail(path, None, "the file holds no bezier or bspline surfaces (surf ... end)")
    warnings = []
    if n_trimmed:
        has = "surface has" if n_trimmed == 1 else "surfaces have"
        warnings.append(f"{n_trimmed} {has} trim/hole/scrv curves, which bsrt ignores: they are rendered untrimmed")
    if unknown:
        warnings.append(f"{path}: ignored unknown statements {', '.join(sorted(unknown))}")
    return Model(path, surfaces, names, skipped, warnings, untrimmed=n_trimmed)


def _parm(path: str, body: _Body, axis: int, which: str) -> tuple[list[float], int]:
    """The parm values of one direction (bezier default: [s0, s1]) and the control point count they imply."""
    d, name = body.degree[axis], "uv"[axis]
    line, values = body.parm.get(name, (body.line, None))
    if values is None:
        if body.kind == "bspline":
            raise fail(path, body.line, f"{which}: the bspline surf has no 'parm {name}' knot vector before its 'end'")
        values = list(body.ranges[axis])
    if body.kind == "bspline":
        return values, len(values) - d - 1
    if len(values) < 2:
        raise fail(path, line, f"{which}: parm {name} of a bezier surface needs at least 2 values, got {len(values)}")
    return values, (len(values) - 1) * d + 1


def _build(path: str, body: _Body, verts: list[list[float]], number: int):
    """verts: V rows [x, y, z, w]."""
    which = f"surface {number}"
    (pu, nu), (pv, nv) = _parm(path, body, 0, which), _parm(path, body, 1, which)
    p, q = body.degree
    if nu < 1 or nv < 1 or nu * nv != len(body.refs):
        raise fail(
            path,
            body.line,
            f"{which}: the surf lists {len(body.refs)} control vertices, but its parm and deg values call for "
            f"{max(nu, 0)} x {max(nv, 0)}",
        )
    if max(body.refs) >= len(verts):
        raise fail(
            path,
            body.line,
            f"{which}: control vertex {max(body.refs) + 1} does not exist ({len(verts)} vertices)",
        )
    if body.kind == "bspline":
        ku, kv = np.array(pu, dtype=np.float64), np.array(pv, dtype=np.float64)
    else:
        ku, kv = bezier_knots(p, pu), bezier_knots(q, pv)
    cv = np.array([verts[k] for k in body.refs], dtype=np.float64)
    cv = cv.reshape(nv, nu, 4).transpose(1, 0, 2)  # u fastest -> (nu, nv, 4)
    weights = cv[..., 3] if body.rational else None
    surface = build_surface(path, body.line, which, (p, q), ku, kv, cv[..., :3], weights)
    return cut(path, body.line, which, surface, body.ranges, ("s0 s1", "t0 t1"))

"""Hand-written IGES test files: a writer for valid 80-column IGES text, and the files.

Run ``python tests/data/iges/generate.py`` to rewrite the ``*.igs`` files next
to it; tests/test_iges_trim.py checks that they are up to date, and builds
broken variants from the same entity lists.

An entity is written as ``E(type, [parameters], form=0, xform=None, label="")``;
a parameter ``R(name)`` points to the entity named ``name`` (its DE number is
filled in), and ``E(..., name="x")`` names an entity. Reals are written with
a decimal point and an ``E`` exponent where needed, so the files are plain
IGES 5.3.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

HERE = Path(__file__).resolve().parent


@dataclass
class R:
    """A pointer to the entity called ``name``."""

    name: str


@dataclass
class E:
    type: int
    params: list
    form: int = 0
    xform: str | None = None  # name of a 124
    name: str | None = None
    label: str = ""
    status: str = "00000000"
    extra: dict = field(default_factory=dict)


def _real(x: float) -> str:
    text = repr(float(x)).upper()
    if "E" in text:
        mant, exp = text.split("E")
        if "." not in mant:
            mant += ".0"
        return f"{mant}E{int(exp)}"
    return text if "." in text else text + ".0"


def _token(x, des: dict) -> str:
    if isinstance(x, R):
        return str(des[x.name])
    if isinstance(x, bool):
        return str(int(x))
    if isinstance(x, int):
        return str(x)
    if isinstance(x, float):
        return _real(x)
    if isinstance(x, str):
        return f"{len(x)}H{x}"
    raise TypeError(f"cannot write {x!r}")


def iges_text(entities: list[E], filename: str = "test.igs", description: str = "bsrt test file") -> str:
    """A complete fixed-format IGES file (S, G, D, P and T sections) holding ``entities``."""
    des = {}
    for k, e in enumerate(entities):
        if e.name is not None:
            des[e.name] = 2 * k + 1

    def rec(data: str, letter: str, seq: int) -> str:
        assert len(data) <= 72, data
        return f"{data:<72}{letter}{seq:7d}"

    start = [rec(description, "S", 1)]
    gfields = [",", ";", "bsrt", filename, "bsrt tests/data/iges/generate.py", "bsrt", 32, 38, 6, 308, 15,
               filename, 1.0, 2, "MM", 1, 0.01, "20260101.000000", 1e-9, 1000.0, "bsrt", "bsrt", 11, 0,
               "20260101.000000"]
    gtext = ",".join(f"{len(x)}H{x}" if isinstance(x, str) else _token(x, des) for x in gfields) + ";"
    glob = [rec(gtext[i : i + 72], "G", k + 1) for k, i in enumerate(range(0, len(gtext), 72))]
    d, p = [], []
    for k, e in enumerate(entities):
        de = 2 * k + 1
        tokens = [str(e.type)] + [_token(x, des) for x in e.params]
        chunks, line = [], ""
        for i, t in enumerate(tokens):
            t += ";" if i == len(tokens) - 1 else ","
            if len(line) + len(t) > 64:
                chunks.append(line)
                line = ""
            line += t
        chunks.append(line)
        first = len(p) + 1
        for c in chunks:
            p.append(f"{c:<64}{de:8d}P{len(p) + 1:7d}")
        xform = des[e.xform] if e.xform else 0
        fields1 = [e.type, first, 0, 0, 0, 0, xform, 0]
        d.append("".join(f"{x:8d}" for x in fields1) + f"{e.status:>8}" + f"D{len(d) + 1:7d}")
        fields2 = [e.type, 0, 0, len(chunks), e.form, 0, 0]
        d.append("".join(f"{x:8d}" if x else " " * 8 for x in fields2[:3]) + f"{fields2[3]:8d}{fields2[4]:8d}"
                 + " " * 16 + f"{e.label[:8]:>8}" + f"{0:8d}" + f"D{len(d) + 1:7d}")
    term = [rec(f"S{len(start):7d}G{len(glob):7d}D{len(d):7d}P{len(p):7d}", "T", 1)]
    return "\n".join(start + glob + d + p + term) + "\n"


# ---------------------------------------------------------------------------
# Building blocks


def bspline_surface(name, degree, knots_u, knots_v, points, weights=None, **kw) -> E:
    """A 128 from points[i][j] (i along u)."""
    p, q = degree
    nu, nv = len(points), len(points[0])
    w = weights or [[1.0] * nv for _ in range(nu)]
    params = [nu - 1, nv - 1, p, q, 0, 0, int(weights is None), 0, 0]
    params += [float(x) for x in knots_u] + [float(x) for x in knots_v]
    params += [float(w[i][j]) for j in range(nv) for i in range(nu)]
    params += [float(c) for j in range(nv) for i in range(nu) for c in points[i][j]]
    params += [float(knots_u[p]), float(knots_u[nu]), float(knots_v[q]), float(knots_v[nv])]
    return E(128, params, name=name, **kw)


def plane_128(name, x0=-1.0, x1=3.0, y0=-2.0, y1=2.0, z=0.0, domain=(0.0, 1.0, 0.0, 1.0)) -> E:
    """A bilinear plane z = const over [x0, x1] x [y0, y1], u along x, v along y."""
    u0, u1, v0, v1 = domain
    pts = [[[x, y, z] for y in (y0, y1)] for x in (x0, x1)]
    return bspline_surface(name, (1, 1), [u0, u0, u1, u1], [v0, v0, v1, v1], pts)


def bspline_curve(name, degree, knots, points, weights=None, range_=None, **kw) -> E:
    n = len(points)
    w = weights or [1.0] * n
    pts3 = [list(pt) + [0.0] * (3 - len(pt)) for pt in points]
    planar = all(pt[2] == 0 for pt in pts3)
    params = [n - 1, degree, int(planar), 0, int(weights is None), 0]
    params += [float(k) for k in knots] + [float(x) for x in w] + [float(c) for pt in pts3 for c in pt]
    a, b = range_ or (knots[degree], knots[n])
    params += [float(a), float(b)]
    if planar:
        params += [0.0, 0.0, 1.0]
    return E(126, params, name=name, **kw)


def circle_126(name, cx, cy, r) -> E:
    """A full circle as a 126: 4 rational quadratic quarters, starting at (cx + r, cy)."""
    s = math.sqrt(0.5)
    pts, w = [], []
    for k in range(9):
        a = k * math.pi / 4
        d = 1.0 if k % 2 == 0 else 1 / s
        pts.append([cx + r * d * math.cos(a), cy + r * d * math.sin(a)])
        w.append(1.0 if k % 2 == 0 else s)
    knots = [0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 4]
    return bspline_curve(name, 2, knots, pts, w)


def line(name, p0, p1, **kw) -> E:
    a = list(p0) + [0.0] * (3 - len(p0))
    b = list(p1) + [0.0] * (3 - len(p1))
    return E(110, [float(x) for x in a + b], name=name, **kw)


def arc(name, zt, centre, start, end, **kw) -> E:
    return E(100, [float(zt), *map(float, centre), *map(float, start), *map(float, end)], name=name, **kw)


def matrix(name, r, t, **kw) -> E:
    return E(124, [float(x) for row, tt in zip(r, t) for x in (*row, tt)], name=name, **kw)


def polygon(prefix, corners) -> list[E]:
    """110 lines around the corners (closed) and the 102 joining them (named prefix)."""
    lines = [line(f"{prefix}.{k}", corners[k], corners[(k + 1) % len(corners)]) for k in range(len(corners))]
    return lines + [E(102, [len(lines)] + [R(x.name) for x in lines], name=prefix)]


def point(name, xyz) -> E:
    return E(116, [float(x) for x in xyz] + [0], name=name)


def direction(name, xyz) -> E:
    return E(123, [float(x) for x in xyz], name=name)


# ---------------------------------------------------------------------------
# The files


def plane_circle_144() -> list[E]:
    """A plane (128) trimmed (144) to a disc of radius 0.4 around (0.5, 0.5) in (u, v),
    a 126 circle, with a hole: a full 100 circle of radius 0.1 written around the
    origin and moved to (0.6, 0.45) by a 124 acting in the (u, v) plane; and a second
    plane with only that hole (N1 = 0)."""
    return [
        plane_128("S"),
        circle_126("outer", 0.5, 0.5, 0.4),
        matrix("M", [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0.6, 0.45, 0.0]),
        arc("hole", 0.0, (0.0, 0.0), (0.1, 0.0), (0.1, 0.0), xform="M"),
        E(142, [0, R("S"), R("outer"), 0, 1], name="C1"),
        E(142, [0, R("S"), R("hole"), 0, 1], name="C2"),
        E(144, [R("S"), 1, 1, R("C1"), R("C2")], name="T"),
        # a second plane, z = 1, whose 144 has no outer boundary (N1 = 0): the whole
        # surface but the same hole
        plane_128("S2", z=1.0),
        E(142, [0, R("S2"), R("hole"), 0, 1], name="C3"),
        E(144, [R("S2"), 0, 1, 0, R("C3")], name="T2"),
    ]


def plane_143() -> list[E]:
    """A 143 on the plane: the square [0.2, 0.8]^2 in (u, v) as two 141 curves: a 102 of
    three sides, and the fourth side written backwards (SENSE 2), with model-space twins."""
    corners = [(0.2, 0.2), (0.8, 0.2), (0.8, 0.8), (0.2, 0.8)]
    three = polygon("three", corners)[:3]
    return [
        plane_128("S"),
        *three,
        E(102, [3] + [R(x.name) for x in three], name="P1"),
        line("P2", (0.2, 0.2), (0.2, 0.8)),  # the fourth side, from its end to its start
        line("M1", (-1.0 + 4 * 0.2, -2.0 + 4 * 0.2, 0.0), (-1.0 + 4 * 0.2, -2.0 + 4 * 0.8, 0.0)),
        E(141, [1, 1, R("S"), 2, 0, 1, 1, R("P1"), R("M1"), 2, 1, R("P2")], name="B"),
        E(143, [1, R("S"), 1, R("B")], name="T"),
    ]


def cylinder_192() -> list[E]:
    """A 144 on a 192 cylinder (radius 2 about the z axis through (1, 2, 3), X along x):
    (u, v) in [0.5, 2.5] x [-1, 2] as a 102 of four 110 lines in (angle, height)."""
    return [
        point("L", (1.0, 2.0, 3.0)), direction("A", (0.0, 0.0, 1.0)), direction("X", (1.0, 0.0, 0.0)),
        E(192, [R("L"), R("A"), 2.0, R("X")], form=1, name="S"),
        *polygon("B", [(0.5, -1.0), (2.5, -1.0), (2.5, 2.0), (0.5, 2.0)]),
        E(142, [0, R("S"), R("B"), 0, 1], name="C"),
        E(144, [R("S"), 1, 0, R("C")], name="T"),
    ]


def cone_194() -> list[E]:
    """A 144 on a 194 cone (radius 1 at the origin, semi-angle 30 degrees, axis y, X along z),
    trimmed to angles [0, 3] and heights [0, 2], with a 126 pcurve from (0.2, 0.5) to (2.8, 1.5)
    (a general curve, approximated after mapping) closing the loop from two 110 lines."""
    return [
        point("L", (0.0, 0.0, 0.0)), direction("A", (0.0, 1.0, 0.0)), direction("X", (0.0, 0.0, 1.0)),
        E(194, [R("L"), R("A"), 1.0, 30.0, R("X")], form=1, name="S"),
        line("a", (2.8, 1.5), (0.2, 1.5)),
        line("b", (0.2, 1.5), (0.2, 0.5)),
        bspline_curve("c", 2, [0, 0, 0, 1, 1, 1], [(0.2, 0.5), (1.5, -0.5), (2.8, 1.5)]),
        E(102, [3, R("c"), R("a"), R("b")], name="B"),
        E(142, [0, R("S"), R("B"), 0, 1], name="C"),
        E(144, [R("S"), 1, 0, R("C")], name="T"),
    ]


def sphere_torus() -> list[E]:
    """A whole 196 sphere (radius 3 at (1, 1, 1)) and a whole 198 torus (radii 4 and 1 at
    the origin, axis (0, 1, 1)), drawn alone, and a 144 on a second sphere whose loop is
    written in degrees (as OCCT writes angles): longitude [30, 120], latitude [-45, 60]."""
    return [
        point("C", (1.0, 1.0, 1.0)), E(196, [R("C"), 3.0], form=0, name="S"),
        point("O", (0.0, 0.0, 0.0)), direction("Z", (0.0, 1.0, 1.0)), direction("X", (1.0, 0.0, 0.0)),
        E(198, [R("O"), R("Z"), 4.0, 1.0, R("X")], form=1, name="T"),
        direction("Z2", (0.0, 0.0, 1.0)),
        E(196, [R("O"), 2.0, R("Z2"), R("X")], form=1, name="S2"),
        *polygon("B", [(30.0, -45.0), (120.0, -45.0), (120.0, 60.0), (30.0, 60.0)]),
        E(142, [0, R("S2"), R("B"), 0, 1], name="C2"),
        E(144, [R("S2"), 1, 0, R("C2")], name="T2"),
    ]


def box_brep() -> list[E]:
    """The unit box [0, 2] x [0, 1] x [0, 1] as a 186 solid: one 514 shell of six 510 faces
    on 190 planes, 508 loops over a 504 edge list of twelve 110 lines and a 502 vertex
    list. The bottom and top faces carry parameter-space curves; the four sides carry
    none (their model-space edges are mapped into the planes exactly)."""
    v = [(x, y, z) for z in (0.0, 1.0) for y in (0.0, 1.0) for x in (0.0, 2.0)]  # vertex k: bits x, y, z
    edges = [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7)]
    out = [E(502, [8] + [float(c) for p in v for c in p], form=1, name="V")]
    for k, (a, b) in enumerate(edges):
        out.append(line(f"e{k}", v[a], v[b]))
    ep = []
    for k, (a, b) in enumerate(edges):
        ep += [R(f"e{k}"), R("V"), a + 1, R("V"), b + 1]
    out.append(E(504, [len(edges)] + ep, form=1, name="EL"))
    # faces: (name, origin, normal, refdir, vertex cycle)
    faces = [
        ("bottom", (0, 0, 0), (0, 0, -1), (1, 0, 0), [0, 2, 3, 1]),
        ("top", (0, 0, 1), (0, 0, 1), (1, 0, 0), [4, 5, 7, 6]),
        ("front", (0, 0, 0), (0, -1, 0), (1, 0, 0), [0, 1, 5, 4]),
        ("back", (0, 1, 0), (0, 1, 0), (1, 0, 0), [2, 6, 7, 3]),
        ("left", (0, 0, 0), (-1, 0, 0), (0, 1, 0), [0, 4, 6, 2]),
        ("right", (2, 0, 0), (1, 0, 0), (0, 1, 0), [1, 3, 7, 5]),
    ]
    face_refs = []
    for name, o, n, r, cyc in faces:
        out += [point(f"{name}.L", o), direction(f"{name}.N", n), direction(f"{name}.R", r)]
        out.append(E(190, [R(f"{name}.L"), R(f"{name}.N"), R(f"{name}.R")], form=1, name=f"{name}.S"))
        # (u, v) of a point on this plane: along R and along N x R
        nx = (n[1] * r[2] - n[2] * r[1], n[2] * r[0] - n[0] * r[2], n[0] * r[1] - n[1] * r[0])
        def uv(p, o=o, r=r, nx=nx):
            return tuple(sum((p[i] - o[i]) * axis[i] for i in range(3)) for axis in (r, nx))

        loop = [4]
        for k in range(4):
            a, b = cyc[k], cyc[(k + 1) % 4]
            idx = edges.index((a, b)) if (a, b) in edges else edges.index((b, a))
            forward = int((a, b) in edges)
            if name in ("bottom", "top"):
                pc = f"{name}.p{k}"  # in the direction of the edge's model-space curve
                first, second = edges[idx]
                out.append(line(pc, uv(v[first]), uv(v[second])))
                loop += [0, R("EL"), idx + 1, forward, 1, 0, R(pc)]
            else:
                loop += [0, R("EL"), idx + 1, forward, 0]
        out.append(E(508, loop, form=1, name=f"{name}.loop"))
        out.append(E(510, [R(f"{name}.S"), 1, 1, R(f"{name}.loop")], form=1, name=f"{name}.F"))
        face_refs += [R(f"{name}.F"), 1]
    out.append(E(514, [6] + face_refs, form=1, name="shell"))
    out.append(E(186, [R("shell"), 1, 0], name="solid"))
    return out


def cylinder_brep(pcurves: bool = True) -> list[E]:
    """A 510 face on a 192 cylinder (radius 1, axis z, height 0..2): one 508 loop of
    bottom circle, seam, top circle (backwards) and seam (backwards) over a 504 list of
    two 100 circles and a 110 seam. With ``pcurves``, the loop gives 110 lines in
    (angle, height); without, the model-space edges are inverted."""
    out = [
        E(502, [2, 1.0, 0.0, 0.0, 1.0, 0.0, 2.0], form=1, name="V"),
        arc("bottom", 0.0, (0.0, 0.0), (1.0, 0.0), (1.0, 0.0)),
        matrix("up", [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0.0, 0.0, 2.0]),
        arc("top", 0.0, (0.0, 0.0), (1.0, 0.0), (1.0, 0.0), xform="up"),
        line("seam", (1.0, 0.0, 0.0), (1.0, 0.0, 2.0)),
        E(504, [3, R("bottom"), R("V"), 1, R("V"), 1, R("top"), R("V"), 2, R("V"), 2,
                R("seam"), R("V"), 1, R("V"), 2], form=1, name="EL"),
        point("L", (0.0, 0.0, 0.0)), direction("A", (0.0, 0.0, 1.0)), direction("X", (1.0, 0.0, 0.0)),
        E(192, [R("L"), R("A"), 1.0, R("X")], form=1, name="S"),
    ]
    tp = 2 * math.pi
    # edge k of the list, orientation, pcurve end points
    uses = [(1, 1, (0.0, 0.0), (tp, 0.0)), (3, 1, (tp, 0.0), (tp, 2.0)), (2, 0, (tp, 2.0), (0.0, 2.0)),
            (3, 0, (0.0, 2.0), (0.0, 0.0))]
    loop = [4]
    for k, (ndx, of, a, b) in enumerate(uses):
        if pcurves:
            # written in the edge's own direction, so reversed edges get reversed pcurves
            p0, p1 = (a, b) if of else (b, a)
            out.append(line(f"p{k}", p0, p1))
            loop += [0, R("EL"), ndx, of, 1, 0, R(f"p{k}")]
        else:
            loop += [0, R("EL"), ndx, of, 0]
    out.append(E(508, loop, form=1, name="loop"))
    out.append(E(510, [R("S"), 1, 1, R("loop")], form=1, name="F"))
    return out


def surfaces_misc() -> list[E]:
    """Surfaces drawn whole: 118 ruled (two arcs: a cone frustum), 120 revolution (an arc
    about the z axis: a torus), 122 tabulated cylinder (an arc along z), 114 bicubic
    patches, a bounded 108 (a circle) and a 108 with a display size, a 190 with no
    boundary (left out) -- and a 144 on a 190 plane surface."""
    q = math.pi / 3
    out = [
        # 118: arcs of radius 1 at z = 0 and radius 2 at z = 3, both over [0, 2.5] radians
        arc("r1", 0.0, (0.0, 0.0), (1.0, 0.0), (math.cos(2.5), math.sin(2.5))),
        matrix("z3", [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0.0, 0.0, 3.0]),
        arc("r2", 0.0, (0.0, 0.0), (2.0, 0.0), (2 * math.cos(2.5), 2 * math.sin(2.5)), xform="z3"),
        E(118, [R("r1"), R("r2"), 0, 0], form=1, name="ruled"),
        # 120: a circle of radius 1 around (3, 0, 0) in the xz plane, turned about z by [0.5, 4]
        line("axis", (0.0, 0.0, -1.0), (0.0, 0.0, 1.0)),
        matrix("xz", [[1, 0, 0], [0, 0, -1], [0, 1, 0]], [3.0, 0.0, 0.0]),
        arc("gen", 0.0, (0.0, 0.0), (1.0, 0.0), (1.0, 0.0), xform="xz"),
        E(120, [R("axis"), R("gen"), 0.5, 4.0], name="rev"),
        # 122: an arc of radius 1.5 around (10, 0) swept up to z = 4
        arc("dir", 0.0, (10.0, 0.0), (11.5, 0.0), (10.0 + 1.5 * math.cos(q), 1.5 * math.sin(q))),
        E(122, [R("dir"), 11.5, 0.0, 4.0], name="tab"),
        # 114: two u by one v segments of x = u, y = v, z = u^2 v + 1 (u in [0, 2], v in [0, 1])
        E(114, _bicubic_params(), name="spl"),
        # 108 bounded by a circle of radius 2 around (0, 0, 5) in the plane z = 5
        matrix("z5", [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0.0, 0.0, 5.0]),
        arc("disc", 0.0, (0.0, 0.0), (2.0, 0.0), (2.0, 0.0), xform="z5"),
        E(108, [0.0, 0.0, 1.0, 5.0, R("disc"), 0.0, 0.0, 5.0, 0.0], form=1, name="bounded"),
        # 108 unbounded with a display size 3 around (1, 1, -2)
        E(108, [0.0, 0.0, 2.0, -4.0, 0, 1.0, 1.0, -2.0, 3.0], form=0, name="shown"),
        point("L", (0.0, 0.0, 7.0)), direction("N", (0.0, 0.0, 1.0)), direction("X", (1.0, 0.0, 0.0)),
        E(190, [R("L"), R("N"), R("X")], form=1, name="lonely"),
        E(190, [R("L"), R("N"), R("X")], form=1, name="P"),
        *polygon("B", [(-1.0, -1.0), (1.0, -1.0), (0.0, 1.0)]),
        E(142, [0, R("P"), R("B"), 0, 1], name="C"),
        E(144, [R("P"), 1, 0, R("C")], name="T"),
    ]
    return out


def _bicubic_params() -> list:
    """114 parameters for x = u, y = v, z = u^2 v + 1 on TU = 0, 1, 2 and TV = 0, 1."""
    params = [3, 1, 2, 1, 0.0, 1.0, 2.0, 0.0, 1.0]
    for i, u0 in enumerate((0.0, 1.0)):
        # in s = u - u0, t = v: x = u0 + s, y = t, z = 1 + (u0 + s)^2 t = 1 + u0^2 t + 2 u0 s t + s^2 t
        x = [0.0] * 16
        y = [0.0] * 16
        z = [0.0] * 16
        x[0], x[1] = u0, 1.0
        y[4] = 1.0
        z[0], z[4], z[5], z[6] = 1.0, u0 * u0, 2 * u0, 1.0  # index a + 4 b for s^a t^b
        params += x + y + z
        params += [0.0] * 48  # the arbitrary values after the row
    params += [0.0] * 48 * 2
    return params


def curves() -> list[E]:
    """One of each curve entity, drawn by nothing (the tests read them one by one)."""
    rot = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # 90 degrees about z
    return [
        matrix("M", rot, [1.0, 2.0, 3.0]),
        arc("arc", 0.5, (1.0, 1.0), (3.0, 1.0), (1.0, 3.0), xform="M"),  # a quarter, radius 2
        line("l1", (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)),
        line("l2", (1.0, 0.0, 0.0), (1.0, 2.0, 0.0)),
        E(102, [2, R("l1"), R("l2")], name="comp"),
        # ellipse x^2/4 + y^2 = 1 (A = 1, C = 4, F = -4) from (2, 0) to (0, 1), z = 1
        E(104, [1.0, 0.0, 4.0, 0.0, 0.0, -4.0, 1.0, 2.0, 0.0, 0.0, 1.0], form=1, name="ellipse"),
        # hyperbola x^2/4 - y^2 = 1 (A = 1, C = -4, F = -4) from (2 cosh -1, 1 sinh -1) to (2 cosh 1, sinh 1)
        E(104, [1.0, 0.0, -4.0, 0.0, 0.0, -4.0, 0.0, 2 * math.cosh(-1.0), math.sinh(-1.0), 2 * math.cosh(1.0),
                math.sinh(1.0)], form=2, name="hyperbola"),
        # parabola y = x^2 / 4, i.e. A = 1, E = -4: from (-2, 1) to (4, 4)
        E(104, [1.0, 0.0, 0.0, 0.0, -4.0, 0.0, 0.0, -2.0, 1.0, 4.0, 4.0], form=3, name="parabola"),
        E(106, [1, 4, 2.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0], form=63, name="copious"),
        E(106, [2, 3, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 2.0, 0.0, 3.0], form=12, name="copious3"),
        # 112: two cubic segments of (t, t^2, t^3) on T = -1, 0, 2
        E(112, [3, 2, 3, 2, -1.0, 0.0, 2.0,
                -1.0, 1.0, 0.0, 0.0, 1.0, -2.0, 1.0, 0.0, -1.0, 3.0, -3.0, 1.0,
                0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
                2.0, 1.0, 0.0, 0.0, 4.0, 4.0, 1.0, 0.0, 8.0, 12.0, 6.0, 1.0], name="spline"),
        # 126: a cubic restricted to [0.25, 0.75] of its [0, 1] domain
        bspline_curve("bspline", 3, [0, 0, 0, 0, 1, 1, 1, 1], [(0, 0, 0), (1, 2, 0), (2, -1, 1), (3, 0, 0)],
                      range_=(0.25, 0.75)),
    ]


def cylinder_128_model_space() -> list[E]:
    """A 144 on a 128 quarter cylinder (radius 1 about z, angle 0..pi/2, z in [0, 2]: rational
    quadratic in u, linear in v) whose 142 gives only the model-space loop: the arcs at z =
    0.5 and 1.5 over angles [0.2, 1.2] (100s lifted by 124s; both counterclockwise, so the
    second runs against the loop) and the two vertical lines between them."""
    s = math.sqrt(0.5)
    pts = [[[x, y, z] for z in (0.0, 2.0)] for x, y in ((1.0, 0.0), (1.0, 1.0), (0.0, 1.0))]
    w = [[1.0, 1.0], [s, s], [1.0, 1.0]]
    a, b = 0.2, 1.2
    ca, sa, cb, sb = math.cos(a), math.sin(a), math.cos(b), math.sin(b)
    return [
        bspline_surface("S", (2, 1), [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], pts, w),
        matrix("z05", [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0.0, 0.0, 0.5]),
        matrix("z15", [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0.0, 0.0, 1.5]),
        arc("low", 0.0, (0.0, 0.0), (ca, sa), (cb, sb), xform="z05"),
        line("up", (cb, sb, 0.5), (cb, sb, 1.5)),
        arc("high", 0.0, (0.0, 0.0), (ca, sa), (cb, sb), xform="z15"),
        line("down", (ca, sa, 1.5), (ca, sa, 0.5)),
        E(102, [4, R("low"), R("up"), R("high"), R("down")], name="B"),
        E(142, [0, R("S"), 0, R("B"), 2], name="C"),
        E(144, [R("S"), 1, 0, R("C")], name="T"),
    ]


def sphere_cap_brep() -> list[E]:
    """A 510 face on a 196 sphere (radius 1 at the origin): the cap above latitude 0.5 rad.
    Its 508 loop: the latitude circle, the seam up to the pole, the pole as a vertex edge
    (TYPE 1) without a parameter-space curve, and the seam down again."""
    tp, pole, lat = 2 * math.pi, math.pi / 2, 0.5
    r, z = math.cos(lat), math.sin(lat)
    return [
        E(502, [2, r, 0.0, z, 0.0, 0.0, 1.0], form=1, name="V"),
        matrix("lift", [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0.0, 0.0, z]),
        arc("circle", 0.0, (0.0, 0.0), (r, 0.0), (r, 0.0), xform="lift"),
        matrix("xz", [[1, 0, 0], [0, 0, -1], [0, 1, 0]], [0.0, 0.0, 0.0]),
        arc("seam", 0.0, (0.0, 0.0), (r, z), (0.0, 1.0), xform="xz"),
        E(504, [2, R("circle"), R("V"), 1, R("V"), 1, R("seam"), R("V"), 1, R("V"), 2], form=1, name="EL"),
        line("p0", (0.0, lat), (tp, lat)),
        line("p1", (tp, lat), (tp, pole)),
        line("p3", (0.0, lat), (0.0, pole)),
        E(508, [4, 0, R("EL"), 1, 1, 1, 0, R("p0"), 0, R("EL"), 2, 1, 1, 0, R("p1"), 1, R("V"), 2, 1, 0,
                0, R("EL"), 2, 0, 1, 0, R("p3")], form=1, name="loop"),
        point("O", (0.0, 0.0, 0.0)), direction("Z", (0.0, 0.0, 1.0)), direction("X", (1.0, 0.0, 0.0)),
        E(196, [R("O"), 1.0, R("Z"), R("X")], form=1, name="S"),
        E(510, [R("S"), 1, 1, R("loop")], form=1, name="F"),
    ]


# ---------------------------------------------------------------------------
# Periodic surfaces: loops across the seam, loops once round


def revolution_seam_144() -> list[E]:
    """A 144 on a 120 turned a full turn (the line x = 2, y = 0, z = 3 u about the z axis:
    a cylinder of radius 2, v the angle) whose outer boundary crosses the seam, written in
    [0, 2 pi] as CAD systems do: u in [0.2, 0.8] (z in [0.6, 2.4]), angles from 5.5 round
    through 2 pi to 0.7, six 110 lines (two pairs meet only across the seam)."""
    tp = 2 * math.pi
    corners = [((0.2, 5.5), (0.2, tp)), ((0.2, 0.0), (0.2, 0.7)), ((0.2, 0.7), (0.8, 0.7)),
               ((0.8, 0.7), (0.8, 0.0)), ((0.8, tp), (0.8, 5.5)), ((0.8, 5.5), (0.2, 5.5))]
    lines = [line(f"b{k}", a, b) for k, (a, b) in enumerate(corners)]
    return [
        line("axis", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
        line("gen", (2.0, 0.0, 0.0), (2.0, 0.0, 3.0)),
        E(120, [R("axis"), R("gen"), 0.0, tp], name="S"),
        *lines,
        E(102, [len(lines)] + [R(x.name) for x in lines], name="B"),
        E(142, [0, R("S"), R("B"), 0, 1], name="C"),
        E(144, [R("S"), 1, 0, R("C")], name="T"),
    ]


def cylinder_band_brep() -> list[E]:
    """A 510 face on a 192 cylinder (radius 1, axis z) with two 508 loops and no seam edge:
    the circle z = 0 (pcurve from angle 1 to 1 + 2 pi) and the circle z = 2 (pcurve from
    angle 3 back to 3 - 2 pi). The face is the whole band 0 <= z <= 2."""
    tp = 2 * math.pi
    return [
        E(502, [2, math.cos(1.0), math.sin(1.0), 0.0, math.cos(3.0), math.sin(3.0), 2.0], form=1, name="V"),
        arc("bottom", 0.0, (0.0, 0.0), (math.cos(1.0), math.sin(1.0)), (math.cos(1.0), math.sin(1.0))),
        matrix("up", [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [0.0, 0.0, 2.0]),
        arc("top", 0.0, (0.0, 0.0), (math.cos(3.0), math.sin(3.0)), (math.cos(3.0), math.sin(3.0)), xform="up"),
        E(504, [2, R("bottom"), R("V"), 1, R("V"), 1, R("top"), R("V"), 2, R("V"), 2], form=1, name="EL"),
        line("p0", (1.0, 0.0), (1.0 + tp, 0.0)),
        line("p1", (3.0 - tp, 2.0), (3.0, 2.0)),  # the edge's direction; used backwards
        E(508, [1, 0, R("EL"), 1, 1, 1, 0, R("p0")], form=1, name="L0"),
        E(508, [1, 0, R("EL"), 2, 0, 1, 0, R("p1")], form=1, name="L1"),
        point("L", (0.0, 0.0, 0.0)), direction("A", (0.0, 0.0, 1.0)), direction("X", (1.0, 0.0, 0.0)),
        E(192, [R("L"), R("A"), 1.0, R("X")], form=1, name="S"),
        E(510, [R("S"), 2, 1, R("L0"), R("L1")], form=1, name="F"),
    ]


def once_round_144() -> list[E]:
    """144s whose outer boundary is one circle once round, closed along the domain's edge
    on its left: on a 196 sphere (radius 1 at the origin) the latitude 0.5 from longitude 0.3
    eastwards (the cap above it, to the pole); on a 194 cone (radius 1 at z = 0, semi-angle
    30 degrees, axis z) the circle z = 1 westwards (the cone from there down to its apex,
    z = -sqrt(3))."""
    tp = 2 * math.pi
    return [
        point("O", (0.0, 0.0, 0.0)), direction("Z", (0.0, 0.0, 1.0)), direction("X", (1.0, 0.0, 0.0)),
        E(196, [R("O"), 1.0, R("Z"), R("X")], form=1, name="S"),
        line("lat", (0.3, 0.5), (0.3 + tp, 0.5)),
        E(142, [0, R("S"), R("lat"), 0, 1], name="C"),
        E(144, [R("S"), 1, 0, R("C")], name="T"),
        E(194, [R("O"), R("Z"), 1.0, 30.0, R("X")], form=1, name="K"),
        line("ring", (tp, 1.0), (0.0, 1.0)),
        E(142, [0, R("K"), R("ring"), 0, 1], name="C2"),
        E(144, [R("K"), 1, 0, R("C2")], name="T2"),
    ]


def closed_128_seam_144() -> list[E]:
    """A 144 on a closed 128: the whole cylinder of radius 1 about z, z = v in [0, 2], u in
    [0, 4] a rational quadratic circle starting at (1, 0, z) (u = 0.5 is 45 degrees), whose
    outer boundary crosses the seam u = 0 = 4: u in [3.5, 4] and [0, 0.5] (angles -45 to 45
    degrees), v in [0.5, 1.5]."""
    s = math.sqrt(0.5)
    ring = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1), (1, 0)]
    pts = [[[x, y, z] for z in (0.0, 2.0)] for x, y in ring]
    w = [[1.0 if k % 2 == 0 else s] * 2 for k in range(9)]
    corners = [((3.5, 0.5), (4.0, 0.5)), ((0.0, 0.5), (0.5, 0.5)), ((0.5, 0.5), (0.5, 1.5)),
               ((0.5, 1.5), (0.0, 1.5)), ((4.0, 1.5), (3.5, 1.5)), ((3.5, 1.5), (3.5, 0.5))]
    lines = [line(f"b{k}", a, b) for k, (a, b) in enumerate(corners)]
    return [
        bspline_surface("S", (2, 1), [0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 4], [0, 0, 2, 2], pts, w),
        *lines,
        E(102, [len(lines)] + [R(x.name) for x in lines], name="B"),
        E(142, [0, R("S"), R("B"), 0, 1], name="C"),
        E(144, [R("S"), 1, 0, R("C")], name="T"),
    ]


def subfigures() -> list[E]:
    """Subfigures: a 308 definition "D1" holding a 144 (the plane x = u, y = v, z = 0 over
    [0, 1]^2, trimmed to the square [0.2, 0.8]^2 in (u, v)), a 308 "D2" holding a 408 of D1
    (scale 2, translation (0, 0, 1)), and two 408s placing them: one of D2 translated by
    (10, 0, 0) then turned 90 degrees about z by its 124, one of D1 with scale 3 and
    translation (0, 5, 0); and a 308 nobody places. Drawn: the square twice, at the corners
    (0.6, 5.6, 0)..(2.4, 7.4, 0) and (-0.4, 10.4, 1)..(-1.6, 11.6, 1); nothing at z = 0 in
    [0.2, 0.8]^2 (the definition itself)."""
    return [
        plane_128("S", 0.0, 1.0, 0.0, 1.0),
        *polygon("B", [(0.2, 0.2), (0.8, 0.2), (0.8, 0.8), (0.2, 0.8)]),
        E(142, [1, R("S"), R("B"), 0, 1], name="C"),
        E(144, [R("S"), 1, 0, R("C")], name="T", status="00010000"),
        E(308, [0, "plate", 1, R("T")], name="D1", status="00010200"),
        E(408, [R("D1"), 0.0, 0.0, 1.0, 2.0], name="I1", status="00010000"),
        E(308, [1, "pair", 1, R("I1")], name="D2", status="00010200"),
        matrix("Rz", [[0, -1, 0], [1, 0, 0], [0, 0, 1]], [0.0, 0.0, 0.0]),
        E(408, [R("D2"), 10.0, 0.0, 0.0, 1.0], name="A", xform="Rz"),
        E(408, [R("D1"), 0.0, 5.0, 0.0, 3.0], name="Bi"),
        E(308, [0, "unused", 1, R("T")], name="D3", status="00010200"),
    ]


def sphere_120_shifted_pcurve() -> list[E]:
    """A 144 on a 120 sphere (radius 1 at the origin: the arc from (0, 1) to (0, -1) through
    (-1, 0), turned a full turn about the line from the origin to (0, -1, 0)), whose 142 has
    both curves. The model-space loop: the meridian from the pole (0, -1, 0) up to (1, 0, 0),
    the equator through (0, 0, 1) to (-1, 0, 0) (two 100 arcs turned into the plane y = 0 by a
    124), the meridian back down: the quarter of the sphere with y <= 0 and z >= 0 (area pi).
    The parameter-space loop, as bug22566_test_Bad.igs writes it, counts the arc's parameter
    from 0 at its start (IGES counts it from the start angle, pi / 2): its corners (pi, pi),
    (pi / 2, pi), (pi / 2, 2 pi), (pi, 2 pi) are the right ones in the writer's parameters
    (there u = pi / 2 is the equator, pi the pole, where the loop closes) but in IGES's u = pi is
    the equator and pi / 2 the other pole: the loop does not close."""
    h = math.pi / 2
    return [
        line("axis", (0.0, 0.0, 0.0), (0.0, -1.0, 0.0)),
        arc("gen", 0.0, (0.0, 0.0), (0.0, 1.0), (0.0, -1.0)),
        E(120, [R("axis"), R("gen"), 0.0, 2 * math.pi], name="S"),
        matrix("Rx", [[1, 0, 0], [0, 0, -1], [0, 1, 0]], [0.0, 0.0, 0.0]),
        arc("m1", 0.0, (0.0, 0.0), (0.0, -1.0), (1.0, 0.0)),
        arc("e1", 0.0, (0.0, 0.0), (1.0, 0.0), (0.0, 1.0), xform="Rx"),
        arc("e2", 0.0, (0.0, 0.0), (0.0, 1.0), (-1.0, 0.0), xform="Rx"),
        arc("m2", 0.0, (0.0, 0.0), (-1.0, 0.0), (0.0, -1.0)),
        E(102, [4, R("m1"), R("e1"), R("e2"), R("m2")], name="model"),
        *polygon("uv", [(2 * h, 2 * h), (h, 2 * h), (h, 3 * h), (h, 4 * h), (2 * h, 4 * h)])[:4],
        E(102, [4, R("uv.0"), R("uv.1"), R("uv.2"), R("uv.3")], name="uv"),
        E(142, [1, R("S"), R("uv"), R("model"), 1], name="C"),
        E(144, [R("S"), 1, 0, R("C")], name="T"),
    ]


FILES = {
    "plane_circle_144.igs": plane_circle_144,
    "plane_143.igs": plane_143,
    "cylinder_192.igs": cylinder_192,
    "cone_194.igs": cone_194,
    "sphere_torus.igs": sphere_torus,
    "box_brep.igs": box_brep,
    "cylinder_brep.igs": cylinder_brep,
    "cylinder_brep_inverted.igs": lambda: cylinder_brep(pcurves=False),
    "surfaces_misc.igs": surfaces_misc,
    "cylinder_128_model_space.igs": cylinder_128_model_space,
    "sphere_cap_brep.igs": sphere_cap_brep,
    "curves.igs": curves,
    "revolution_seam_144.igs": revolution_seam_144,
    "cylinder_band_brep.igs": cylinder_band_brep,
    "once_round_144.igs": once_round_144,
    "closed_128_seam_144.igs": closed_128_seam_144,
    "subfigures.igs": subfigures,
    "sphere_120_shifted_pcurve.igs": sphere_120_shifted_pcurve,
}


def main() -> None:
    for name, build in FILES.items():
        (HERE / name).write_text(iges_text(build(), name))


if __name__ == "__main__":
    main()

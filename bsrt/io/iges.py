"""IGES 5.x fixed-format ASCII files: entity 128 (rational B-spline surface).

Every record is 80 columns: data in 1-72, the section letter (S, G, D, P, T)
in 73 and a sequence number in 74-80. The reader checks the section order,
the sequence numbers and the Terminate record's counts, so truncated or
spliced files are reported rather than half-read.

* G: only the parameter and record delimiters are used (default ``,`` ``;``).
* D: two records per entity; the directory entry number (DE) of an entity is
  the sequence number of its first record. Fields used: entity type, P
  pointer and P line count, transformation matrix pointer (field 7), form,
  label (columns 57-64 of the 2nd record) and subscript.
* P: columns 1-64 hold the parameters, 65-72 the DE back-pointer.

Entity 128 parameters: K1 K2 M1 M2 PROP1..5, the K1+M1+2 u knots and K2+M2+2
v knots, the (K1+1)(K2+1) weights, the control points (x y z each) and
U0 U1 V0 V1. Weights and points are listed u fastest (index (i, j) is at
position i + (K1+1) j); degree = M. When [U0, U1] x [V0, V1] is smaller than
the knot domain the surface is cut to it.

Entity 124 (transformation matrix) parameters are R11 R12 R13 T1 R21 ...
T3: x' = R x + T. A 128 whose field 7 points to a 124 is mapped by it; a 124
may itself point to another 124, which is applied after it.

Trimming is not supported: 128 surfaces referenced by 141 (boundary), 143
(bounded surface) or 144 (trimmed surface) entities are drawn untrimmed and
one warning says how many. Every other entity, except the 124s applied to a
128, is counted in ``Model.skipped`` by type. Compressed (C) and binary
IGES are refused.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

import numpy as np

from . import Model, build_surface, cut, fail, read_text, split_lines

_ENTITY_NAMES = {
    100: "circular arc", 102: "composite curve", 104: "conic arc", 106: "copious data",
    108: "plane", 110: "line", 112: "parametric spline curve", 114: "parametric spline surface",
    116: "point", 118: "ruled surface", 120: "surface of revolution", 122: "tabulated cylinder",
    123: "direction", 124: "transformation matrix", 125: "flash", 126: "B-spline curve",
    128: "B-spline surface", 130: "offset curve", 140: "offset surface", 141: "boundary",
    142: "curve on a parametric surface", 143: "bounded surface", 144: "trimmed surface",
    186: "manifold solid B-rep object", 190: "plane surface", 192: "cylindrical surface",
    194: "conical surface", 196: "spherical surface", 198: "toroidal surface",
    202: "angular dimension", 206: "diameter dimension", 210: "general label", 212: "general note",
    214: "leader", 216: "linear dimension", 222: "radius dimension", 228: "general symbol",
    230: "sectioned area", 308: "subfigure definition", 314: "color definition",
    402: "associativity instance", 404: "drawing", 406: "property", 408: "singular subfigure instance",
    410: "view", 502: "vertex list", 504: "edge list", 508: "loop", 510: "face", 514: "shell",
}
# entity type -> index (0-based, after the type) of its surface pointer
_TRIMMING = {141: 2, 143: 1, 144: 0}
_SECTIONS = "SGDPT"
_HOLLERITH = re.compile(r"\s*(\d+)H")
_REAL = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[EeDd][+-]?\d+)?")


@dataclass
class _Entity:
    """One directory entry."""

    de: int  # its DE number (sequence number of its first D record)
    line: int  # file line of its first D record
    type: int
    pstart: int  # first P line (1-based within the P section)
    xform: int  # DE of its transformation matrix, 0 for none
    pcount: int  # number of P lines
    label: str


class _Params:
    """The parameters of one entity: tokens with their file lines, read in order."""

    def __init__(self, path: str, entity: _Entity, tokens: list[tuple[str, int]]):
        self.path, self.entity, self.tokens, self.pos = path, entity, tokens, 1

    def fail(self, line: int, message: str):
        return fail(self.path, line, f"entity {self.entity.type} (DE {self.entity.de}): {message}")

    def _next(self, what: str) -> tuple[str, int]:
        if self.pos >= len(self.tokens):
            raise self.fail(self.tokens[-1][1], f"its {len(self.tokens) - 1} parameters end before {what}")
        self.pos += 1
        return self.tokens[self.pos - 1]

    def real(self, what: str) -> float:
        token, line = self._next(what)
        if token == "":
            return 0.0
        if _REAL.fullmatch(token) is None:
            raise self.fail(line, f"expected {what} (a number), got {token!r}")
        value = float(token.replace("D", "E").replace("d", "e"))
        if not np.isfinite(value):
            raise self.fail(line, f"{what} {token} is too large")
        return value

    def reals(self, count: int, what: str) -> np.ndarray:
        return np.array([self.real(what) for _ in range(count)], dtype=np.float64)

    def int(self, what: str, minimum: int | None = None) -> int:
        token, line = self._next(what)
        if token == "":
            value = 0
        elif re.fullmatch(r"[+-]?\d+", token):
            value = int(token)
        else:
            raise self.fail(line, f"expected {what} (a whole number), got {token!r}")
        if minimum is not None and value < minimum:
            raise self.fail(line, f"{what} must be at least {minimum}, got {value}")
        return value

    @property
    def line(self) -> int:
        return self.tokens[min(self.pos, len(self.tokens) - 1)][1]


def _records(path: str, text: str) -> dict[str, list[tuple[int, str]]]:
    """Section letter -> [(file line, 80-column record)], with order, sequence and T checks."""
    sections: dict[str, list[tuple[int, str]]] = {s: [] for s in _SECTIONS}
    current = 0
    lines = split_lines(text)
    if not lines:
        raise fail(path, 1, "the file is empty")
    for number, raw in enumerate(lines, start=1):
        if not raw.strip() and number == len(lines):
            continue
        if len(raw) > 80:
            raise fail(path, number, f"the record is {len(raw)} characters long; IGES records are 80 columns")
        rec = raw.ljust(80)
        letter = rec[72]
        if letter == "C" and number == 1:
            raise fail(
                path, number,
                "compressed ASCII IGES is not supported; save the file in the fixed 80-column format",
            )
        if letter not in _SECTIONS:
            raise fail(
                path, number,
                f"column 73 holds {letter!r}, not a section letter S, G, D, P or T (is this an 80-column IGES file?)",
            )
        k = _SECTIONS.index(letter)
        if k < current:
            raise fail(path, number, f"a {letter} record comes after the {_SECTIONS[current]} section")
        current = k
        seq = rec[73:80].strip()
        expected = len(sections[letter]) + 1
        if not seq.isdigit() or int(seq) != expected:
            raise fail(path, number, f"expected sequence number {letter}{expected} in columns 74-80, got {seq!r}")
        sections[letter].append((number, rec))
    if not sections["T"]:
        raise fail(path, len(lines), "the file has no Terminate (T) record; it may be truncated")
    tline, trec = sections["T"][0]
    for k, letter in enumerate("SGDP"):
        field = trec[8 * k : 8 * k + 8]
        count = field[1:].strip()
        if field[0] != letter or not count.isdigit():
            raise fail(
                path, tline,
                f"the Terminate record should give the {letter} line "
                f"count in columns {8 * k + 1}-{8 * k + 8}, got {field!r}",
            )
        if int(count) != len(sections[letter]):
            raise fail(
                path, tline,
                f"the Terminate record says {int(count)} {letter} lines but the "
                f"file has {len(sections[letter])} (truncated or edited file?)",
            )
    return sections


def _delimiters(path: str, records: list[tuple[int, str]]) -> tuple[str, str]:
    """The parameter and record delimiters declared at the start of the G section."""
    text = "".join(rec[:72] for _, rec in records)
    line = records[0][0] if records else 1
    delims, pos = [], 0
    for default in (",", ";"):
        # each field is either empty (the default) or a Hollerith string 1Hx
        if text.startswith("1H", pos) and len(text) > pos + 2:
            delims.append(text[pos + 2])
            pos += 3
        else:
            delims.append(default)
        pos += 1  # the parameter delimiter after the field
    p, r = delims
    if p == r or p in " 0123456789" or r in " 0123456789":
        raise fail(path, line, f"the Global section declares unusable delimiters {p!r} and {r!r}")
    return p, r


def _directory(path: str, records: list[tuple[int, str]], n_params: int) -> dict[int, _Entity]:
    """DE number -> entity, checking each pair of D records."""
    if len(records) % 2:
        raise fail(path, records[-1][0], f"the Directory section has {len(records)} lines, not an even number")
    out = {}
    for k in range(0, len(records), 2):
        (line, a), (line2, b) = records[k], records[k + 1]

        def field(rec, i, at, what, minimum=None):
            s = rec[8 * i : 8 * i + 8].strip()
            if not s:
                return 0
            if not re.fullmatch(r"[+-]?\d+", s):
                raise fail(
                    path, at,
                    f"directory entry {k + 1}: {what} (columns {8 * i + 1}-{8 * i + 8}) is {s!r}, not a whole number",
                )
            value = int(s)
            if minimum is not None and value < minimum:
                raise fail(path, at, f"directory entry {k + 1}: {what} must be at least {minimum}, got {value}")
            return value

        etype = field(a, 0, line, "the entity type", 0)
        if field(b, 0, line2, "the entity type", 0) != etype:
            raise fail(path, line2, f"directory entry {k + 1}: the two records give different entity types")
        pstart = field(a, 1, line, "the parameter data pointer", 0)
        xform = field(a, 6, line, "the transformation matrix pointer", 0)
        pcount = field(b, 3, line2, "the parameter line count", 0)
        subscript = b[64:72].strip()
        label = b[56:64].strip() + (f"({subscript})" if subscript.lstrip("0") else "")
        if etype != 0 and (pstart < 1 or pcount < 1 or pstart + pcount - 1 > n_params):
            raise fail(
                path, line,
                f"directory entry {k + 1}: its parameter lines "
                f"{pstart}..{pstart + pcount - 1} are not within the {n_params} P lines",
            )
        out[k + 1] = _Entity(k + 1, line, etype, pstart, xform, pcount, label)
    return out


def _parameters(path: str, entity: _Entity, precs: list[tuple[int, str]], delims: tuple[str, str]) -> _Params:
    """Tokenise an entity's P records up to the record delimiter (Hollerith strings kept whole)."""
    pdelim, rdelim = delims
    chars, where = [], []
    for line, rec in precs[entity.pstart - 1 : entity.pstart - 1 + entity.pcount]:
        back = rec[64:72].strip()
        if not back.isdigit() or int(back) != entity.de:
            raise fail(
                path, line,
                f"this P line points back to DE {back!r}, but DE {entity.de} says its parameters are here",
            )
        chars.append(rec[:64])
        where.extend([line] * 64)
    text = "".join(chars)
    delimiter = re.compile("[" + re.escape(pdelim + rdelim) + "]")
    tokens, i = [], 0
    while True:
        j = i
        m = _HOLLERITH.match(text, i)
        if m:  # a Hollerith string nHxxxx may contain delimiters: skip its n characters
            j = m.end() + int(m.group(1))
        d = delimiter.search(text, j)
        if d is None:
            raise fail(
                path, where[-1],
                f"entity {entity.type} (DE {entity.de}): the parameters have no record delimiter {rdelim!r}",
            )
        tokens.append((text[i : d.start()].strip(), where[min(i, len(where) - 1)]))
        if d.group() == rdelim:
            break
        i = d.end()
    if tokens[0][0] != str(entity.type):
        raise fail(
            path, tokens[0][1],
            f"the parameters of DE {entity.de} start with "
            f"{tokens[0][0]!r}, but the directory says entity {entity.type}",
        )
    return _Params(path, entity, tokens)


def _matrix(path: str, entities, de: int, cache: dict, records, delims, chain=()) -> np.ndarray:
    """4x4 world-from-local matrix of the 124 at DE ``de`` including the 124s it points to."""
    if de in cache:
        return cache[de]
    entity = entities.get(de)
    if entity is None or entity.type != 124:
        what = "nothing" if entity is None else f"entity {entity.type}"
        first = entities[chain[-1]] if chain else None
        raise fail(
            path, first.line if first else 1,
            f"transformation matrix pointer {de} points to {what}, not to an entity 124",
        )
    if de in chain:
        raise fail(
            path, entity.line,
            f"the transformation matrices at DE {', '.join(map(str, chain))} refer to each other in a loop",
        )
    params = _parameters(path, entity, records, delims)
    m = np.eye(4)
    m[:3, :] = params.reals(12, "a matrix entry").reshape(3, 4)
    if entity.xform:
        m = _matrix(path, entities, entity.xform, cache, records, delims, chain + (de,)) @ m
    cache[de] = m
    return m


def _surface(path: str, entity: _Entity, params: _Params):
    which = f"entity 128 (DE {entity.de})"
    k1, k2 = params.int("K1", 0), params.int("K2", 0)
    m1, m2 = params.int("M1", 0), params.int("M2", 0)
    for name in ("PROP1", "PROP2", "PROP3", "PROP4", "PROP5"):
        params.int(name)
    ku = params.reals(k1 + m1 + 2, "a u knot")
    kv = params.reals(k2 + m2 + 2, "a v knot")
    nu, nv = k1 + 1, k2 + 1
    w = params.reals(nu * nv, "a weight").reshape(nv, nu).T
    pts = params.reals(3 * nu * nv, "a control point coordinate").reshape(nv, nu, 3).transpose(1, 0, 2)
    u0, u1, v0, v1 = (params.real(name) for name in ("U0", "U1", "V0", "V1"))
    if np.any(w <= 0):
        raise fail(path, entity.line, f"{which}: every weight must be > 0, found {w.min():g}")
    surface = build_surface(path, entity.line, which, (m1, m2), ku, kv, pts, w)
    return cut(path, entity.line, which, surface, ((u0, u1), (v0, v1)), ("U0 U1", "V0 V1"))


def read(path: str) -> Model:
    sections = _records(path, read_text(path))
    delims = _delimiters(path, sections["G"])
    precs = sections["P"]
    entities = _directory(path, sections["D"], len(precs))
    base = os.path.basename(path)

    surfaces, names, skipped = [], [], {}
    cache: dict[int, np.ndarray] = {}
    used_matrices: set[int] = set()
    trimmed: set[int] = set()
    trim_types: set[int] = set()
    for entity in entities.values():
        if entity.type == 128:
            surface = _surface(path, entity, _parameters(path, entity, precs, delims))
            if entity.xform:
                m = _matrix(path, entities, entity.xform, cache, precs, delims, (entity.de,))
                with np.errstate(all="ignore"):  # huge entries give non-finite points, reported below
                    moved = surface.transformed(m).points
                surface = build_surface(
                    path, entity.line, f"entity 128 (DE {entity.de}) after its transformation matrix",
                    surface.degree, surface.knots_u, surface.knots_v, moved, surface.weights,
                )
                de = entity.xform
                while de and de not in used_matrices:
                    used_matrices.add(de)
                    de = entities[de].xform
            surfaces.append(surface)
            names.append(f"{base}#D{entity.de}" + (f" {entity.label}" if entity.label else ""))
        elif entity.type in _TRIMMING:
            params = _parameters(path, entity, precs, delims)
            for _ in range(_TRIMMING[entity.type]):
                params.int("a parameter")
            ptr = params.int("the surface pointer")
            target = entities.get(ptr)
            if target is None:
                raise params.fail(params.line, f"it points to surface DE {ptr}, which does not exist")
            if target.type == 128:
                trimmed.add(ptr)
                trim_types.add(entity.type)
    for entity in entities.values():
        if entity.type not in (0, 128) and entity.de not in used_matrices:
            key = f"IGES entity {entity.type} ({_ENTITY_NAMES.get(entity.type, 'unknown type')})"
            skipped[key] = skipped.get(key, 0) + 1
    if not surfaces:
        found = ", ".join(f"{n} x {k}" for k, n in skipped.items()) or "no entities"
        raise fail(path, None, f"the file holds no B-spline surfaces (entity 128), only {found}")
    warnings = []
    if trimmed:
        kinds = "/".join(str(t) for t in sorted(trim_types))
        are = "surface is" if len(trimmed) == 1 else "surfaces are"
        warnings.append(
            f"{len(trimmed)} {are} referenced by trimming entities ({kinds}) and rendered untrimmed"
        )
    return Model(path, surfaces, names, skipped, warnings, untrimmed=len(trimmed))

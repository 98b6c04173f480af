"""IGES records: the file's sections, directory entries and parameters (:class:`IgesFile`).

The package docstring (bsrt/io/iges/__init__.py) describes the format and what is drawn.
"""

from __future__ import annotations

import operator
import os
import re

import numpy as np
import numpy.ma  # np.unique imports it on its first call: ~20 ms of the first load otherwise

from bsrt.io import fail, read_text, split_lines
from bsrt.io.iges.params import _HOLLERITH, _INT, _REAL, _Entity, _parameters, _Params

ENTITY_NAMES = {
    100: "circular arc",
    102: "composite curve",
    104: "conic arc",
    106: "copious data",
    108: "plane",
    110: "line",
    112: "parametric spline curve",
    114: "parametric spline surface",
    116: "point",
    118: "ruled surface",
    120: "surface of revolution",
    122: "tabulated cylinder",
    123: "direction",
    124: "transformation matrix",
    125: "flash",
    126: "B-spline curve",
    128: "B-spline surface",
    130: "offset curve",
    140: "offset surface",
    141: "boundary",
    142: "curve on a parametric surface",
    143: "bounded surface",
    144: "trimmed surface",
    186: "manifold solid B-rep object",
    190: "plane surface",
    192: "cylindrical surface",
    194: "conical surface",
    196: "spherical surface",
    198: "toroidal surface",
    202: "angular dimension",
    206: "diameter dimension",
    210: "general label",
    212: "general note",
    214: "leader",
    216: "linear dimension",
    222: "radius dimension",
    228: "general symbol",
    230: "sectioned area",
    308: "subfigure definition",
    314: "color definition",
    402: "associativity instance",
    404: "drawing",
    406: "property",
    408: "singular subfigure instance",
    410: "view",
    502: "vertex list",
    504: "edge list",
    508: "loop",
    510: "face",
    514: "shell",
}
_SECTIONS = "SGDPT"


def _records(path: str, text: str) -> dict[str, list[tuple[int, str]]]:
    """Section letter -> [(file line, 80-column record)], with order, sequence and T checks."""
    lines = split_lines(text)
    if not lines:
        raise fail(path, 1, "the file is empty")
    sections = _records_fast(lines)
    if sections is None:  # something is wrong: the record by record checks say what
        sections = _records_checked(path, lines)
    return _terminate(path, lines, sections)


_ORDER = re.compile("S*G*D*P*T*")
_SEQ = re.compile(" *[0-9]+")  # one sequence field (7 columns, not blank)


def _records_fast(lines: list[str]) -> dict[str, list[tuple[int, str]]] | None:
    """The sections of a well-formed file, checked in bulk (None at the first doubt)."""
    if lines and not lines[-1].strip():
        lines = lines[:-1]
    if not lines or max(map(len, lines)) > 80:
        return None
    recs = [raw if len(raw) == 80 else raw.ljust(80) for raw in lines]
    letters = "".join(map(operator.itemgetter(72), recs))
    if letters[:1] == "C" or _ORDER.fullmatch(letters) is None:
        return None
    sections: dict[str, list[tuple[int, str]]] = {}
    start = 0
    for letter in _SECTIONS:
        end = len(letters) - len(letters[start:].lstrip(letter))
        seqs = list(map(operator.itemgetter(slice(73, 80)), recs[start:end]))
        if seqs != list(map("{:7d}".format, range(1, end - start + 1))) and (  # not blank-padded: zero-padded?
            not all(_SEQ.fullmatch(q) for q in seqs) or list(map(int, seqs)) != list(range(1, end - start + 1))
        ):
            return None
        sections[letter] = list(zip(range(start + 1, end + 1), recs[start:end]))
        start = end
    return sections


def _records_checked(path: str, lines: list[str]) -> dict[str, list[tuple[int, str]]]:
    """The record by record checks, raising InputError at the first bad record."""
    sections: dict[str, list[tuple[int, str]]] = {s: [] for s in _SECTIONS}
    current = 0
    for number, raw in enumerate(lines, start=1):
        if not raw.strip() and number == len(lines):
            continue
        if len(raw) > 80:
            raise fail(path, number, f"the record is {len(raw)} characters long; IGES records are 80 columns")
        rec = raw.ljust(80)
        letter = rec[72]
        if letter == "C" and number == 1:
            raise fail(
                path,
                number,
                "compressed ASCII IGES is not supported; save the file in the fixed 80-column format",
            )
        if letter not in _SECTIONS:
            raise fail(
                path,
                number,
                f"column 73 holds {letter!r}, not a section letter S, G, D, P or T (is this an 80-column IGES file?)",
            )
        k = _SECTIONS.index(letter)
        if k < current:
            raise fail(path, number, f"a {letter} record comes after the {_SECTIONS[current]} section")
        current = k
        seq = rec[73:80].strip()
        expected = len(sections[letter]) + 1
        if not (seq.isascii() and seq.isdigit()) or int(seq) != expected:
            raise fail(path, number, f"expected sequence number {letter}{expected} in columns 74-80, got {seq!r}")
        sections[letter].append((number, rec))
    return sections


def _terminate(path: str, lines: list[str], sections) -> dict[str, list[tuple[int, str]]]:
    """The sections, once the Terminate record's counts agree with them."""
    if not sections["T"]:
        raise fail(path, len(lines), "the file has no Terminate (T) record; it may be truncated")
    tline, trec = sections["T"][0]
    for k, letter in enumerate("SGDP"):
        field = trec[8 * k : 8 * k + 8]
        count = field[1:].strip()
        if field[0] != letter or not (count.isascii() and count.isdigit()):
            raise fail(
                path,
                tline,
                f"the Terminate record should give the {letter} line "
                f"count in columns {8 * k + 1}-{8 * k + 8}, got {field!r}",
            )
        if int(count) != len(sections[letter]):
            raise fail(
                path,
                tline,
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


def _resolution(records: list[tuple[int, str]], delims: tuple[str, str]) -> float:
    """Global parameter 19, the minimum user-intended resolution (model units); 0 if absent or unreadable."""
    text = "".join(rec[:72] for _, rec in records)
    pdelim, rdelim = delims
    fields, i = [], 0
    while i < len(text) and len(fields) < 19:
        m = _HOLLERITH.match(text, i)
        j = m.end() + int(m.group(1)) if m else i
        ends = [k for k in (text.find(pdelim, j), text.find(rdelim, j)) if k >= 0]
        if not ends:
            break
        end = min(ends)
        fields.append(text[i:end].strip())
        if text[end] == rdelim:
            break
        i = end + 1
    if len(fields) < 19 or _REAL.fullmatch(fields[18]) is None:
        return 0.0
    value = float(fields[18].replace("D", "E").replace("d", "e"))
    return value if np.isfinite(value) and value > 0 else 0.0


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
            if s.isdigit() and s.isascii():
                return int(s)
            if not _INT.fullmatch(s):
                raise fail(
                    path,
                    at,
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
        form = field(b, 4, line2, "the form number")
        subscript = b[64:72].strip()
        label = b[56:64].strip() + (f"({subscript})" if subscript.lstrip("0") else "")
        if etype != 0 and (pstart < 1 or pcount < 1 or pstart + pcount - 1 > n_params):
            raise fail(
                path,
                line,
                f"directory entry {k + 1}: its parameter lines "
                f"{pstart}..{pstart + pcount - 1} are not within the {n_params} P lines",
            )
        blanked = a[64:66] == "01"
        dependent = a[66:68] in ("01", "11")
        out[k + 1] = _Entity(k + 1, line, etype, pstart, xform, pcount, label, form, blanked, dependent)
    return out


class IgesFile:
    """A checked IGES file: its directory, parameters on demand, matrices, and what was used.

    resolution: the Global section's minimum user-intended resolution (model units, 0 if none).
    used: DEs of the entities that took part in something drawn.
    cache: memo of converted entities, keyed by (kind, DE).
    """

    def __init__(self, path: str):
        self.path = path
        self.base = os.path.basename(path)
        sections = _records(path, read_text(path))
        self.delims = _delimiters(path, sections["G"])
        self.resolution = _resolution(sections["G"], self.delims)
        self.precs = sections["P"]
        self.entities = _directory(path, sections["D"], len(self.precs))
        self._tokens: dict[int, tuple] = {}  # DE -> (texts, where) of _Params
        self._matrices: dict[int, np.ndarray] = {}
        self.used: set[int] = set()
        self.cache: dict = {}
        self.open_loops: list = []  # InputErrors of the trimmed surfaces left out for open loops

    def params(self, entity: _Entity) -> _Params:
        """A fresh reader of the entity's parameters (tokenised once)."""
        tokens = self._tokens.get(entity.de)
        if tokens is None:
            p = _parameters(self.path, entity, self.precs, self.delims)
            tokens = self._tokens[entity.de] = (p.texts, p.where)
        return _Params(self.path, entity, *tokens)

    def get(self, ref: _Params, de: int, what: str, types=None) -> _Entity:
        """The entity at DE ``de``, which ``ref`` (just read) names as ``what``.

        types: allowed entity types (None: any). Errors point at ``ref``'s parameter.
        """
        target = self.entities.get(de)
        if target is None or target.type == 0:
            raise ref.fail(f"its {what} points to DE {de}, which does not exist")
        if types is not None and target.type not in types:
            allowed = " or ".join(f"{t} ({ENTITY_NAMES.get(t, 'unknown')})" for t in sorted(types))
            raise ref.fail(
                f"its {what} points to DE {de}, an entity {target.type} "
                f"({ENTITY_NAMES.get(target.type, 'unknown type')}), not an entity {allowed}"
            )
        return target

    def fail(self, entity: _Entity, message: str, line: int | None = None):
        return fail(
            self.path, entity.line if line is None else line, f"entity {entity.type} (DE {entity.de}): {message}"
        )

    def matrix(self, entity: _Entity) -> np.ndarray | None:
        """4x4 model-from-definition matrix of the entity's own 124 chain (None if it has none)."""
        if not entity.xform:
            return None
        return self._matrix(entity.xform, (entity.de,))

    def _matrix(self, de: int, chain: tuple) -> np.ndarray:
        """The composed matrix of the 124 chain starting at ``de`` (iterative: a legal chain
        of any length resolves without recursion). chain: the DEs that led here."""
        walk: list[_Entity] = []  # the 124s not yet composed, outermost last
        seen = set(chain)
        first = self.entities[chain[-1]]
        while de not in self._matrices:
            entity = self.entities.get(de)
            if entity is None or entity.type != 124:
                what = "nothing" if entity is None else f"entity {entity.type}"
                raise fail(
                    self.path,
                    first.line,
                    f"entity {first.type} (DE {first.de}): its "
                    f"transformation matrix pointer {de} points to {what}, not to an entity 124",
                )
            if de in seen:
                des = ", ".join(map(str, list(chain[1:]) + [e.de for e in walk]))
                raise fail(
                    self.path, entity.line, f"the transformation matrices at DE {des} refer to each other in a loop"
                )
            seen.add(de)
            walk.append(entity)
            if not entity.xform:
                break
            first, de = entity, entity.xform
        outer = self._matrices.get(de) if walk and walk[-1].de != de else None
        if not walk:
            return self._matrices[de]
        for entity in reversed(walk):
            m = np.eye(4)
            m[:3, :] = self.params(entity).reals(12, "a matrix entry").reshape(3, 4)
            if outer is not None:
                with np.errstate(all="ignore"):
                    m = outer @ m
                if not np.all(np.isfinite(m)):
                    raise fail(
                        self.path,
                        entity.line,
                        f"entity 124 (DE {entity.de}): the composed transformation "
                        "matrix overflows (entries beyond 1e308)",
                    )
            self.used.add(entity.de)
            self._matrices[entity.de] = m
            outer = m
        return outer

    def name(self, entity: _Entity) -> str:
        return f"{self.base}#D{entity.de}" + (f" {entity.label}" if entity.label else "")


def entity_name(etype: int) -> str:
    return f"IGES entity {etype} ({ENTITY_NAMES.get(etype, 'unknown type')})"

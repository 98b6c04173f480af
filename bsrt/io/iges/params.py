"""IGES parameter data: one entity's parameters as typed tokens, with their file lines (:class:`_Params`)."""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from bsrt import validate
from bsrt.io import fail

_HOLLERITH = re.compile(r"\s*([0-9]+)H")
_REAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[EeDd][+-]?[0-9]+)?")
_NUMBER_CHARACTERS = re.compile(r"[0-9+\-.EeDd\n]*")  # tokens joined by newlines
_INT = re.compile(r"[+-]?[0-9]+")


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
    form: int = 0  # form number (2nd record, columns 33-40)
    blanked: bool = False  # blank status 01 (status number, columns 65-66): hidden in the sending system
    dependent: bool = False  # subordinate switch 01 or 11 (columns 67-68): physically part of another entity


class _Params:
    """The parameters of one entity: tokens (stripped text) read in order, and ``where``: the
    file line of token i at ``where[i]``."""

    def __init__(self, path: str, entity: _Entity, texts: list[str], where):
        self.path, self.entity, self.texts, self.where, self.pos = path, entity, texts, where, 1

    def fail(self, message: str, line: int | None = None):
        """InputError 'path:line: entity T (DE n): message' at the parameter read last."""
        return fail(
            self.path,
            self.line if line is None else line,
            f"entity {self.entity.type} (DE {self.entity.de}): {message}",
        )

    def _next(self, what: str) -> str:
        if self.pos >= len(self.texts):
            raise self.fail(f"its {len(self.texts) - 1} parameters end before {what}")
        self.pos += 1
        return self.texts[self.pos - 1]

    def real(self, what: str) -> float:
        token = self._next(what)
        if token == "":
            return 0.0
        if _REAL.fullmatch(token) is None:
            raise self.fail(f"expected {what} (a number), got {token!r}")
        value = float(token.replace("D", "E").replace("d", "e"))
        if not abs(value) <= validate.MAX_COORDINATE:
            raise self.fail(
                f"{what} {token} is too large (beyond +-{validate.MAX_COORDINATE:g}, see Limits in docs/scene-format.md)"
            )
        return value

    def reals(self, count: int, what: str) -> np.ndarray:
        """(count,) float64; one by one (with the first bad one reported) only if the fast path fails.

        The fast path: the tokens' characters are digits, signs, points and exponent letters
        (``_NUMBER_CHARACTERS``), and Python's float (NumPy's conversion of text) reads every
        one: of such strings it reads exactly those ``_REAL`` matches."""
        chunk = self.texts[self.pos : self.pos + count]
        text = "\n".join(chunk)
        if len(chunk) == count and _NUMBER_CHARACTERS.fullmatch(text):
            if "D" in text or "d" in text:
                chunk = text.replace("D", "E").replace("d", "e").split("\n")
            try:
                values = np.array(chunk, dtype=np.float64)
            except ValueError:  # an empty token, or one like "1.2.3"
                values = None
            if values is not None and np.all(np.abs(values) <= validate.MAX_COORDINATE):
                self.pos += count
                return values
        return np.array([self.real(what) for _ in range(count)], dtype=np.float64)

    def int(self, what: str, minimum: int | None = None) -> int:
        token = self._next(what)
        if token.isdigit() and token.isascii():
            value = int(token)
        elif token == "":
            value = 0
        elif _INT.fullmatch(token):
            value = int(token)
        else:
            raise self.fail(f"expected {what} (a whole number), got {token!r}")
        if minimum is not None and value < minimum:
            raise self.fail(f"{what} must be at least {minimum}, got {value}")
        return value

    def pointer(self, what: str) -> int:
        """A DE pointer (0: none). Negative pointers are read as their absolute value."""
        return abs(self.int(what))

    def skip(self, count: int, what: str) -> None:
        for _ in range(count):
            self._next(what)

    @property
    def line(self) -> int:
        """File line of the parameter read last (of the first one before any is read)."""
        return self.where[max(1, min(self.pos - 1, len(self.texts) - 1))]


def _parameters(path: str, entity: _Entity, precs: list[tuple[int, str]], delims: tuple[str, str]) -> _Params:
    """Tokenise an entity's P records up to the record delimiter (Hollerith strings kept whole)."""
    pdelim, rdelim = delims
    chunk = precs[entity.pstart - 1 : entity.pstart - 1 + entity.pcount]
    de8 = f"{entity.de:8d}"
    for line, rec in chunk:
        if rec[64:72] == de8:
            continue
        back = rec[64:72].strip()
        if not (back.isascii() and back.isdigit()) or int(back) != entity.de:
            raise fail(
                path,
                line,
                f"this P line points back to DE {back!r}, but DE {entity.de} says its parameters are here",
            )
    lines = [line for line, _ in chunk]
    text = "".join([rec[:64] for _, rec in chunk])
    end = text.find(rdelim)
    if end >= 0 and "H" not in text[:end] and "h" not in text[:end]:  # no Hollerith string: split at once
        parts = text[:end].split(pdelim)
        texts = list(map(str.strip, parts))  # (no Python code per token: a B-spline has thousands)
        where = _Lines(lines, parts)
    else:
        tokens = _hollerith_tokens(path, entity, text, [x for x in lines for _ in range(64)], delims)
        texts, where = [t for t, _ in tokens], [line for _, line in tokens]
    if texts[0] != str(entity.type):
        raise fail(
            path,
            where[0],
            f"the parameters of DE {entity.de} start with {texts[0]!r}, but the directory says entity {entity.type}",
        )
    return _Params(path, entity, texts, where)


class _Lines:
    """The file line of each token of records ``lines`` (their file lines) joined and split into
    ``parts``: where[i], worked out at the first question (only errors ask)."""

    def __init__(self, lines: list[int], parts: list[str]):
        self.lines, self.parts, self.at = lines, parts, None

    def __getitem__(self, i: int) -> int:
        if self.at is None:
            if len(self.lines) == 1:
                self.at = [self.lines[0]] * len(self.parts)
            else:  # each token's first column in the joined records, in records: its file line
                sizes = np.fromiter(map(len, self.parts), dtype=np.int64, count=len(self.parts)) + 1
                self.at = np.asarray(self.lines)[(np.cumsum(sizes) - sizes) // 64].tolist()
        return self.at[i]


def _hollerith_tokens(path, entity, text, where, delims) -> list[tuple[str, int]]:
    """Tokens of parameters that may hold Hollerith strings nHxxxx (whose characters may be delimiters)."""
    pdelim, rdelim = delims
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
                path,
                where[-1],
                f"entity {entity.type} (DE {entity.de}): the parameters have no record delimiter {rdelim!r}",
            )
        tokens.append((text[i : d.start()].strip(), where[min(i, len(where) - 1)]))
        if d.group() == rdelim:
            return tokens
        i = d.end()

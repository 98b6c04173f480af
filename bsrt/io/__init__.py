"""Model-file importers: one module per format, one entry point.

``load_model(path)`` reads a file of B-spline / Bezier surfaces and returns a
:class:`Model`. Every reader validates each surface with
:func:`bsrt.geometry.bspline.make_surface` and raises :class:`bsrt.errors.InputError`
for any malformed input, with one sentence of the form
``FILE:LINE: what is wrong``.

The formats are declared once, in :data:`bsrt.io.formats.READERS`
(:data:`FORMATS`: extension -> the format read by default). STEP and BREP
(and IGES with format "occt") are read through OpenCASCADE, the optional
extra ``bsrt[cad]`` (:mod:`bsrt.io.occt`); without it they give one message.
The slow formats go through the converted-model cache (:mod:`bsrt.io.cache`):
a second load of an unchanged file unpickles the first one's Model.

This module also holds the small helpers the readers share: decoding the file
(:func:`read_text`), strict number parsing, error formatting, building a
surface with a located error (:func:`build_surface`) and cutting a surface to
a sub-rectangle of its domain (:func:`cut`; :func:`bsrt.geometry.bspline.restrict`).
"""

from __future__ import annotations

import importlib
import os
import re
import time
from collections.abc import Callable

import numpy as np

from bsrt import validate
from bsrt.errors import InputError
from bsrt.files import check_input_file
from bsrt.geometry.bspline import BSplineSurface, make_surface, restrict  # noqa: F401  (restrict: the readers')
from bsrt.io.formats import BY_EXTENSION as FORMATS
from bsrt.io.formats import READERS
from bsrt.io.model import LoadRecord, Model

__all__ = ["FORMATS", "READERS", "LoadRecord", "Model", "load_model"]


def load_model(
    path, format: str = "auto", *, cache: bool = True, progress: Callable[[int, int], None] | None = None
) -> Model:
    """Read a model file.

    format: "auto" (by extension, case-insensitive) or a format name of
    :data:`bsrt.io.formats.READERS` (e.g. "occt": STEP, BREP or IGES through
    OpenCASCADE, by extension).
    cache: use the converted-model cache (:mod:`bsrt.io.cache`) for the
    formats it holds (``Reader.cached``); False reads the file and writes
    nothing. progress: called as ``progress(done, total)`` while the
    OpenCASCADE reader converts faces (not on a cached load, nor by the
    other readers). ``Model.load`` tells how long it took and whether the
    cache served it.
    """
    start = time.perf_counter()
    path = os.fspath(path)
    format = _resolve_format(path, format)
    faces: list[tuple[int, int]] = []

    def count(done: int, total: int) -> None:
        faces[:] = [(int(done), int(total))]
        if progress is not None:
            progress(done, total)

    from bsrt.io import cache as model_cache

    if cache and READERS[format].cached:
        _check_reader(path, format)  # a missing extra or a FIFO: the same message as without the cache
        model, cached = model_cache.load(path, format, lambda: _read(path, format, count))
    else:
        model, cached = _read(path, format, count), False
    model.load = LoadRecord(path, format, time.perf_counter() - start, cached, faces[0] if faces else None)
    return model


def _resolve_format(path: str, format: str) -> str:
    """The format name for ``format`` ("auto": by the extension); InputError for an unknown one."""
    format = format.lower()
    if format == "auto":
        ext = os.path.splitext(path)[1].lower()
        if ext in FORMATS:
            return FORMATS[ext]
        exts = ", ".join(sorted(FORMATS))
        raise InputError(f"{path}: unknown model file extension {ext or '(none)'!r}; supported extensions are {exts}")
    if format not in READERS:
        raise InputError(f"{path}: unknown model format {format!r}; supported formats are {', '.join(sorted(READERS))}")
    return format


def _check_reader(path: str, format: str) -> None:
    """InputError if the reader cannot run (the OpenCASCADE extra missing) or the path is not a
    regular file: checked before the cache is asked, so its answer never hides them."""
    if READERS[format].module == "occt":
        from bsrt.io import occt

        kind = occt.kind_of(path, format)  # format "occt" with another extension: its own message first
        if not occt.available():
            raise InputError(occt.needs_message(path, kind))
    _regular(path)


def _read(path: str, format: str, progress) -> Model:
    """The model, read by its reader (no cache); the new model's ``load`` is None."""
    module = READERS[format].module
    if module == "occt":
        from bsrt.io import occt

        if not occt.available():
            raise InputError(occt.needs_message(path, occt.kind_of(path, format)))
        return checked(occt.read(path, format, progress=progress))
    reader = importlib.import_module(f".{module}", __name__)
    return checked(reader.read(_regular(path)))


def _regular(path: str) -> str:
    """path, if it is a regular file: a FIFO or a device would block or never end."""
    return os.fspath(check_input_file(path, "model file"))


def checked(model: Model) -> Model:
    """The model, each surface within the limits (degree, coordinates, weights), else an InputError
    naming the file and the surface."""
    for surface, name in zip(model.surfaces, model.names):
        try:
            validate.surface(surface)
        except InputError as e:
            raise fail(model.path, None, f"surface {name}: {e}") from None
    return model


# ---------------------------------------------------------------------------
# Helpers shared by the readers


def fail(path: str, line: int | None, message: str) -> InputError:
    """An InputError ``path:line: message`` (``path: message`` if line is None)."""
    where = path if line is None else f"{path}:{line}"
    return InputError(f"{where}: {message}")


def read_text(path: str) -> str:
    """The file's text; InputError if it is missing, binary or not UTF-8."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise fail(path, None, f"cannot read the file ({e.strerror or e})") from None
    if b"\0" in data:
        line = data.count(b"\n", 0, data.index(b"\0")) + 1
        raise fail(path, line, "this is a binary file, not a text model file")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise fail(path, line, f"byte {e.start} is not valid UTF-8 text") from None


def split_lines(text: str) -> list[str]:
    """The lines of a text split at \\n, \\r\\n or \\r only (unlike str.splitlines, which
    also splits at form feeds and other separators and would shift line numbers)."""
    lines = re.split(r"\r\n|\r|\n", text)
    return lines[:-1] if lines and lines[-1] == "" else lines


_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"[+-]?[0-9]+")


def parse_float(path: str, line: int, token: str, what: str) -> float:
    """A finite decimal number (no nan/inf, no Python-only spellings)."""
    if _NUMBER.fullmatch(token) is None:
        raise fail(path, line, f"expected {what} (a number), got {token!r}")
    value = float(token)
    if not abs(value) <= validate.MAX_COORDINATE:
        raise fail(
            path,
            line,
            f"{what} {token} is too large (beyond +-{validate.MAX_COORDINATE:g}, see Limits in docs/scene-format.md)",
        )
    return value


def parse_int(path: str, line: int, token: str, what: str, minimum: int | None = None) -> int:
    """A whole number, optionally at least ``minimum``."""
    if _INTEGER.fullmatch(token) is None:
        raise fail(path, line, f"expected {what} (a whole number), got {token!r}")
    value = int(token)
    if minimum is not None and value < minimum:
        raise fail(path, line, f"{what} must be at least {minimum}, got {value}")
    return value


class Tokens:
    """Whitespace-separated tokens of a text, each with its 1-based line number."""

    def __init__(self, path: str, text: str, separators: str = r"\s+"):
        self.path = path
        self.items: list[tuple[str, int]] = []
        lines = split_lines(text)
        for number, line in enumerate(lines, start=1):
            self.items.extend((t, number) for t in re.split(separators, line) if t)
        self.pos = 0
        self.last_line = max(1, len(lines))

    def at_end(self) -> bool:
        return self.pos >= len(self.items)

    def peek(self) -> tuple[str, int] | None:
        return None if self.at_end() else self.items[self.pos]

    def next(self, what: str) -> tuple[str, int]:
        if self.at_end():
            raise fail(self.path, self.last_line, f"the file ends early, expected {what}")
        item = self.items[self.pos]
        self.pos += 1
        return item

    def int(self, what: str, minimum: int | None = None) -> int:
        token, line = self.next(what)
        return parse_int(self.path, line, token, what, minimum)

    def float(self, what: str) -> float:
        token, line = self.next(what)
        return parse_float(self.path, line, token, what)

    def floats(self, count: int, what: str) -> np.ndarray:
        """(count,) float64; reads one token at a time so a huge count just hits the end."""
        return np.array([self.float(what) for _ in range(count)], dtype=np.float64)

    def line(self) -> int:
        """Line of the next token (or the last line at the end)."""
        return self.last_line if self.at_end() else self.items[self.pos][1]


def build_surface(path: str, line: int, which: str, degree, knots_u, knots_v, points, weights=None):
    """make_surface, with its InputError prefixed by ``path:line: which: ``."""
    try:
        return make_surface(degree, knots_u, knots_v, points, weights)
    except InputError as e:
        raise fail(path, line, f"{which}: {e}") from None


def bezier_knots(degree: int, breaks) -> np.ndarray:
    """Knots of a piecewise Bezier spline: end breaks repeated degree+1 times, inner ones degree times."""
    breaks = list(breaks)
    knots = [breaks[0]] * (degree + 1)
    for b in breaks[1:-1]:
        knots += [b] * degree
    return np.array(knots + [breaks[-1]] * (degree + 1), dtype=np.float64)


def cut(path: str, line: int, which: str, surface: BSplineSurface, ranges, labels) -> BSplineSurface:
    """Check that each (a, b) in ``ranges`` lies in the knot domain and cut the surface to them.

    labels: how the file names the two ranges, e.g. ("U0 U1", "V0 V1").
    Ends within 1e-9 (relative) of the domain's ends count as equal to them.
    """
    clean = []
    for (a, b), (lo, hi), label in zip(ranges, (surface.domain_u, surface.domain_v), labels):
        tol = 1e-9 * max(1.0, abs(lo), abs(hi))
        if not (lo - tol <= a < b <= hi + tol):
            raise fail(
                path,
                line,
                f"{which}: the range {label} = [{a:g}, {b:g}] is not inside the knot domain [{lo:g}, {hi:g}]",
            )
        a, b = min(max(a, lo), hi), max(min(b, hi), lo)  # ends within tol past the domain: on its ends
        a, b = (lo if a - lo <= tol else a, hi if hi - b <= tol else b)
        if not a < b:
            raise fail(
                path,
                line,
                f"{which}: the range {label} covers no part of the knot domain [{lo:g}, {hi:g}] "
                f"(it lies within {tol:g} of its end)",
            )
        clean.append((a, b))
    try:
        return restrict(surface, *clean)
    except InputError as e:
        raise fail(path, line, f"{which}: {e}") from None

"""The model-file readers: one declaration each.

:data:`READERS` is the registry: a format's name (``--format``, an
``[[import]]``'s ``format``), the extensions it is chosen by, what it
reads, the module that reads it (``read(path)``; the OpenCASCADE package
``read(path, format, progress)``), the optional extra it needs and whether
the converted-model cache holds it. ``--help``, ``--format``'s choices,
the scene format's checks, batches' file search, the unknown-extension
error, ``bsrt doctor`` and the docs' table (:func:`markdown_table`) all
read it. Adding a format is one entry here plus its module.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass

#: what each optional extra provides: the module it installs, to test for it
EXTRAS = {"cad": "OCP"}


@dataclass(frozen=True)
class Reader:
    """name: the format's name. extensions: lower case with the dot; by_extension:
    picked for them when the format is "auto" (else only when named). module: the
    reading module under bsrt.io. extra: the pip extra it needs (``bsrt[cad]``), or
    None. cached: loads go through the converted-model cache. what: one line."""

    name: str
    extensions: tuple[str, ...]
    what: str
    module: str
    extra: str | None = None
    cached: bool = False
    by_extension: bool = True

    def available(self) -> bool:
        """Whether its extra (if any) is installed."""
        return self.extra is None or importlib.util.find_spec(EXTRAS[self.extra]) is not None


READERS: dict[str, Reader] = {
    r.name: r
    for r in (
        Reader("bez", (".bez",), "Newell/Utah indexed Bezier patches (the Qt3D tea set)", "bez"),
        Reader("bpt", (".bpt",), "Bezier patch text (Ryan Holmes' teapot, teacup, teaspoon)", "bpt"),
        Reader(
            "brep",
            (".brep", ".brp"),
            "OpenCASCADE BREP: trimmed faces of any surface, through OpenCASCADE",
            "occt",
            extra="cad",
            cached=True,
        ),
        Reader("g2", (".g2",), "GoTools / Splipy spline surfaces (class 200)", "g2"),
        Reader(
            "iges",
            (".igs", ".iges"),
            "IGES 5.3 (bsrt's own reader): NURBS 128, analytic 108/114/118/120/122 "
            "and 190-198 as exact NURBS (118s whose rulings are no NURBS within 1e-10), offsets 140, "
            "trimmed 144/142, bounded 143/141, B-rep solids 186, subfigures 308/408",
            "iges",
            cached=True,
        ),
        Reader("nurbs", (".nurbs",), "GLScene NURBS surface (VRML97 NurbsSurface fields)", "nurbs"),
        Reader("obj", (".obj",), "Wavefront OBJ free-form surfaces (bezier, bspline, rational)", "obj"),
        Reader(
            "step",
            (".step", ".stp", ".p21"),
            "STEP AP203/AP214/AP242 B-reps and assemblies with colours, through OpenCASCADE",
            "occt",
            extra="cad",
            cached=True,
        ),
        Reader(
            "occt",
            (".step", ".stp", ".p21", ".brep", ".brp", ".igs", ".iges"),
            "STEP, BREP or IGES (by extension) through OpenCASCADE: IGES read by OpenCASCADE instead of bsrt",
            "occt",
            extra="cad",
            cached=True,
            by_extension=False,
        ),
    )
}

#: extension -> the format read by default
BY_EXTENSION: dict[str, str] = {ext: r.name for r in READERS.values() if r.by_extension for ext in r.extensions}


def extensions_text() -> str:
    """The model-file extensions for help text: ``.bez .bpt .brep ...``."""
    return " ".join(sorted(BY_EXTENSION))


def format_choices() -> tuple[str, ...]:
    """``--format``'s and ``[[import]].format``'s values: "auto" and every format name."""
    return ("auto",) + tuple(READERS)


def markdown_table() -> str:
    """The readers as a Markdown table (docs/usage.md carries it; a test keeps it current)."""
    rows = ["| format | extensions | reads | needs |", "|---|---|---|---|"]
    for r in READERS.values():
        exts = " ".join(f"`{e}`" for e in r.extensions) + ("" if r.by_extension else " (only with `--format occt`)")
        rows.append(f"| `{r.name}` | {exts} | {r.what} | {f'`bsrt[{r.extra}]`' if r.extra else '-'} |")
    return "\n".join(rows)

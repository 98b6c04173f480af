"""The render settings: one declaration each, everything else derived from it.

:data:`SETTINGS` is the registry. Each :class:`Setting` says its name (the
Python keyword and the :class:`RenderOptions` field), the scene table that
holds it (``[film]`` or ``[render]``), its type, default, bounds, unit and
help. From it come: the scene format's ``[film]`` / ``[render]`` parsing
(:mod:`bsrt.scene.parse`), the dataclasses :class:`Film` and
:class:`RenderSettings`, the command line's flags (``--spp`` ...,
:func:`add_flags`), the Python API's keyword checks (:func:`checked_overrides`),
batches and the preview, and the settings table of the docs
(:func:`markdown_table`). Adding a setting is one entry here plus the code
that uses it.

``RenderOptions`` (bsrt/rendering/options.py), one field per setting, is
resolved once at the edge (scene values, then the caller's overrides, every
value checked) and passed to ``render()``; nothing downstream re-reads the
scene's tables or re-checks a name.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, make_dataclass, replace
from typing import Any

import numpy as np

from bsrt import validate
from bsrt.errors import InputError
from bsrt.methods import DEFAULT_METHOD, METHODS

MAP_MODES = ("float", "rgba8")
DEVICES = ("auto", "cpu", "gpu")  # where the seeded solve and the direct lighting run: bsrt/rendering/gpu.py

#: name -> (direction from the model to the eye, the camera's up), in the frame (X, Y, Z = up) of
#: :func:`bsrt.scene.auto.view_frame`; "default" is bsrt's three-quarter view from above
VIEWS = {
    "default": ((-0.75, 0.55, 0.42), (0.0, 0.0, 1.0)),
    "iso": ((1.0, -1.0, 1.0), (0.0, 0.0, 1.0)),
    "front": ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    "back": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "left": ((-1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "right": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "top": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    "bottom": ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
}
VIEW_NAMES = tuple(v for v in VIEWS if v != "default")


@dataclass(frozen=True)
class Setting:
    """One render setting.

    name: the Python keyword, the RenderOptions field and the key in its
    table. table: "film" or "render". kind: "int", "float", "choice", "bool" or
    "color" (three numbers >= 0, linear RGB; <= hi when hi is given). lo, hi: bounds (lo_open: lo
    itself excluded). choices: for "choice", and the allowed values of an "int" when given. unit: shown in help and docs.
    commands: the CLI commands that take it as a flag ("render" also means
    batch and animate; "map"; "preview"; "scan").
    """

    name: str
    table: str
    kind: str
    default: Any
    help: str
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    choices: tuple[str, ...] = ()
    unit: str = ""
    commands: tuple[str, ...] = ("render", "preview")

    @property
    def key(self) -> str:
        """The scene file's key: ``render.spp``."""
        return f"{self.table}.{self.name}"

    @property
    def flag(self) -> str:
        """The command line's flag: ``--max-iterations``."""
        return "--" + self.name.replace("_", "-")

    @property
    def python_type(self) -> type:
        return {"int": int, "float": float, "choice": str, "color": tuple, "bool": bool}[self.kind]

    def check(self, value, label: str | None = None):
        """``value`` checked and normalised (int, float, str or a 3-tuple of floats);
        else an InputError ``<label>: <what is wrong>`` (label: the name by default)."""
        label = self.name if label is None else label
        if self.kind == "int":
            number = validate.whole(label, value, int(self.lo), int(self.hi))
            if self.choices and number not in self.choices:
                raise InputError(f"{label}: expected one of {', '.join(map(str, self.choices))}, got {number}")
            return number
        if self.kind == "float":
            low = f"{'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}]"
            return validate.real(label, value, self.lo, self.hi, lo_open=self.lo_open, expected=f"a number in {low}")
        if self.kind == "bool":
            if not isinstance(value, (bool, np.bool_)):
                raise InputError(f"{label}: expected true or false, got {validate.show(value)}")
            return bool(value)
        if self.kind == "choice":
            if value not in self.choices:
                raise InputError(f"{label}: expected one of {', '.join(self.choices)}, got {validate.show(value)}")
            return value
        if (
            isinstance(value, (str, bytes))
            or not hasattr(value, "__len__")
            or len(value) != 3
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in value)
        ):
            raise InputError(f"{label}: expected three numbers (linear RGB), got {validate.show(value)}")
        if not all(math.isfinite(x) and x >= 0 for x in value):
            raise InputError(f"{label}: expected three finite numbers >= 0 (linear RGB), got {validate.show(value)}")
        if self.hi is not None and any(x > self.hi for x in value):
            raise InputError(
                f"{label}: expected three numbers in [0, {self.hi:g}] (linear RGB), got {validate.show(value)}"
            )
        return tuple(float(x) for x in value)

    def describe(self) -> str:
        """The help line: text, range or choices, default."""
        if self.kind == "choice" or self.choices:
            span = "one of " + ", ".join(map(str, self.choices))
        elif self.kind == "bool":
            span = "true or false"
        elif self.kind == "color":
            span = "R,G,B >= 0" if self.hi is None else f"R,G,B in [0, {self.hi:g}]"
        else:
            span = f"{'>' if self.lo_open else '>='} {self.lo:g}, <= {self.hi:g}"
        unit = f" {self.unit}" if self.unit else ""
        return f"{self.help} ({span}; default {_shown(self.default)}{unit}; scene key {self.key})"


def _shown(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"  # as the scene file spells it
    return (
        ",".join(f"{x:g}" for x in value)
        if isinstance(value, tuple)
        else f"{value:g}"
        if isinstance(value, float)
        else str(value)
    )


SETTINGS: tuple[Setting, ...] = (
    Setting(
        "width", "film", "int", 512, "film width", 1, validate.MAX_FILM_SIDE, unit="pixels", commands=("render", "map")
    ),
    Setting(
        "height",
        "film",
        "int",
        512,
        "film height",
        1,
        validate.MAX_FILM_SIDE,
        unit="pixels",
        commands=("render", "map"),
    ),
    Setting("background", "film", "color", (0.03, 0.03, 0.04), "colour where no surface is hit, linear RGB", hi=1.0),
    Setting(
        "transparent",
        "film",
        "bool",
        False,
        "write the background as transparent: RGBA with the surfaces' coverage as alpha (PNG, WebP)",
        commands=("render",),
    ),
    Setting(
        "bit_depth",
        "film",
        "int",
        8,
        "bits per channel of a PNG (16: PNG only)",
        8,
        16,
        choices=(8, 16),
        commands=("render",),
    ),
    Setting(
        "method",
        "render",
        "choice",
        DEFAULT_METHOD,
        "root finder (the methods are listed at the end of `bsrt render --help`)",
        choices=tuple(METHODS),
    ),
    Setting(
        "map",
        "render",
        "choice",
        "float",
        "precision of the preliminary map",
        choices=MAP_MODES,
        commands=("render", "map", "preview"),
    ),
    Setting(
        "tolerance",
        "render",
        "float",
        1e-9,
        "largest ray-surface distance of a hit",
        0.0,
        1.0,
        lo_open=True,
        unit="of the scene's diagonal",
        commands=("render", "preview", "scan"),
    ),
    Setting("max_iterations", "render", "int", 64, "root-finder steps per pixel and start", 1, validate.MAX_ITERATIONS),
    Setting(
        "spp", "render", "int", 1, "samples per pixel (anti-aliasing)", 1, validate.MAX_SPP, commands=("render",)
    ),  # the preview traces one sample per pixel
    Setting("max_depth", "render", "int", 3, "mirror-reflection bounces", 0, validate.MAX_DEPTH),
    Setting(
        "adaptive_spp",
        "render",
        "int",
        4,
        "adaptive anti-aliasing: samples per pixel where neighbouring pixels disagree, when spp = 1 (0 or 1: off)",
        0,
        validate.MAX_SPP,
        commands=("render",),
    ),
    Setting("edges", "render", "bool", False, "draw the model's visible edges, creases and silhouettes"),
    Setting("edge_width", "render", "float", 1.5, "width of the drawn edges", 0.0, 64.0, lo_open=True, unit="pixels"),
    Setting("edge_color", "render", "color", (0.0, 0.0, 0.0), "colour of the drawn edges, linear RGB"),
    Setting("hidden_edges", "render", "bool", False, "also draw the hidden edges, faint and dashed (with edges)"),
    Setting(
        "ao",
        "render",
        "bool",
        False,
        "ambient occlusion: the ambient light of each point times the fraction of 16 exact rays over its "
        "hemisphere that leave within half a model radius",
        commands=("render",),
    ),
    Setting(
        "ground",
        "render",
        "bool",
        False,
        "a ground plane under the model (traced exactly: the lights' shadows fall on it) with a contact shadow",
        commands=("render",),
    ),
    Setting(
        "device",
        "render",
        "choice",
        "auto",
        "where the seeded root finder and the direct lighting run: gpu (OpenGL 4.5 compute shaders in float64), cpu, or auto "
        "(the faster path: cpu on every machine measured so far, a GPU machine included)",
        choices=DEVICES,
    ),
)
BY_NAME: dict[str, Setting] = {s.name: s for s in SETTINGS}


def _table_class(name: str, table: str, doc: str) -> type:
    """A frozen dataclass with one field per setting of ``table``, in registry order, with its default."""
    cls = make_dataclass(
        name, [(s.name, s.python_type, field(default=s.default)) for s in SETTINGS if s.table == table], frozen=True
    )
    cls.__module__ = __name__  # make_dataclass's own module otherwise: pickling (batches) needs the real one
    cls.__doc__ = doc + "\n\n" + "\n".join(f"{s.name}: {s.describe()}" for s in SETTINGS if s.table == table)
    return cls


Film = _table_class("Film", "film", "The scene's ``[film]``: the picture's size and background.")
RenderSettings = _table_class("RenderSettings", "render", "The scene's ``[render]``: how rays are traced.")


def checked_overrides(values: Mapping[str, Any]) -> dict:
    """The given (not None) settings, checked: name -> value (a message names the setting as the
    keyword it is). Unknown names are a TypeError (a programming error)."""
    out = {}
    for name, value in values.items():
        if name not in BY_NAME:
            raise TypeError(f"unknown render setting {name!r} (known: {', '.join(BY_NAME)})")
        if value is not None:
            setting = BY_NAME[name]
            out[name] = setting.check(value)
    return out


def setting_keywords(function):
    """``function`` (whose ``**settings`` take the render settings) with a signature that names
    every setting as a keyword-only parameter (default None), in registry order, after its
    positional parameters: what ``help()``, notebooks and ``inspect.signature`` show. The
    function itself checks ``settings`` with :func:`checked_overrides` (an unknown name is a
    TypeError)."""
    import inspect

    signature = inspect.signature(function)
    params = list(signature.parameters.values())
    positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    keywords = [p for p in params if p.kind is p.KEYWORD_ONLY]
    named = [
        inspect.Parameter(
            s.name, inspect.Parameter.KEYWORD_ONLY, default=None, annotation=f"{s.python_type.__name__} | None"
        )
        for s in SETTINGS
    ]
    function.__signature__ = signature.replace(parameters=positional + named + keywords)
    return function


def with_settings(scene, values: Mapping[str, Any]):
    """The scene with checked settings (name -> value) written into its [film] and [render]."""
    film = {k: v for k, v in values.items() if BY_NAME[k].table == "film"}
    render = {k: v for k, v in values.items() if BY_NAME[k].table == "render"}
    return replace(scene, film=replace(scene.film, **film), render=replace(scene.render, **render))


# ---------------------------------------------------------------------------
# The command line's flags, derived


def add_flags(parser, command: str) -> None:
    """Add a flag for each setting that ``command`` ("render", "map" or "preview") takes;
    each value is checked by the setting itself (argparse's one-line error on a bad one)."""
    import argparse

    for s in SETTINGS:
        if command in s.commands:
            kwargs: dict[str, Any] = {"dest": s.name, "help": s.describe()}
            if s.kind == "choice":
                kwargs["choices"] = s.choices
            elif s.kind == "bool":
                kwargs["action"] = argparse.BooleanOptionalAction
                kwargs["default"] = None
            else:
                kwargs["type"] = _parse_flag(s)
                kwargs["metavar"] = "R,G,B" if s.kind == "color" else s.name.upper()
            parser.add_argument(s.flag, **kwargs)


def _parse_flag(setting: Setting):
    import argparse

    def parse(text: str):
        try:
            if setting.kind == "color":
                value = [float(x) for x in text.replace(",", " ").split()]
            else:
                value = int(text) if setting.kind == "int" else float(text)
        except ValueError:
            what = (
                "a whole number"
                if setting.kind == "int"
                else "three numbers like 1,1,1"
                if setting.kind == "color"
                else "a number"
            )
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        try:
            return setting.check(value, "")
        except InputError as exc:
            raise argparse.ArgumentTypeError(str(exc).removeprefix(": ")) from None

    parse.__name__ = setting.name  # argparse's "invalid <name> value" fallback
    return parse


def flag_values(args, command: str) -> dict:
    """The settings given on the command line (argparse namespace): name -> value."""
    return {
        s.name: getattr(args, s.name)
        for s in SETTINGS
        if command in s.commands and getattr(args, s.name, None) is not None
    }


# ---------------------------------------------------------------------------
# The docs' table, derived


def markdown_table() -> str:
    """The settings as a Markdown table (docs/scene-format.md carries it; a test keeps it current)."""
    rows = ["| scene key | Python keyword | flag | type | default | range | meaning |", "|---|---|---|---|---|---|---|"]
    for s in SETTINGS:
        if s.kind == "choice" or s.choices:
            span = ", ".join(f"`{c}`" for c in s.choices)
        elif s.kind == "bool":
            span = "`true`, `false`"
        elif s.kind == "color":
            span = "3 numbers >= 0" if s.hi is None else f"3 numbers in [0, {s.hi:g}]"
        else:
            span = f"{'(' if s.lo_open else '['}{s.lo:g}, {s.hi:g}]"
        flag = f"`{s.flag}`"
        unit = f" ({s.unit})" if s.unit else ""
        rows.append(f"| `{s.key}` | `{s.name}` | {flag} | {s.kind} | `{_shown(s.default)}` | {span} | {s.help}{unit} |")
    return "\n".join(rows)

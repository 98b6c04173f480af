"""Scene documents: Python values into the tables, lists and numbers of a scene
file, and a scene back into a scene file (the one writer: ``dumps_toml``).

A scene built in Python becomes the same document a TOML file gives (arrays
through ``.tolist()``, which keeps every float64), so the scene parser checks
it; :func:`scene_document` and :func:`dumps_toml` write a scene (or a camera,
:func:`camera_toml`) as text that reads back bit for bit.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
from collections.abc import Mapping
from dataclasses import asdict
from typing import Any

import numpy as np

from bsrt import __version__
from bsrt.errors import InputError
from bsrt.scene.camera import Camera
from bsrt.scene.model import Light, Material, Scene

_TOML_WORDS = (
    (re.compile(r"expected a table$"), "expected a mapping (a dict) or the bsrt object"),
    (re.compile(r"expected an array of tables \[\[\w+\]\]"), "expected a list"),
    (re.compile(r"missing table \[(\w+)\]"), r"missing (\1= is required)"),
    (
        re.compile(r"the scene has no \[\[surface\]\] or \[\[import\]\] \(nothing to render\)"),
        "no surfaces given (nothing to render)",
    ),
)


@contextlib.contextmanager
def python_words():
    """The scene format's messages about its tables, said in Python's words for a scene built in Python
    (keys and values keep their names: they are the keyword and field names)."""
    try:
        yield
    except InputError as exc:
        message = str(exc)
        for pattern, words in _TOML_WORDS:
            message = pattern.sub(words, message)
        if message == str(exc):
            raise
        raise type(exc)(message) from None


def camera_doc(camera) -> dict:
    if isinstance(camera, Camera):
        return {
            "eye": plain(camera.eye),
            "look_at": plain(camera.look_at),
            "up": plain(camera.up),
            "fov": plain(camera.fov),
            "fov_axis": camera.fov_axis,
        }
    return plain(camera)


def light_doc(light) -> dict:
    if isinstance(light, Light):
        doc = {"kind": light.kind, "color": light.color, "intensity": light.intensity}
        if light.position is not None:
            doc["position"] = light.position
        if light.direction is not None:
            doc["direction"] = light.direction
        return plain(doc)
    return plain(light)


def material_ref(material, mats: list):
    """A surface's material as the document holds it: a name (a Material object joins ``mats``)."""
    if isinstance(material, Material):
        if not any(m is material or m == material for m in mats):
            mats.append(material)
        return material.name
    return plain(material)


def surface_doc(s, mats: list) -> dict:
    doc = {
        "degree": plain(s.degree),
        "knots_u": plain(s.knots_u),
        "knots_v": plain(s.knots_v),
        "points": plain(s.points),
    }
    if s.weights is not None:
        doc["weights"] = plain(s.weights)
    if s.name is not None:
        doc["name"] = s.name
    if s.material is not None:
        doc["material"] = material_ref(s.material, mats)
    if s.color is not None:
        doc["color"] = plain(s.color)
    if s.trims is not None and (not is_array_like(s.trims) or len(s.trims)):
        doc["trim"] = [loop_doc(loop) for loop in s.trims] if is_array_like(s.trims) else plain(s.trims)
    if s.transform is not None:
        doc["transform"] = plain(s.transform)
    return doc


def loop_doc(loop):
    if isinstance(loop, Mapping):
        return plain(loop)
    curves = getattr(loop, "curves", loop)  # a TrimLoop, or a sequence of curves
    return {"curves": [curve_doc(c) for c in curves] if is_array_like(curves) else plain(curves)}


def curve_doc(curve):
    if isinstance(curve, Mapping):
        doc = dict(curve)
        if doc.get("weights", 0) is None:
            del doc["weights"]
        return plain(doc)
    if all(hasattr(curve, k) for k in ("degree", "knots", "points")):
        doc = {"degree": curve.degree, "knots": curve.knots, "points": curve.points}
        if getattr(curve, "weights", None) is not None:
            doc["weights"] = curve.weights
        return plain(doc)
    return plain(curve)


def import_doc(item, mats: list) -> dict:
    doc = {"file": os.fspath(item.file), "format": item.format}
    if item.material is not None:
        doc["material"] = material_ref(item.material, mats)
    if item.transform is not None:
        doc["transform"] = plain(item.transform)
    return doc


def plain(value):
    """NumPy arrays and scalars, tuples and mappings as the lists, numbers and dicts of a TOML document."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Mapping):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return value


def is_array_like(value) -> bool:
    return isinstance(value, (list, tuple, np.ndarray))


# ---------------------------------------------------------------------------
# A scene -> a scene file


def scene_document(scene: Scene) -> dict:
    """The document (tables, lists, numbers) of a scene file for ``scene``:
    surfaces in world space with their trims, materials by (unique) name."""
    names, used = [], set()
    for i, m in enumerate(scene.materials):
        name = m.name
        while name in used:  # a material called "default" beside the automatic one
            name = f"{m.name}-{i}"
            i += 1
        used.add(name)
        names.append(name)
    doc: dict[str, Any] = {
        "film": asdict(scene.film),
        "camera": camera_doc(scene.camera),
        "render": asdict(scene.render),
        "material": [{**asdict(m), "name": n} for m, n in zip(scene.materials, names)],
        "light": [light_doc(light) for light in scene.lights],
        "surface": [],
    }
    for s in scene.surfaces:
        g = s.geometry
        table = {
            "name": s.name,
            "material": names[s.material],
            "degree": list(g.degree),
            "knots_u": g.knots_u,
            "knots_v": g.knots_v,
            "points": g.points,
        }
        if g.weights is not None:
            table["weights"] = g.weights
        if g.trims:
            table["trim"] = [loop_doc(loop) for loop in g.trims]
        doc["surface"].append(plain(table))
    return plain(doc)


def header(scene: Scene) -> str:
    lines = [f"Scene file (bsrt scene format version 1), written by bsrt {__version__} from {scene.path}."]
    lines += [f"note: {n}" for n in scene.notes]
    return "\n".join(lines)


_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def dumps_toml(doc: Mapping, header: str = "") -> str:
    """A scene document as TOML text: top-level tables, then arrays of tables
    (``[[surface]]`` with its ``[[surface.trim]]`` loops). Floats are written
    with ``repr``, which tomllib reads back to the same float64."""
    out = [f"# {line}".rstrip() for line in header.splitlines()]
    for key, value in doc.items():
        if isinstance(value, Mapping):
            out += ["", f"[{_key(key)}]"] + _table_body(value)
        elif isinstance(value, list) and value and all(isinstance(v, Mapping) for v in value):
            for item in value:
                subtables = {
                    k: v
                    for k, v in item.items()
                    if isinstance(v, list) and v and all(isinstance(x, Mapping) for x in v)
                }
                out += ["", f"[[{_key(key)}]]"] + _table_body({k: v for k, v in item.items() if k not in subtables})
                for sub, loops in subtables.items():
                    for loop in loops:
                        out += [f"[[{_key(key)}.{_key(sub)}]]"] + _table_body(loop)
        elif not (isinstance(value, list) and not value):
            out.append(f"{_key(key)} = {_value(value)}")
    return "\n".join(out).lstrip("\n") + "\n"


def _table_body(table: Mapping) -> list[str]:
    lines = []
    for key, value in table.items():
        if isinstance(value, list) and value and isinstance(value[0], (list, Mapping)):
            # one element per line: rows of points, the curves of a loop
            lines.append(f"{_key(key)} = [")
            lines += [f"  {_value(v)}," for v in value]
            lines.append("]")
        else:
            lines.append(f"{_key(key)} = {_value(value)}")
    return lines


def _key(key: str) -> str:
    return key if _BARE_KEY.fullmatch(key) else _string(key)


def _value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + " }" if value else "{}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f", "\r": "\\r"}


def _string(text: str) -> str:
    """A TOML basic string: quotes, backslashes and control characters escaped."""
    return (
        '"'
        + "".join(_ESCAPES.get(c) or (f"\\u{ord(c):04x}" if ord(c) < 0x20 or ord(c) == 0x7F else c) for c in text)
        + '"'
    )


def camera_toml(camera: Camera) -> str:
    """The camera as a scene file's [camera] table (floats round-trip exactly)."""
    return dumps_toml({"camera": camera_doc(camera)})


def import_scene_document(scene: Scene, model_file: str, format: str = "auto") -> dict:
    """The small, editable scene of ``bsrt scene MODEL``: ``scene`` (the automatic scene of the
    model file, bsrt.scene.framing.scene_for_model) as [film], [camera], [render], the model's
    material, its lights spelled out (point lights by their brightness at the model's centre,
    bsrt.scene.auto) and one [[import]] of ``model_file`` (a path as the scene file will name
    it) with the file's own colours. Reading it renders the same picture as the model file."""
    from bsrt.scene.auto import surface_points

    points = surface_points([s.geometry for s in scene.surfaces])
    centre = (points.min(axis=0) + points.max(axis=0)) / 2.0
    base = scene.materials[0]  # the model's material; the file's colours follow it (file_colors)
    lights = []
    for light in scene.lights:
        doc = light_doc(light)
        if light.kind == "point":
            distance2 = float(np.sum((np.array(light.position) - centre) ** 2))
            doc = {k: v for k, v in doc.items() if k != "intensity"}
            doc["brightness"] = light.intensity / distance2 if distance2 > 0 else light.intensity
        lights.append(doc)
    camera = camera_doc(scene.camera)
    return plain(
        {
            "film": asdict(scene.film),
            "camera": camera,
            "render": asdict(scene.render),
            "material": [asdict(base)],
            "light": lights,
            "import": [{"file": model_file, "format": format, "material": base.name, "file_colors": True}],
        }
    )

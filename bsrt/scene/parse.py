"""Scene files (TOML, format version 1) into frozen dataclasses.

Every problem is an InputError naming the file, the table and the key, e.g.
``column.toml: surface[3].knots_u: expected 12 values (8 points + degree 3 +
1), got 11``. Unknown keys are errors: nothing is silently ignored.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np

from bsrt import validate
from bsrt.errors import InputError, MissingFileError
from bsrt.files import check_input_file
from bsrt.geometry.bspline import make_surface
from bsrt.geometry.trim import TrimLoop, make_trim_curve
from bsrt.scene.camera import Camera, rotation_matrix
from bsrt.scene.model import DEFAULT_MATERIAL, Film, Light, Material, RenderSettings, Scene, SceneSurface
from bsrt.scene.tables import _show, _Table
from bsrt.settings import SETTINGS


def load_scene(path: str | Path, *, cache: bool = True, progress=None, film_size=None) -> Scene:
    """Read and validate a scene file (docs/scene-format.md is the format).

    cache, progress: for the model files of its [[import]] tables, as in
    :func:`bsrt.io.load_model` (progress(done, total): faces converted). film_size: the
    (width, height) an automatic camera is fitted to (default: the scene's [film])."""
    path = check_input_file(path, "scene file")
    where = path.name
    try:
        text = path.read_bytes().decode("utf-8-sig")  # a byte-order mark is accepted, as in model files
    except FileNotFoundError:
        raise MissingFileError(path) from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, not a scene file") from None
    except UnicodeDecodeError:
        raise InputError(f"{where}: not a text (UTF-8) file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{where}: invalid TOML: {exc}") from None
    except RecursionError:
        raise InputError(f"{where}: invalid TOML: arrays or tables nested too deeply") from None
    order = re.findall(r"(?m)^[ \t]*\[\[[ \t]*(surface|import)[ \t]*\]\]", text)
    scene = parse_scene(data, where, path.parent, order, cache=cache, progress=progress, film_size=film_size)
    return replace(scene, inputs=(str(path),) + scene.inputs)


def parse_scene(
    data: dict,
    where: str = "<scene>",
    folder: Path | None = None,
    order=None,
    *,
    cache: bool = True,
    progress=None,
    film_size=None,
    studio: bool = True,
) -> Scene:
    """Validate an already-parsed TOML document.

    (Long: it walks the tables in the format's order, each a short block, and
    the materials and lights it builds are what later tables refer to.)

    folder resolves [[import]] files; order: the kinds ("surface" or
    "import") of the surface-producing tables as they appear in the text,
    which tomllib does not keep (None: surfaces first, then imports).
    cache, progress: for the imported model files (:func:`bsrt.io.load_model`).
    A scene with [[import]] and no [camera] gets the automatic camera (bsrt/scene/auto.py),
    fitted to film_size (width, height) when given, else to its [film]; a scene with no
    [[light]] gets the studio rig, with a note (unless studio is False: ``Scene.build``).
    """
    known = {"film", "camera", "render", "material", "light", "surface", "import"}
    for key in data:
        if key not in known:
            raise InputError(f"{where}: {key}: unknown table (expected one of {', '.join(sorted(known))})")

    film = Film(**_settings_table(where, data, "film"))

    if "camera" not in data:
        if "import" not in data:
            raise InputError(f"{where}: camera: missing table [camera] (only a scene with [[import]] may leave it out)")
        camera, keyframes = None, []  # the automatic camera, fitted to the surfaces below
    else:
        camera, keyframes = _camera(where, data)

    render = RenderSettings(**_settings_table(where, data, "render"))

    materials, by_name = [], {}
    for i, raw in enumerate(_array_of_tables(where, data, "material")):
        t = _Table(where, raw, f"material[{i}]")
        name = t.string("name", required=True)
        if name in by_name:
            t.fail("name", f"duplicate material name {name!r}")
        mat = Material(
            name=name,
            color=t.vector("color", DEFAULT_MATERIAL.color, lo=0.0),
            specular=t.number("specular", DEFAULT_MATERIAL.specular, lo=0.0, hi=1.0),
            shininess=t.number("shininess", DEFAULT_MATERIAL.shininess, lo=0.0),
            reflectance=t.number("reflectance", 0.0, lo=0.0, hi=1.0),
        )
        t.finish()
        by_name[name] = len(materials)
        materials.append(mat)

    lights, bright = [], []  # bright: (light index, brightness at the model's centre)
    for i, raw in enumerate(_array_of_tables(where, data, "light")):
        t = _Table(where, raw, f"light[{i}]")
        kind = t.string("kind", required=True, choices=("point", "directional", "ambient"))
        if t.has("brightness"):
            if kind != "point":
                t.fail(
                    "brightness", "only for point lights (a directional or ambient light's intensity has no falloff)"
                )
            if t.has("intensity"):
                t.fail("brightness", "give either intensity or brightness, not both")
            bright.append((i, t.number("brightness", lo=0.0)))
        light = Light(
            kind=kind,
            color=t.vector("color", (1.0, 1.0, 1.0), lo=0.0),
            intensity=t.number("intensity", 1.0, lo=0.0),
            position=t.vector("position", required=True) if kind == "point" else None,
            direction=t.vector("direction", required=True) if kind == "directional" else None,
        )
        if kind == "directional" and not any(light.direction):
            t.fail("direction", "must not be the zero vector")
        t.finish()
        lights.append(light)

    surfaces, notes, inputs, loads = [], [], [], []
    for kind, i, raw in _surface_entries(where, data, order):
        if kind == "import":
            t = _Table(where, raw, f"import[{i}]")
            model = _load_import(t, folder, cache, progress)
            inputs.append(str(model.path))
            loads.append(model.load)
            own = t.has("material") or t.has("color")
            file_colors = t.raw("file_colors", not own)
            if not isinstance(file_colors, bool):
                t.fail("file_colors", f"expected true or false, got {_show(file_colors)}")
            material = _material_for(t, materials, by_name)
            colored = (  # the file's colours (STEP) on the import's material, or on the default one
                _colour_materials(model, materials, materials[material], f"{Path(model.path).name}:")
                if file_colors
                else None
            )
            matrix = _transform(t, "transform") if t.has("transform") else None
            t.finish()
            notes += [f"{model.path}: {w}" for w in model.warnings] + _skipped_notes(model)
            mirror = matrix is not None and np.linalg.det(matrix[:3, :3]) < 0  # reverses every orientation
            for k, (geometry, name) in enumerate(zip(model.surfaces, model.names)):
                mat = material if colored is None or colored[k] is None else colored[k]
                if matrix is not None:
                    geometry = _within_limits(t, "transform", geometry.transformed(matrix), name)
                flip = bool(model.reversed[k]) if model.reversed else False
                surfaces.append(SceneSurface(geometry, mat, name, flip != mirror))
            continue
        t = _Table(where, raw, f"surface[{i}]")
        name = t.string("name", f"surface-{i}")
        material = _material_for(t, materials, by_name)
        try:
            geometry = make_surface(*_surface_arrays(t))
            validate.surface(geometry)
        except InputError as exc:
            raise InputError(f"{where}: surface[{i}].{exc}") from None
        if t.has("trim"):
            geometry = _trimmed(t, geometry)
        if t.has("transform"):
            geometry = _within_limits(t, "transform", geometry.transformed(_transform(t, "transform")), name)
        t.finish()
        surfaces.append(SceneSurface(geometry, material, name))
    if not surfaces:
        raise InputError(f"{where}: the scene has no [[surface]] or [[import]] (nothing to render)")
    if camera is None or (studio and not lights) or bright:
        from bsrt.scene.auto import fit_camera, studio_lights, surface_points

        points = surface_points([s.geometry for s in surfaces])
        centre = (points.min(axis=0) + points.max(axis=0)) / 2.0
        for i, value in bright:  # as bright as `value` at the centre: no inverse-square arithmetic
            distance2 = float(np.sum((np.array(lights[i].position) - centre) ** 2))
            lights[i] = replace(lights[i], intensity=value * distance2)
        if camera is None:
            w, h = film_size or (film.width, film.height)
            camera = fit_camera(points, w, h)
        if studio and not lights:
            lights = list(studio_lights(points, camera))
            notes.append(f"{where}: no [[light]]: lit by the default studio rig (key, fill, rim and ambient light)")
    return Scene(
        film,
        camera,
        render,
        tuple(materials),
        tuple(lights),
        tuple(surfaces),
        where,
        tuple(notes),
        tuple(inputs),
        tuple(keyframes),
        tuple(loads),
    )


def _camera(where: str, data: dict):
    """The [camera] table: (Camera, its parsed keyframes)."""
    cam_t = _Table(where, data["camera"], "camera")
    eye = np.array(cam_t.vector("eye", required=True))
    look_at = np.array(cam_t.vector("look_at", required=True))
    up = np.array(cam_t.vector("up", (0.0, 0.0, 1.0)))
    fov = cam_t.number("fov", 40.0, lo=0.0, hi=validate.MAX_FOV, lo_open=True, hi_open=True)
    if fov < validate.MIN_FOV:
        cam_t.fail(
            "fov", f"must be at least {validate.MIN_FOV:g} degrees (see Limits in docs/scene-format.md), got {fov:g}"
        )
    fov_axis = cam_t.string("fov_axis", "y", choices=("x", "y"))
    keyframes = cam_t.raw("keyframe", [])  # parsed below, by bsrt/scene/keyframes.py
    cam_t.finish()
    camera = Camera(eye, look_at, up, fov, fov_axis)
    try:
        validate.camera(camera)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    if keyframes != []:
        from bsrt.scene.keyframes import parse_keyframes

        keyframes = parse_keyframes(keyframes, where, camera)
    return camera, keyframes


def _settings_table(where: str, data: dict, table: str) -> dict:
    """The values of the settings that ``table`` ("film" or "render") holds (bsrt.settings.SETTINGS),
    each checked by its setting; absent keys take the setting's default."""
    t = _Table(where, data.get(table, {}), table)
    values = {}
    for s in SETTINGS:
        if s.table == table:
            values[s.name] = s.check(t.raw(s.name), f"{where}: {s.key}") if t.has(s.name) else s.default
    t.finish()
    return values


def _surface_arrays(t: _Table) -> tuple:
    """(degree, knots_u, knots_v, points, weights) of a [[surface]], each checked for type
    (whole numbers for the degrees, numbers elsewhere: no booleans, no strings) and finiteness."""
    degree = t.raw("degree", required=True)
    if (
        not isinstance(degree, list)
        or len(degree) != 2
        or any(isinstance(d, bool) or not isinstance(d, int) for d in degree)
    ):
        raise InputError(f"degree: expected two whole numbers [p, q], got {_show(degree)}")
    if max(degree) > validate.MAX_DEGREE:
        raise InputError(
            f"degree: at most {validate.MAX_DEGREE} (see Limits in docs/scene-format.md), got {_show(degree)}"
        )
    arrays = [validate.numbers(key, t.raw(key, required=True), check=False) for key in ("knots_u", "knots_v", "points")]
    weights = t.raw("weights")
    return (degree, *arrays, None if weights is None else validate.numbers("weights", weights, check=False))


def _within_limits(t: _Table, key: str, geometry, name: str):
    """A transformed surface whose coordinates stay within the limits."""
    try:
        validate.surface(geometry)
    except InputError as exc:
        t.fail(key, f"moves surface {name!r} out of range: {exc}")
    return geometry


def _trimmed(t: _Table, geometry):
    """The surface with its [[surface.trim]] loops (docs/scene-format.md, "Trimmed surfaces")."""
    raw = t.raw("trim")
    if not isinstance(raw, list):
        t.fail("trim", "expected an array of tables [[surface.trim]], each with curves = [...]")
    loops = []
    for i, loop_raw in enumerate(raw):
        lt = _Table(t.where, loop_raw, f"{t.name}.trim[{i}]")
        curves_raw = lt.raw("curves", required=True)
        if not isinstance(curves_raw, list) or not curves_raw:
            lt.fail("curves", "expected a non-empty list of curves { degree, knots, points [, weights] }")
        curves = []
        for j, c_raw in enumerate(curves_raw):
            ct = _Table(t.where, c_raw, f"{lt.name}.curves[{j}]")
            args = (
                ct.raw("degree", required=True),
                ct.raw("knots", required=True),
                ct.raw("points", required=True),
                ct.raw("weights"),
            )
            try:
                curves.append(make_trim_curve(*args))
            except InputError as exc:
                raise InputError(f"{t.where}: {ct.name}.{exc}") from None
            ct.finish()
        lt.finish()
        loops.append(TrimLoop(tuple(curves)))
    try:
        return geometry.with_trims(loops)
    except InputError as exc:
        raise InputError(f"{t.where}: {t.name}.{exc}") from None


def _load_import(t: _Table, folder: Path | None, cache: bool = True, progress=None):
    from bsrt.io import load_model
    from bsrt.io.formats import format_choices

    file = t.string("file", required=True)
    fmt = t.string("format", "auto", choices=format_choices())
    path = Path(file) if folder is None or Path(file).is_absolute() else folder / file
    try:
        found = path.exists()
    except (OSError, ValueError) as exc:  # a name over 255 bytes, a NUL character
        t.fail("file", f"cannot open {_show(str(path))}: {getattr(exc, 'strerror', None) or exc}")
    if not found:
        raise MissingFileError(path, f"{t.where}: {t.name}.file: no such file: {path}")
    try:
        check_input_file(path, "model file")
    except InputError as exc:
        t.fail("file", str(exc))
    return load_model(path, fmt, cache=cache, progress=progress)


def _colour_materials(model, materials: list, base: Material, prefix: str) -> list | None:
    """The model file's own colours (STEP) as materials appended to ``materials``: per surface,
    the index of its colour's material, or None where the file gives none. None if it has no colours."""
    colors = getattr(model, "colors", None)
    if not colors or all(c is None for c in colors):
        return None
    index: dict = {}
    out = []
    for c in colors:
        if c is None:
            out.append(None)
            continue
        key = tuple(float(x) for x in c)
        if key not in index:
            index[key] = len(materials)
            materials.append(replace(base, name=f"{prefix}rgb({key[0]:.4g},{key[1]:.4g},{key[2]:.4g})", color=key))
        out.append(index[key])
    return out


def _skipped_notes(model) -> list[str]:
    if not model.skipped:
        return []
    items = ", ".join(f"{n} x {what}" for what, n in sorted(model.skipped.items(), key=lambda kv: -kv[1]))
    return [f"{model.path}: not drawable, left out: {items}"]


def _array_of_tables(where: str, data: dict, key: str) -> list:
    value = data.get(key, [])
    if not isinstance(value, list):
        raise InputError(f"{where}: {key}: expected an array of tables [[{key}]]")
    return value


def _surface_entries(where: str, data: dict, order):
    """(kind, index within its kind, table) for [[surface]] and [[import]] in file order."""
    tables = {key: _array_of_tables(where, data, key) for key in ("surface", "import")}
    if order is None or [order.count(k) for k in tables] != [len(v) for v in tables.values()]:
        order = ["surface"] * len(tables["surface"]) + ["import"] * len(tables["import"])
    seen = {"surface": 0, "import": 0}
    out = []
    for kind in order:
        out.append((kind, seen[kind], tables[kind][seen[kind]]))
        seen[kind] += 1
    return out


def _material_for(t: _Table, materials: list, by_name: dict) -> int:
    if t.has("material") and t.has("color"):
        t.fail("color", "give either material or color, not both")
    if t.has("material"):
        name = t.string("material")
        if name not in by_name:
            t.fail("material", f"no [[material]] named {name!r}")
        return by_name[name]
    if t.has("color"):
        materials.append(Material(name=f"{t.name}.color", color=t.vector("color", lo=0.0)))
        return len(materials) - 1
    if "__default__" not in by_name:
        by_name["__default__"] = len(materials)
        materials.append(DEFAULT_MATERIAL)
    return by_name["__default__"]


def _transform(parent: _Table, key: str) -> np.ndarray:
    """world_from_local (4, 4): scale, then rotate (axis, degrees), then translate."""
    t = _Table(parent.where, parent.raw(key), f"{parent.name}.{key}")
    scale_raw = t.raw("scale", 1.0)
    if isinstance(scale_raw, list):
        scale = np.array(t.vector("scale"))
    else:
        scale = np.full(3, t.number("scale", 1.0))
    if np.any(scale == 0):
        t.fail("scale", "must not be zero")
    if np.any(np.abs(scale) > validate.MAX_COORDINATE) or np.any(np.abs(scale) < 1.0 / validate.MAX_COORDINATE):
        t.fail(
            "scale",
            f"each factor's size must lie within 1e-15 .. 1e15 (see Limits in docs/scene-format.md), got {scale_raw}",
        )
    rot = t.vector("rotate", (0.0, 0.0, 1.0, 0.0), length=4)
    translate = np.array(t.vector("translate", (0.0, 0.0, 0.0)))
    t.finish()
    axis = np.array(rot[:3])
    if np.linalg.norm(axis) == 0:
        t.fail("rotate", "the rotation axis must not be the zero vector")
    m = np.eye(4)
    m[:3, :3] = rotation_matrix(axis, rot[3]) @ np.diag(scale)
    m[:3, 3] = translate
    return m

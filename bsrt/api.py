"""The Python API: load, build, save and render scenes from scripts and notebooks.

Everything here is re-exported from the package (``bsrt.load``,
``bsrt.Scene``, ``bsrt.render``, ...); ``docs/python-api.md`` is the guide.

One rule keeps the API and the scene files in step: a scene built in Python
is turned into the same document a TOML file gives (tables, lists and
numbers; arrays through ``.tolist()``, which keeps every float64 exactly) and
goes through :func:`bsrt.scene.parse_scene`, so every check and every error
message is the scene format's own (``<python>: surface[0].knots_u: expected
12 values (8 points + degree 3 + 1), got 11``). Values the API does not
recognise are passed through unchanged, so they meet the same checks a
wrong value in a file would. :meth:`Scene.to_toml` writes the other way: a
file that :func:`load` reads back to the same scene, bit for bit. The
document's two directions live in :mod:`bsrt.scene.document`.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterable, Mapping
from dataclasses import asdict, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bsrt import scene as _scene
from bsrt.errors import InputError
from bsrt.parts import (
    _PROBE_CAMERA,
    _PROBE_SURFACE,
    WHERE,
    Camera,
    Import,
    Light,
    Surface,
    Vector3,
    from_geomdl,
    from_splipy,
)
from bsrt.scene import Material
from bsrt.scene.camera import Camera as _Camera
from bsrt.scene.document import (
    camera_doc,
    dumps_toml,
    header,
    import_doc,
    light_doc,
    plain,
    python_words,
    scene_document,
    surface_doc,
)
from bsrt.settings import Film, RenderSettings, checked_overrides, setting_keywords, with_settings

if TYPE_CHECKING:
    from bsrt.rendering.pipeline import RenderResult

__all__ = [
    "Camera",
    "Film",
    "Import",
    "Light",
    "Material",
    "RenderSettings",
    "Scene",
    "Surface",
    "from_geomdl",
    "from_splipy",
    "load",
    "render",
]

ProgressArg = bool | Callable[[str, float], None] | None


# ---------------------------------------------------------------------------
# The scene


class Scene(_scene.Scene):
    """A checked scene, ready to render: a :class:`bsrt.scene.Scene` (frozen) with
    constructors and writers.

    Fields: film (Film), camera (:class:`bsrt.scene.camera.Camera`), render
    (RenderSettings), materials, lights, surfaces (SceneSurface: geometry in
    world space, material index, name), path (the file or label), notes.
    Make one with :func:`load` or :meth:`build`; change one with
    ``dataclasses.replace``.
    """

    @classmethod
    def build(
        cls,
        surfaces: Iterable,
        camera: Camera | Mapping | None = None,
        *,
        lights: Iterable[Light | Mapping] | None = None,
        materials: Iterable[Material | Mapping] = (),
        film: Film | Mapping | None = None,
        render: RenderSettings | Mapping | None = None,
        name: str = WHERE,
        folder: str | os.PathLike | None = None,
        cache: bool = True,
    ) -> Scene:
        """A scene from parts made in Python.

        surfaces: :class:`Surface`, :class:`Import`, or anything
        :meth:`Surface.from_object` takes (Splipy, geomdl, bsrt surfaces),
        numbered in this order. camera: None frames the surfaces
        automatically, as for a model file (a three-quarter view from
        above, +z up). lights: None gives the model files' studio rig (key,
        fill, rim and ambient light); ``[]`` none. materials: the named materials that
        surfaces refer to (Materials given on surfaces are added after
        them). film, render: the ``[film]`` and ``[render]`` values
        (defaults: 512x512, black; the scene format's defaults). name: the
        label in error messages and ``Scene.path``. folder: where Import
        files are looked up. cache: False reads Import files without the
        converted-model cache (docs/usage.md, "Model files").

        Raises InputError with the scene format's messages, e.g.
        ``<python>: surface[0].knots_u: expected 6 values (3 points + degree 2 + 1), got 5``.
        """
        data, order = _document(list(surfaces), camera, lights, materials, film, render)
        with python_words():
            scene = _scene.parse_scene(
                data, name, None if folder is None else Path(folder), order, cache=cache, studio=False
            )
        if camera is None or lights is None:
            scene = _automatic(scene, camera is None, lights is None)
        return _wrap(scene)

    @classmethod
    def load(cls, path: str | os.PathLike, **overrides) -> Scene:
        """The same as :func:`bsrt.load`."""
        return load(path, **overrides)

    def to_toml(self) -> str:
        """The scene as a scene file (TOML) that :func:`load` reads back to the same scene.

        Surfaces are written in world space (transforms applied, imports
        expanded), floats with ``repr`` (so every array comes back bit for
        bit), every material by name; notes become comments.
        """
        return dumps_toml(scene_document(self), header=header(self))

    def save(self, path: str | os.PathLike) -> None:
        """Write :meth:`to_toml` to ``path`` (``.toml``), atomically."""
        from bsrt.rendering.image import write_text

        path = Path(path)
        if path.suffix.lower() != ".toml":
            raise InputError(f"{path}: a scene file name must end in .toml")
        if not path.parent.is_dir():
            raise InputError(f"{path}: the folder {str(path.parent)!r} does not exist")
        write_text(path, self.to_toml())

    def __repr__(self) -> str:
        n = len(self.surfaces)
        return (
            f"Scene({self.path!r}, {n} surface{'s' if n != 1 else ''}, {len(self.lights)} light"
            f"{'s' if len(self.lights) != 1 else ''}, {self.film.width}x{self.film.height}, "
            f"{self.render.method}, spp={self.render.spp})"
        )


def _wrap(scene: _scene.Scene) -> Scene:
    return scene if type(scene) is Scene else Scene(**{f.name: getattr(scene, f.name) for f in fields(scene)})


# ---------------------------------------------------------------------------
# Loading


@setting_keywords
def load(
    path: str | os.PathLike,
    *,
    camera_eye: Vector3 | None = None,
    camera_look_at: Vector3 | None = None,
    camera_up: Vector3 | None = None,
    fov: float | None = None,
    view: str | None = None,
    format: str = "auto",
    cache: bool = True,
    progress: Callable[[str, float], None] | None = None,
    **settings,
) -> Scene:
    """Read a scene file (.toml) or a model file (.igs, .bez, .g2, ...).

    A model file gets the automatic scene of ``bsrt render MODEL``: a camera
    framing it from a three-quarter view above (+z up unless camera_up says
    otherwise), key, fill and ambient lights, one neutral material.
    Overrides, as the command line's options: every render setting of the
    registry (bsrt.settings.SETTINGS: width, height, background, spp, ...; the
    signature lists them), camera_eye, camera_look_at, camera_up ((3,) each),
    fov (degrees), view (a named view of the automatic camera: "iso", "front",
    "back", "left", "right", "top", "bottom") and format (model files: "auto", by extension, or a format name). The
    overrides become part of the scene (``to_toml`` writes them).
    cache: False reads model files (a scene's imports too) without the
    converted-model cache, writing nothing to it; by default a second load
    of an unchanged STEP, BREP or IGES file comes from the cache.
    progress: called as ``progress("load", fraction)`` while OpenCASCADE
    converts faces. ``Scene.loads`` tells how each model file was loaded.

    Raises InputError naming the file, table and key (or the override).
    """
    from bsrt.scene.loading import CameraOverrides, load_input

    settings = checked_overrides(settings)
    camera = CameraOverrides(camera_eye, camera_look_at, camera_up, fov, keywords=True, view=view)
    scene = load_input(
        path,
        format,
        width=settings.get("width"),
        height=settings.get("height"),
        camera=camera,
        cache=cache,
        progress=progress,
    )
    return _wrap(with_settings(scene, settings))


# ---------------------------------------------------------------------------
# Rendering


@setting_keywords
def render(
    scene: Scene | _scene.Scene | str | os.PathLike | Surface | Import | Iterable | Any,
    *,
    camera: Camera | Mapping | None = None,
    progress: ProgressArg = None,
    cache: bool = True,
    **settings,
) -> RenderResult:
    """Render a scene: a :class:`Scene`, a scene or model file (loaded with :func:`load`), or
    what :meth:`Scene.build` takes (surfaces: bsrt, Splipy or geomdl objects, :class:`Import`,
    or a list of them; framed and lit automatically).

    The keywords override the scene's own settings for this render only
    (None: the scene's value): every render setting of the registry
    (bsrt.settings.SETTINGS: width, height, background, transparent, method,
    spp, ...; the signature lists them), camera (a :class:`Camera`). progress: a
    function called as ``progress(stage, fraction)`` (stage "map", "solve",
    "shade", "aov" or "done"; fraction 0..1 of the whole render; it may
    raise to abandon the render; given a file, first "load" with the
    fraction of its faces converted), or True for a progress bar on stderr
    (lines when stderr is not a terminal) ended by a one-line summary.
    cache: False loads a file without the converted-model cache and builds the
    patch table and hierarchy without the prepared-geometry cache (docs/usage.md).

    Returns a :class:`bsrt.rendering.pipeline.RenderResult`: ``pixels`` (H, W, 3) uint8
    sRGB, ``linear`` (H, W, 3) float64, ``aovs()`` (the per-pixel arrays of
    ``--aov``: hit, t, surface, u, v, position, normal, iterations,
    residual), ``stats`` (timings and counters), ``save(path)`` (PNG, JPEG
    or WebP by the extension), ``to_pil()``; a notebook shows it as an image.
    """
    from bsrt.rendering.options import RenderOptions
    from bsrt.rendering.pipeline import render as pipeline

    bar = None
    if progress is True:
        from bsrt.progress import wanted

        bar = report = wanted(sys.stderr, True)
    elif progress in (None, False):
        report = None
    elif callable(progress):
        report = progress
    else:
        raise TypeError(f"progress: expected a function progress(stage, fraction), True or None, got {progress!r}")
    try:
        settings = checked_overrides(settings)
        if isinstance(scene, (str, os.PathLike)):  # the automatic camera fits the film asked for
            scene = load(
                scene, cache=cache, progress=report, width=settings.get("width"), height=settings.get("height")
            )
        elif not isinstance(scene, _scene.Scene):  # what Scene.build takes: surfaces, imports, lists of them
            scene = Scene.build(scene if isinstance(scene, (list, tuple)) else [scene], cache=cache)
        if camera is not None:
            settings["camera"] = _checked_camera(camera)
        options = RenderOptions.resolve(scene, **settings)
        if bar is not None:
            bar("setup", 0.0)
        result = pipeline(scene, options, progress=report, cache=cache)
    except BaseException:
        if bar is not None:
            bar.clear()
        raise
    if bar is not None:
        bar.finish(
            f"rendered {options.width}x{options.height}, {options.spp} spp, {options.method}, {bar.elapsed():.1f} s"
        )
    return result


def _checked_camera(camera) -> _Camera:
    """A camera checked as a [camera] table (the messages of a scene file)."""
    probe = {"camera": camera_doc(camera), "surface": [_PROBE_SURFACE]}
    with python_words():
        return _scene.parse_scene(probe, WHERE).camera


# ---------------------------------------------------------------------------
# Python objects -> a scene document (what tomllib gives for the same file)


def _document(surfaces: list, camera, lights, materials, film, render) -> tuple[dict, list]:
    mats = list(materials)
    data: dict[str, Any] = {"camera": _PROBE_CAMERA if camera is None else camera_doc(camera)}
    if film is not None:
        data["film"] = plain(asdict(film)) if isinstance(film, Film) else plain(film)
    if render is not None:
        data["render"] = plain(asdict(render)) if isinstance(render, RenderSettings) else plain(render)
    data["light"] = [light_doc(light) for light in (lights or ())]
    tables = {"surface": [], "import": []}
    order = []
    for item in surfaces:
        if isinstance(item, Import):
            kind, doc = "import", import_doc(item, mats)
        elif isinstance(item, Surface):
            kind, doc = "surface", surface_doc(item, mats)
        elif isinstance(item, Mapping):
            kind, doc = "surface", plain(item)
        else:
            kind, doc = "surface", surface_doc(Surface.from_object(item), mats)
        tables[kind].append(doc)
        order.append(kind)
    data["material"] = [plain(asdict(m)) if isinstance(m, Material) else plain(m) for m in mats]
    data.update({k: v for k, v in tables.items() if v})
    return data, order


def _automatic(scene: _scene.Scene, camera: bool, lights: bool) -> _scene.Scene:
    """The model files' automatic camera and/or lights for a built scene."""
    from bsrt.io import Model

    model = Model(scene.path, [s.geometry for s in scene.surfaces], [s.name for s in scene.surfaces])
    auto = _scene.scene_for_model(model, scene.film.width, scene.film.height)
    return replace(
        scene, camera=auto.camera if camera else scene.camera, lights=auto.lights if lights else scene.lights
    )

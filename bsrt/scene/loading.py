"""Scene or model file -> Scene, with the camera overrides: one place for the
CLI's render and map, the preview and the batch commands.

A ``.toml`` file is a scene; anything else is a model file read by
``bsrt.io.load_model`` (``format`` picks the reader, "auto" by extension) and
framed by ``scene_for_model`` with the automatic camera and lights.
Model files (a scene's imports too) go through the converted-model cache
unless ``cache=False``; ``Scene.loads`` records how each load went.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from bsrt.errors import InputError
from bsrt.files import check_input_file


@dataclass(frozen=True)
class CameraOverrides:
    """What the user asked for on top of the file: any field left None keeps
    the scene's value (or the automatic camera's, for a model). ``eye``,
    ``look_at`` and ``up`` are 3-sequences; ``fov`` is degrees in (0, 180).
    ``keywords``: messages name the Python API's keywords (``camera_eye``)
    instead of the command line's options (``--camera-eye``). ``view``: a named
    view of the automatic camera (bsrt.scene.auto.VIEW_NAMES), fitted to the
    model or the scene's surfaces; ``turntable``: the automatic camera of an
    orbit (centred on the model's up axis)."""

    eye: tuple | None = None
    look_at: tuple | None = None
    up: tuple | None = None
    fov: float | None = None
    keywords: bool = False
    view: str | None = None
    turntable: bool = False

    @classmethod
    def from_args(cls, args) -> CameraOverrides:
        """From argparse's ``--camera-eye --camera-look-at --camera-up --fov``
        (attributes missing on ``args`` count as not given)."""
        return cls(
            getattr(args, "camera_eye", None),
            getattr(args, "camera_look_at", None),
            getattr(args, "camera_up", None),
            getattr(args, "fov", None),
            view=getattr(args, "view", None),
        )

    def label(self, name: str) -> str:
        """How the user spelled setting ``name`` (a keyword such as ``camera_eye``)."""
        return name if self.keywords else "--" + name.replace("_", "-")

    def respell(self, message: str) -> str:
        """A message naming command-line options, in the user's spelling."""
        if self.keywords:
            for option in ("camera-eye", "camera-look-at", "camera-up", "fov", "format", "view"):
                message = message.replace("--" + option, option.replace("-", "_"))
        return message

    def checked(self) -> CameraOverrides:
        """The overrides with every given vector three finite numbers within the
        coordinate limit and the fov a valid angle; else InputError."""
        from bsrt import validate

        vectors = {}
        for name in ("eye", "look_at", "up"):
            value = getattr(self, name)
            if value is not None:
                vectors[name] = _vector(self.label(f"camera_{name}"), value)
        fov = None if self.fov is None else validate.fov(self.fov, self.label("fov"))
        if self.view is not None:
            from bsrt.scene.auto import VIEW_NAMES

            if self.view not in VIEW_NAMES:
                raise InputError(f"{self.label('view')}: expected one of {', '.join(VIEW_NAMES)}, got {self.view!r}")
        return replace(self, fov=fov, **vectors)


def _vector(key: str, value) -> tuple:
    from bsrt import validate

    try:
        v = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        v = None
    if v is None or v.shape != (3,) or isinstance(value, str) or not np.all(np.isfinite(v)):
        raise InputError(f"{key}: expected three finite numbers like (1, 2, 3), got {value!r}")
    validate.numbers(key, value, validate.MAX_COORDINATE)
    return tuple(float(x) for x in v)


def load_input(
    path,
    format: str = "auto",
    *,
    width: int | None = None,
    height: int | None = None,
    camera: CameraOverrides = CameraOverrides(),
    cache: bool = True,
    progress=None,
):
    """A Scene from a scene file, or from a model file with an automatic camera.

    cache: use the converted-model cache (``bsrt.io.load_model``). progress:
    a render's ``progress(stage, fraction)``, told stage "load" with the
    fraction of faces converted (bsrt/progress.py).

    ``width``/``height`` frame a model's automatic camera (default 512); a
    scene keeps its own film (the render options override it later). The
    caller reports ``scene.notes`` (import warnings) once. Every message
    names the settings as ``camera`` spells them (options or keywords).
    """
    from bsrt.progress import load_reporter
    from bsrt.scene import load_scene, scene_for_model

    faces = load_reporter(progress)
    camera = camera.checked()
    if not isinstance(format, str):
        raise InputError(f"{camera.label('format')}: expected a string, got {format!r}")
    path = check_input_file(path, "scene or model file")
    if path.suffix.lower() == ".toml":
        if format != "auto":
            raise InputError(f"{camera.label('format')}: only for model files; {path.name} is a scene file (.toml)")
        scene = load_scene(path, cache=cache, progress=faces, film_size=(width, height) if width and height else None)
        if camera.view is not None:
            scene = _fitted_view(scene, camera, width, height)
        return _override_camera(scene, camera)
    from bsrt.io import load_model

    model = load_model(path, format, cache=cache, progress=faces)
    try:
        return scene_for_model(
            model,
            width or 512,
            height or 512,
            camera.eye,
            camera.look_at,
            camera.fov,
            camera.up or (0.0, 0.0, 1.0),
            view=camera.view,
            turntable=camera.turntable,
        )
    except InputError as exc:
        raise InputError(camera.respell(str(exc))) from None


def _fitted_view(scene, overrides: CameraOverrides, width, height):
    """The scene seen along the named view (or framed for a turntable) by the automatic camera,
    fitted to its surfaces and the film (width, height, else the scene's)."""
    from bsrt.scene.auto import DEFAULT_FOV, fit_camera, surface_points

    camera = fit_camera(
        surface_points([s.geometry for s in scene.surfaces]),
        width or scene.film.width,
        height or scene.film.height,
        overrides.view or "default",
        overrides.up or (0.0, 0.0, 1.0),
        overrides.fov or DEFAULT_FOV,
        overrides.turntable,
    )
    return replace(scene, camera=camera)


def _override_camera(scene, overrides: CameraOverrides):
    cam = scene.camera
    pick = lambda given, own: own if given is None else np.array(given, dtype=np.float64)  # noqa: E731
    camera = replace(
        cam,
        eye=pick(overrides.eye, cam.eye),
        look_at=pick(overrides.look_at, cam.look_at),
        up=pick(overrides.up, cam.up),
        fov=cam.fov if overrides.fov is None else overrides.fov,
    )
    view = camera.look_at - camera.eye
    if np.linalg.norm(view) == 0 or np.linalg.norm(np.cross(view, camera.up)) < 1e-9 * np.linalg.norm(view):
        names = " / ".join(overrides.label(f"camera_{n}") for n in ("eye", "look_at", "up"))
        raise InputError(f"{names}: the view direction must not be zero or parallel to up")
    return replace(scene, camera=camera)

"""Checks shared by every entry point (scene files, model files, the command
line, the Python API): types, finiteness, ranges, sizes and the limits of the
"Limits" of docs/scene-format.md, applied once, before any work starts.

Every function raises :class:`InputError` whose message starts with the key it
was given (``"points: ..."``); callers prefix the file and table or line.
A boolean is never a number, a string never a knot.
"""

from __future__ import annotations

import math
import os

import numpy as np

from bsrt.errors import InputError

# The limits (docs/scene-format.md, "Limits"), each with its reason there.
MAX_COORDINATE = 1e15  # |x|, |y|, |z| of points, eye, look_at, lights, translations
MAX_DEGREE = 25  # OpenCASCADE's Geom_BSplineSurface::MaxDegree() (docs/scene-format.md, Limits)
CHECKED_DEGREE = (
    9  # above this, the power-basis evaluation is measured against the reference (docs/scene-format.md, Limits)
)
MAX_WEIGHT_RATIO = 1e12  # largest / smallest weight of one surface
MAX_SPP = 256  # 8-bit output: a coverage step finer than 1/256 cannot show
MAX_ITERATIONS = 10_000  # root finders converge in tens of steps
MAX_DEPTH = 16  # mirror bounces
MAX_FILM_SIDE = 65_536  # pixels along a side
BYTES_PER_PIXEL = 120  # peak memory of a render per film pixel (4096 x 4096 peaks at 1.98 GB)
MIN_FOV, MAX_FOV = 1e-3, 180.0  # degrees, the upper end open
FLOAT_STEPS = 64  # a tolerance must span this many float64 steps (eps) of the scene's coordinates


def whole(key: str, value, lo: int, hi: int) -> int:
    """``value`` as an int in [lo, hi]; booleans, floats and strings refused."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
        raise InputError(f"{key}: expected a whole number >= {lo}, got {show(value)}")
    if value > hi:
        raise InputError(f"{key}: must be at most {hi} (see Limits in docs/scene-format.md), got {show(value)}")
    return int(value)


def real(
    key: str,
    value,
    lo: float | None = None,
    hi: float | None = None,
    lo_open=False,
    hi_open=False,
    expected: str | None = None,
) -> float:
    """``value`` as a finite float in [lo, hi] (open ends with lo_open / hi_open); ``expected``
    replaces the message's own description of the range ("a number in (0, 1]")."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{key}: expected {expected or 'a number'}, got {show(value)}")
    number = float(value) if abs(value) < 1e300 or isinstance(value, (float, np.floating)) else math.inf
    if not math.isfinite(number):
        raise InputError(f"{key}: expected {expected or 'a finite number'}, got {show(value)}")
    if lo is not None and (number < lo or (lo_open and number == lo)):
        raise InputError(
            f"{key}: expected {expected}, got {show(value)}"
            if expected
            else f"{key}: must be {'>' if lo_open else '>='} {lo:g}, got {number:g}"
        )
    if hi is not None and (number > hi or (hi_open and number == hi)):
        raise InputError(
            f"{key}: expected {expected}, got {show(value)}"
            if expected
            else f"{key}: must be {'<' if hi_open else '<='} {hi:g}, got {number:g}"
        )
    return number


def numbers(key: str, values, limit: float | None = None, check=True) -> np.ndarray:
    """float64 array of nested lists of numbers: booleans, strings and other
    objects refused; with ``check``, every value finite and (with ``limit``) |value| <= limit."""
    if isinstance(values, np.ndarray):
        if values.dtype == bool or not (np.issubdtype(values.dtype, np.number)):
            raise InputError(f"{key}: expected numbers, got an array of {values.dtype}")
    else:
        _only_numbers(key, values)
    try:
        with np.errstate(all="ignore"):
            array = np.array(values, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{key}: expected a regular grid of numbers (every row the same length)") from None
    if check:
        finite(key, array, limit)
    return array


def _only_numbers(key: str, values) -> None:
    stack = [values]
    while stack:  # iterative: a deeply nested list is refused, not a RecursionError
        x = stack.pop()
        if isinstance(x, (list, tuple)):
            if len(stack) > 1_000_000:
                raise InputError(f"{key}: too many values")
            stack.extend(x)
        elif isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)):
            raise InputError(f"{key}: expected numbers, got {show(x)}")
        elif isinstance(x, int) and abs(x) > 1e300:
            raise InputError(f"{key}: {show(x)} is too large")


def finite(key: str, array: np.ndarray, limit: float | None = None) -> None:
    """All values finite and (with ``limit``) of magnitude <= limit."""
    bad = ~np.isfinite(array)
    if bad.any():
        raise InputError(f"{key}: value {_index(bad)} is not a finite number")
    if limit is not None and array.size:
        big = np.abs(array) > limit
        if big.any():
            raise InputError(
                f"{key}: value {_index(big)} ({array[big].flat[0]:g}) is beyond +-{limit:g} "
                "(see Limits in docs/scene-format.md)"
            )


def _index(mask: np.ndarray) -> str:
    return str(list(map(int, np.argwhere(mask)[0]))) if mask.ndim > 1 else str(int(np.argmax(mask)))


def surface(geometry) -> None:
    """A built BSplineSurface within the limits: degree, coordinates, weights, knots."""
    p, q = geometry.degree
    if max(p, q) > MAX_DEGREE:
        raise InputError(f"degree: at most {MAX_DEGREE} (see Limits in docs/scene-format.md), got [{p}, {q}]")
    finite("points", geometry.points, MAX_COORDINATE)
    finite("knots_u", geometry.knots_u, MAX_COORDINATE)
    finite("knots_v", geometry.knots_v, MAX_COORDINATE)
    if geometry.weights is not None:
        w = geometry.weights
        finite("weights", w)
        if w.min() <= 0 or w.max() / w.min() > MAX_WEIGHT_RATIO:
            raise InputError(
                f"weights: must be > 0, the largest at most {MAX_WEIGHT_RATIO:g} times the smallest; "
                f"got {w.min():g} .. {w.max():g}"
            )


def camera(cam) -> None:
    """A camera whose frame and field of view are computable: eye, look_at and up
    within the coordinate limit, fov in [MIN_FOV, MAX_FOV], up not along the view."""
    for key in ("eye", "look_at", "up"):
        finite(f"camera.{key}", np.asarray(getattr(cam, key), dtype=np.float64), MAX_COORDINATE)
    fov(cam.fov, "camera.fov")
    view = np.asarray(cam.look_at, float) - np.asarray(cam.eye, float)
    size = np.linalg.norm(view)
    if size == 0 or size < 1e-12 * max(np.abs(cam.eye).max(), np.abs(cam.look_at).max()):
        raise InputError("camera.look_at: must differ from eye (by more than float64 resolves)")
    up = np.asarray(cam.up, float)
    if np.linalg.norm(up) == 0:
        raise InputError("camera.up: must not be the zero vector")
    if np.linalg.norm(np.cross(view / size, up / np.linalg.norm(up))) < 1e-9:
        raise InputError("camera.up: must not be parallel to the view direction (look_at - eye)")


def fov(value, key: str = "fov") -> float:
    """A field of view in degrees: a number in [MIN_FOV, 180)."""
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not 0.0 < float(value) < MAX_FOV
    ):
        shown = show(value) if isinstance(value, bool) or not isinstance(value, (int, float)) else f"{value:g}"
        raise InputError(f"{key}: must be between 0 and 180 degrees, got {shown}")
    value = float(value)
    if value < MIN_FOV:
        raise InputError(
            f"{key}: must be at least {MIN_FOV:g} degrees (see Limits in docs/scene-format.md), got {value:g}"
        )
    return value


def film(width: int, height: int) -> None:
    """The film's memory: at most the machine's physical memory."""
    need = BYTES_PER_PIXEL * width * height
    have = physical_memory()
    if have and need > have:
        raise InputError(
            f"film: {width} x {height} pixels would need about {need / 1e9:.3g} GB of memory "
            f"(~{BYTES_PER_PIXEL} bytes per pixel); this machine has {have / 1e9:.3g} GB"
        )


def physical_memory() -> int:
    """Bytes of physical memory (0 if unknown)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 0


def smallest_tolerance(surfaces, eye) -> float:
    """The smallest [render].tolerance float64 resolves for these surfaces seen from eye:
    FLOAT_STEPS steps (eps) of the largest coordinate, as a fraction of the scene's diagonal
    (above 1: no tolerance is usable)."""
    lo, hi = _box(surfaces)
    diagonal = float(np.linalg.norm(hi - lo))
    reach = max(float(np.abs(lo).max()), float(np.abs(hi).max()), float(np.abs(np.asarray(eye)).max()))
    if diagonal == 0:  # a scene that is one point: no size to resolve against, nothing to refuse
        return 0.0
    return FLOAT_STEPS * np.finfo(np.float64).eps * reach / diagonal


def environment() -> None:
    """The environment variables bsrt reads: an EGL device index is a whole number >= 0."""
    for name in ("BSRT_EGL_DEVICE", "GLCONTEXT_DEVICE_INDEX"):
        value = os.environ.get(name)
        if value is not None and not (value.strip().isascii() and value.strip().isdigit()):
            raise InputError(
                f"environment variable {name}: expected an EGL device index (0, 1, ...), got {show(value)}"
            )


def show(value) -> str:
    """A short repr for messages."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def evaluation_error(surface, samples: int = 4) -> float:
    """Largest distance between the patch table's power-basis evaluation and the
    reference (de Boor) evaluator, on a samples x samples grid inside each of the
    surface's Bezier patches. The power basis loses digits as about 3^degree,
    so above CHECKED_DEGREE this is measured, not assumed."""
    from bsrt.geometry.bspline import evaluate
    from bsrt.geometry.patches import PatchSet

    patches = PatchSet([surface])
    b = patches.bounds  # (P, 4): u0, u1, v0, v1
    s = (np.arange(samples) + 0.5) / samples
    su, sv = (x.ravel() for x in np.meshgrid(s, s, indexing="ij"))
    u = (b[:, :1] + (b[:, 1:2] - b[:, :1]) * su).ravel()
    v = (b[:, 2:3] + (b[:, 3:4] - b[:, 2:3]) * sv).ravel()
    patch = np.repeat(np.arange(len(b)), su.size)
    got = patches.evaluate(patch, u, v, derivatives=False).T
    return float(np.abs(got - evaluate(surface, u, v)[0]).max())


def smallest_tolerance_of_high_degrees(surfaces, names, diagonal: float):
    """(tolerance, name, degree) of the surface above CHECKED_DEGREE whose measured
    evaluation error, as a fraction of the scene's diagonal, is largest; None if none."""
    worst = None
    for surface, name in zip(surfaces, names):
        if max(surface.degree) <= CHECKED_DEGREE or diagonal == 0:
            continue
        error = 4.0 * evaluation_error(surface) / diagonal
        if worst is None or error > worst[0]:
            worst = (error, name, list(surface.degree))
    return worst


def _box(surfaces):
    lo = np.min([s.points.reshape(-1, 3).min(axis=0) for s in surfaces], axis=0)
    hi = np.max([s.points.reshape(-1, 3).max(axis=0) for s in surfaces], axis=0)
    return lo, hi


def diagonal(surfaces) -> float:
    """The diagonal of the control points' box (the scene size tolerances are fractions of)."""
    lo, hi = _box(surfaces)
    return float(np.linalg.norm(hi - lo))

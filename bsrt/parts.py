"""The parts of a scene built in Python: :class:`Camera`, :class:`Light`, :class:`Surface`,
:class:`Import`, and Splipy / geomdl surfaces. Re-exported by :mod:`bsrt.api` and the package.

Values are kept as given and checked when the scene is built (:meth:`bsrt.Scene.build`), with
the messages of a scene file.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace

import numpy as np

from bsrt import scene as _scene
from bsrt.geometry.bspline import BSplineSurface
from bsrt.scene import Material
from bsrt.scene.camera import Camera as _Camera
from bsrt.scene.document import is_array_like, surface_doc

WHERE = "<python>"  # the "file name" in the messages about a scene built in Python

ArrayLike = np.ndarray | Sequence
Vector3 = np.ndarray | Sequence[float]

_PROBE_CAMERA = {"eye": [0.0, -1.0, 0.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 0.0, 1.0]}
_PROBE_SURFACE = {
    "degree": [1, 1],
    "knots_u": [0.0, 0.0, 1.0, 1.0],
    "knots_v": [0.0, 0.0, 1.0, 1.0],
    "points": [[[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0], [1.0, 0.0, 1.0]]],
}


class Camera(_Camera):
    """A pinhole camera, as the scene format's ``[camera]`` table.

    eye, look_at: (3,) points; up: (3,) direction, default +z (need not be
    orthogonal to the view, must not be parallel to it); fov: full angle in
    degrees, 0 < fov < 180, along fov_axis ("y": vertical, or "x").
    Array-likes are stored as (3,) float64 arrays; the values are checked
    when the camera is used (:meth:`Scene.build`, :func:`render`), with the
    messages of a scene file.
    """

    def __init__(
        self, eye: Vector3, look_at: Vector3, up: Vector3 = (0.0, 0.0, 1.0), fov: float = 40.0, fov_axis: str = "y"
    ):
        for key, value in (("eye", eye), ("look_at", look_at), ("up", up)):
            object.__setattr__(self, key, _as_vector3(value))
        object.__setattr__(self, "fov", fov)
        object.__setattr__(self, "fov_axis", fov_axis)


class Light(_scene.Light):
    """A light, as a ``[[light]]`` table: ``Light(kind, color, intensity, position, direction)``.

    Easier through the constructors :meth:`point`, :meth:`directional` and
    :meth:`ambient`. Colours are linear RGB; ``color * intensity`` is the
    strength (a point light falls off with the square of the distance).
    Equal to a :class:`bsrt.scene.Light` with the same values.
    """

    @classmethod
    def point(cls, position: Vector3, color: Vector3 = (1.0, 1.0, 1.0), intensity: float = 1.0) -> Light:
        """A point light at ``position`` (3,)."""
        return cls("point", _as_tuple(color), intensity, position=_as_tuple(position))

    @classmethod
    def directional(cls, direction: Vector3, color: Vector3 = (1.0, 1.0, 1.0), intensity: float = 1.0) -> Light:
        """A distant light whose light travels along ``direction`` (3,) (no falloff)."""
        return cls("directional", _as_tuple(color), intensity, direction=_as_tuple(direction))

    @classmethod
    def ambient(cls, color: Vector3 = (1.0, 1.0, 1.0), intensity: float = 1.0) -> Light:
        """Light from everywhere: adds ``color * intensity * albedo`` to every visible point."""
        return cls("ambient", _as_tuple(color), intensity)

    def __eq__(self, other):
        if isinstance(other, _scene.Light):
            return all(getattr(self, f.name) == getattr(other, f.name) for f in fields(_scene.Light))
        return NotImplemented

    __hash__ = _scene.Light.__hash__


@dataclass(frozen=True, eq=False)
class Surface:
    """One B-spline (or NURBS) surface, as a ``[[surface]]`` table.

    degree: (p, q), each >= 1 (degree, not order).
    knots_u: (nu + p + 1,) non-decreasing; knots_v: (nv + q + 1,).
    points: (nu, nv, 3), points[i, j] = P(i, j), i along u.
    weights: (nu, nv), all > 0, or None (not rational).
    material: the name of a material of the scene, or a :class:`Material`
      (added to the scene's materials); color: (3,) linear RGB instead of a
      material; neither: a default grey.
    name: a label (default ``surface-<index>``).
    trims: trim loops in the surface's (u, v) domain, each a sequence of
      curves ``{"degree": p, "knots": (n + p + 1,), "points": (n, 2),
      "weights": (n,) or None}`` (mappings, or objects with those
      attributes, such as :class:`bsrt.geometry.trim.TrimCurve`); see docs/scene-format.md,
      "Trimmed surfaces" (even-odd rule).
    transform: ``{"scale": s or (3,), "rotate": (ax, ay, az, degrees),
      "translate": (3,)}``, applied in that order.

    Values are kept as given and checked when the scene is built, with the
    messages of a scene file. Other libraries' surfaces: :meth:`from_object`.
    """

    degree: tuple[int, int]
    knots_u: ArrayLike
    knots_v: ArrayLike
    points: ArrayLike
    weights: ArrayLike | None = None
    material: str | Material | None = None
    color: Vector3 | None = None
    name: str | None = None
    trims: Sequence = ()
    transform: Mapping | None = None

    @classmethod
    def from_object(cls, obj, **kwargs) -> Surface:
        """A Surface from a Splipy ``Surface`` (``TrimmedSurface``: with its loops),
        a geomdl ``BSpline.Surface`` / ``NURBS.Surface``, a :class:`bsrt.geometry.bspline.BSplineSurface`
        or a scene's :class:`bsrt.scene.SceneSurface` (its geometry and name; its
        material is an index into its own scene's materials, so give
        ``material=``); recognised by their attributes (neither library is
        imported). kwargs: the other fields (material, color, name,
        transform, trims)."""
        from bsrt.adapters import object_fields

        if isinstance(obj, Surface):
            return replace(obj, **kwargs)
        return cls(**{**object_fields(obj, trims_given="trims" in kwargs), **kwargs})

    def geometry(self) -> BSplineSurface:
        """The checked surface (transform applied, trims attached), as the
        renderer holds it; errors are the scene format's, for ``surface[0]``."""
        table = {k: v for k, v in surface_doc(self, []).items() if k not in ("material", "color")}
        probe = {"camera": _PROBE_CAMERA, "surface": [table]}
        return _scene.parse_scene(probe, WHERE).surfaces[0].geometry

    def __repr__(self) -> str:
        shape = np.shape(self.points) if is_array_like(self.points) else "?"
        extra = "".join(
            [
                ", rational" if self.weights is not None else "",
                f", {len(self.trims)} trim loop(s)" if self.trims else "",
                f", name={self.name!r}" if self.name is not None else "",
            ]
        )
        degree = tuple(self.degree) if is_array_like(self.degree) else self.degree
        return f"Surface(degree={degree!r}, points {shape}{extra})"


@dataclass(frozen=True)
class Import:
    """Surfaces from a model file, as an ``[[import]]`` table: every surface of
    ``file`` (relative to ``folder`` of :meth:`Scene.build`, default the
    current folder), with ``material`` and ``transform`` as for a Surface."""

    file: str | os.PathLike
    format: str = "auto"
    material: str | Material | None = None
    transform: Mapping | None = None


def from_splipy(surface, **kwargs) -> Surface:
    """A :class:`Surface` from a Splipy ``Surface`` or ``TrimmedSurface`` (its loops as trims).
    kwargs: the other Surface fields (material, color, name, transform, trims to replace the loops)."""
    from bsrt.adapters import splipy_fields

    return Surface(**{**splipy_fields(surface), **kwargs})


def from_geomdl(surface, **kwargs) -> Surface:
    """A :class:`Surface` from a geomdl ``BSpline.Surface`` or ``NURBS.Surface``.
    kwargs: the other Surface fields (material, color, name, transform, trims)."""
    from bsrt.adapters import geomdl_fields

    return Surface(**{**geomdl_fields(surface, trims_given="trims" in kwargs), **kwargs})


def _as_vector3(value):
    try:
        v = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        return value  # checked (and refused) when the camera is used
    return v if v.shape == (3,) and not isinstance(value, str) else value


def _as_tuple(value):
    try:
        return tuple(float(x) for x in value)
    except (TypeError, ValueError):
        return value  # checked (and refused) when the scene is built

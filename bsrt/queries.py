"""Exact ray queries: :func:`intersect` (re-exported as ``bsrt.intersect``; docs/ray-queries.md).

The scene is anything :func:`bsrt.render` accepts. Its geometry (patch table,
hierarchy, orientations) is prepared once per scene object and reused by
later calls (a model file's path: per file, while it is unchanged); the
work itself is ``bsrt.rendering.raycast``.
"""

from __future__ import annotations

import math
import os
import weakref
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bsrt.errors import InputError

MODES = ("nearest", "any", "all")
DEFAULT_TOLERANCE = 1e-9

_BY_SCENE: dict[int, tuple[weakref.ref, Any]] = {}  # id(scene) -> (its weak reference, RayCaster)
_BY_FILE: dict[tuple, tuple[Any, Any]] = {}  # (real path, size, mtime, format) -> (scene, RayCaster)
_FILES_KEPT = 2


@dataclass(eq=False)
class Intersections:
    """What :func:`intersect` found. K records: one per ray (modes "nearest", "any"; K = N) or
    one per hit (mode "all"; K = M, sorted by ray, then t).

    hit: (K,) bool (mode "all": all True). t: (K,) float64, distance along the
    unit direction (scene units). point: (K, 3) float64, S(u, v). normal:
    (K, 3) float64, the unit outward normal as modelled (a B-rep face's
    orientation; else S_u x S_v). front_facing: (K,) bool, the outward normal
    faces the ray's origin (False where no hit). u, v: (K,) float64, the
    surface's own parameters. surface: (K,) int64, index into ``names``
    (-1 where no hit). residual: (K,) float64, |S(u, v) - (o + t d)| in
    scene units. ray: (K,) int64, the ray of each record. offsets: (N + 1,)
    int64, ray i's records are offsets[i]:offsets[i + 1]. exhausted: (N,)
    bool, the rays that spent their work budget (module rendering/raycast.py:
    64 times a rendered ray's; none on ordinary parts): their records may
    lack a hit. names: (S,) the
    surfaces' names (a STEP file's ``FILE:ASSEMBLY/.../PART#k``, an IGES
    label, a scene surface's name). Floats are NaN where there is no hit.
    mode, tolerance (fraction of the diagonal) and diagonal (scene units):
    how it was asked.
    """

    hit: np.ndarray
    t: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    front_facing: np.ndarray
    u: np.ndarray
    v: np.ndarray
    surface: np.ndarray
    residual: np.ndarray
    ray: np.ndarray
    offsets: np.ndarray
    exhausted: np.ndarray
    names: tuple[str, ...] = field(repr=False)
    mode: str = "nearest"
    tolerance: float = DEFAULT_TOLERANCE
    diagonal: float = 1.0

    def __len__(self) -> int:
        return int(self.hit.shape[0])

    @property
    def count(self) -> np.ndarray:
        """(N,) int64: records per ray (hits per ray for mode "all")."""
        return np.diff(self.offsets)

    def surface_names(self) -> list[str | None]:
        """The name of each record's surface (None where no hit)."""
        return [self.names[s] if s >= 0 else None for s in self.surface.tolist()]

    def __repr__(self) -> str:
        n = self.offsets.shape[0] - 1
        return f"<Intersections {self.mode}: {int(self.hit.sum())} hits of {n} rays on {len(self.names)} surfaces>"


def intersect(
    scene,
    origins,
    directions,
    *,
    t_min=0.0,
    t_max=math.inf,
    mode: str = "nearest",
    tolerance: float | None = None,
) -> Intersections:
    """Exact hits of N rays with a scene's (trimmed) surfaces.

    scene: what :func:`bsrt.render` accepts (a Scene, a scene or model file,
    surfaces). origins: (N, 3) or (3,) (one origin for every ray);
    directions: (N, 3), need not be unit (t is measured along the unit
    direction). t_min, t_max: scalars or (N,); a hit has t_min < t < t_max.
    mode: "nearest" (the nearest hit), "any" (occlusion: some hit, faster; its
    t is not necessarily the nearest), "all" (every hit, sorted by t).
    tolerance: largest ray-surface distance of a hit, a fraction of the
    scene's diagonal (default 1e-9; down to 1e-13 by a float64 Newton polish).

    Returns :class:`Intersections`. Raises InputError (a ValueError) for bad
    arrays (naming the argument and the first bad row), a bad mode or
    tolerance, or a scene without surfaces; N = 0 gives an empty result.
    """
    from bsrt.rendering.raycast import MIN_TOLERANCE
    from bsrt.validate import real

    if mode not in MODES:
        raise InputError(f"mode: expected one of {', '.join(map(repr, MODES))}, got {mode!r}")
    if tolerance is None:
        tolerance = DEFAULT_TOLERANCE
    tolerance = real("tolerance", tolerance, 0.0, 1.0, lo_open=True, expected="a number in (0, 1]")
    if tolerance < MIN_TOLERANCE:
        raise InputError(
            f"tolerance: {tolerance:g} of the diagonal is below what float64 can give; the least is {MIN_TOLERANCE:g}"
        )
    d = _rays("directions", directions)
    n = d.shape[0]
    o = given = _rays("origins", origins, allow_single=True)
    if o.shape[0] == 1 and n != 1:
        o = np.broadcast_to(o, (n, 3))
    elif o.shape[0] != n:
        raise InputError(f"origins: {o.shape[0]} rows do not match directions: {n} rows")
    length = np.linalg.norm(d, axis=1)
    zero = np.flatnonzero(~(length > 0.0))
    if zero.size:
        raise InputError(f"directions: row {zero[0]} is zero")
    unit = d / length[:, None]
    lo, hi = _bound("t_min", t_min, n), _bound("t_max", t_max, n)
    wrong = np.flatnonzero(~(lo < hi))
    if wrong.size:
        raise InputError(f"t_min, t_max: row {wrong[0]} has t_min {lo[wrong[0]]:g} >= t_max {hi[wrong[0]]:g}")
    scene, caster = prepared(scene)
    least = caster.least_tolerance(given)
    if tolerance < least:
        worst = caster.high_degree
        where = f" (surface {worst[1]!r} of degree {worst[2]})" if worst and worst[0] >= least else ""
        raise InputError(
            f"tolerance: {tolerance:g} of the diagonal is below what float64 can give for this scene and these "
            f"origins{where}; the least is {least:.2g}"
        )
    names = tuple(s.name for s in scene.surfaces)
    found, exhausted = caster.cast(np.ascontiguousarray(o), unit, lo, hi, tolerance, mode)
    ranks = np.arange(n + 1, dtype=np.int64)  # nearest and any: one record per ray
    offsets = np.searchsorted(found.ray, ranks).astype(np.int64) if mode == "all" else ranks
    return Intersections(
        found.hit,
        found.t,
        found.point,
        found.normal,
        found.front_facing,
        found.u,
        found.v,
        found.surface,
        found.residual,
        found.ray,
        offsets,
        exhausted,
        names,
        mode,
        tolerance,
        caster.diagonal,
    )


def prepared(scene):
    """(Scene, RayCaster) for what :func:`bsrt.render` accepts, from the cache when the same scene
    object (or the same unchanged model file) was prepared before."""
    from bsrt import scene as _scene
    from bsrt.rendering.raycast import RayCaster

    if isinstance(scene, (str, os.PathLike)):
        from bsrt.api import load

        path = os.fspath(scene)
        try:
            stat = os.stat(path)
            key = (os.path.realpath(path), stat.st_size, stat.st_mtime_ns)
        except OSError:
            key = None
        if key in _BY_FILE:
            return _BY_FILE[key]
        loaded = load(path)
        _no_surfaces(loaded)
        entry = (loaded, RayCaster(loaded))
        if key is not None:
            while len(_BY_FILE) >= _FILES_KEPT:
                del _BY_FILE[next(iter(_BY_FILE))]
            _BY_FILE[key] = entry
        return entry
    if not isinstance(scene, _scene.Scene):
        from bsrt.api import Scene

        items = scene if isinstance(scene, (list, tuple)) else [scene]
        if isinstance(items, Iterable) and not len(items):
            raise InputError("scene: has no surfaces to intersect")
        scene = Scene.build(items)
    key = id(scene)
    entry = _BY_SCENE.get(key)
    if entry is not None and entry[0]() is scene:
        return scene, entry[1]
    _no_surfaces(scene)
    caster = RayCaster(scene)
    _BY_SCENE[key] = (weakref.ref(scene, lambda _, key=key: _BY_SCENE.pop(key, None)), caster)
    return scene, caster


def _no_surfaces(scene) -> None:
    if not scene.surfaces:
        raise InputError(f"{getattr(scene, 'path', '<scene>')}: has no surfaces to intersect")


def _rays(name: str, value, allow_single: bool = False) -> np.ndarray:
    """value as an (N, 3) float64 array with finite rows, else an InputError naming ``name``."""
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as e:
        raise InputError(f"{name}: expected an (N, 3) array of numbers ({e})") from None
    if a.dtype.kind not in "fiu":
        raise InputError(f"{name}: expected an (N, 3) array of numbers, got dtype {a.dtype}")
    if allow_single and a.shape == (3,):
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != 3:
        raise InputError(f"{name}: expected shape (N, 3), got {a.shape}")
    a = np.asarray(a, dtype=np.float64)
    bad = np.flatnonzero(~np.isfinite(a).all(axis=1))
    if bad.size:
        raise InputError(f"{name}: row {bad[0]} is not finite ({a[bad[0]].tolist()})")
    return a


def _bound(name: str, value, n: int) -> np.ndarray:
    """t_min / t_max as an (N,) float64 array (a scalar broadcast), no NaN; else an InputError."""
    try:
        a = np.asarray(value)
    except (TypeError, ValueError):
        a = np.asarray(None)
    if a.dtype.kind not in "fiu" or a.ndim > 1 or (a.ndim == 1 and a.shape[0] != n):
        raise InputError(f"{name}: expected a number or ({n},) numbers, got {np.shape(value)} of {a.dtype}")
    a = np.array(np.broadcast_to(a.astype(np.float64), (n,)))
    bad = np.flatnonzero(np.isnan(a))
    if bad.size:
        raise InputError(f"{name}: row {bad[0]} is NaN")
    return a

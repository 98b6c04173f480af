"""bsrt: direct ray tracing of B-spline and trimmed NURBS surfaces.

The Python API (docs/python-api.md)::

    import bsrt
    scene = bsrt.load("scenes/column.toml", width=256, height=256)
    result = bsrt.render(scene)            # a notebook shows it as an image
    result.save("column.png")

``bsrt.load``, ``bsrt.render``, ``bsrt.Scene`` (``Scene.build``,
``to_toml``, ``save``), ``bsrt.Surface``, ``bsrt.Camera``, ``bsrt.Light``,
``bsrt.Material``, ``bsrt.Film``, ``bsrt.Import``, ``bsrt.from_splipy``,
``bsrt.from_geomdl``; ``bsrt.intersect`` and ``bsrt.sensors`` (exact ray
queries, docs/ray-queries.md); ``bsrt.batch`` and ``bsrt.animate`` (many renders
on Dask, the extra ``bsrt[dask]``). They are imported on first use, so ``import bsrt``
stays fast (NumPy, OpenGL and the compiled kernels load when needed).

The rendering pipeline itself is ``bsrt.rendering.pipeline`` (``render(scene,
options)``, ``Geometry``, ``RenderResult``).
"""

from __future__ import annotations

import importlib as _importlib

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (5 ms); checkers know the name

__version__ = "0.3.0"

_LAZY = {
    "load": "api",
    "Scene": "api",
    "Surface": "api",
    "Camera": "api",
    "Light": "api",
    "Material": "api",
    "Film": "api",
    "RenderSettings": "api",
    "Import": "api",
    "from_splipy": "api",
    "from_geomdl": "api",
    "InputError": "errors",
    "RenderError": "errors",
    "render": "api",
    "RenderResult": "rendering.pipeline",
    "intersect": "queries",
    "Intersections": "queries",
    "batch": "batches.api",
    "animate": "batches.api",
}

_MODULES = ("sensors",)  # submodules imported on first use: bsrt.sensors.lidar(...)

__all__ = sorted([*_LAZY, *_MODULES, "__version__"])

if TYPE_CHECKING:  # what type checkers and IDEs see (the names of _LAZY)
    from bsrt import sensors
    from bsrt.api import (
        Camera,
        Film,
        Import,
        Light,
        Material,
        RenderSettings,
        Scene,
        Surface,
        from_geomdl,
        from_splipy,
        load,
        render,
    )
    from bsrt.batches.api import animate, batch
    from bsrt.errors import InputError, RenderError
    from bsrt.queries import Intersections, intersect
    from bsrt.rendering.pipeline import RenderResult


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(_importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    if name in _MODULES:
        return _importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))

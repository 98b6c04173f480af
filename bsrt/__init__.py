"""bsrt: direct ray tracing of B-spline and trimmed NURBS surfaces.

The Python API (docs/python-api.md)::

    import bsrt
    scene = bsrt.load("scenes/column.toml", width=256, height=256)
    result = bsrt.render(scene)            # a notebook shows it as an image
    result.save("column.png")

``bsrt.load``, ``bsrt.render``, ``bsrt.Scene`` (``Scene.build``,
``to_toml``, ``save``), ``bsrt.Surface``, ``bsrt.Camera``, ``bsrt.Light``,
``bsrt.Material``, ``bsrt.Film``, ``bsrt.Import``, ``bsrt.from_splipy``,
``bsrt.from_geomdl``. They are imported on first use, so ``import bsrt``
stays fast (NumPy, OpenGL and the compiled kernels load when needed).

``bsrt.render`` is also the name of the pipeline module (``bsrt/render.py``,
``from bsrt.render import Geometry``): that module is callable, and calling
it is the API's :func:`bsrt.api.render`.
"""

from __future__ import annotations

import importlib as _importlib
import sys as _sys
import types as _types

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (5 ms); checkers know the name

__version__ = "0.2.0"

_LAZY = {
    "load": "api", "Scene": "api", "Surface": "api", "Camera": "api", "Light": "api", "Material": "api",
    "Film": "api", "RenderSettings": "api", "Import": "api",
    "from_splipy": "adapters", "from_geomdl": "adapters",
    "InputError": "errors", "RenderError": "errors",
    "RenderResult": "render",
}

__all__ = [
    "Camera", "Film", "Import", "InputError", "Light", "Material", "RenderError", "RenderResult", "RenderSettings",
    "Scene", "Surface", "__version__", "from_geomdl", "from_splipy", "load", "render",
]

if TYPE_CHECKING:  # what type checkers and IDEs see
    from .adapters import from_geomdl, from_splipy
    from .api import Camera, Film, Import, Light, Material, RenderSettings, Scene, Surface, load, render
    from .errors import InputError, RenderError
    from .render import RenderResult


def __getattr__(name: str):
    if name == "render":
        return _importlib.import_module(".render", __name__)  # made callable on import (below)
    if name in _LAZY:
        value = getattr(_importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))


class _RenderModule(_types.ModuleType):
    """The class of the module ``bsrt.render``: calling it renders through the API."""

    def __call__(self, scene, *, width=None, height=None, method=None, spp=None, map=None, tolerance=None,
                 max_iterations=None, max_depth=None, camera=None, progress=None):
        """Render a scene: see :func:`bsrt.api.render`."""
        from .api import render

        return render(scene, width=width, height=height, method=method, spp=spp, map=map, tolerance=tolerance,
                      max_iterations=max_iterations, max_depth=max_depth, camera=camera, progress=progress)


class _Package(_types.ModuleType):
    # The import system binds every submodule to its package with setattr
    # once it is loaded, however it is imported ("Submodules" in the
    # language reference's import system chapter): that is where bsrt.render
    # becomes callable.
    def __setattr__(self, name, value):
        if name == "render" and type(value) is _types.ModuleType and value.__name__ == f"{__name__}.render":
            value.__class__ = _RenderModule
        super().__setattr__(name, value)


_sys.modules[__name__].__class__ = _Package

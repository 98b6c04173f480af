"""Compiling (or loading) every kernel up front, on a tiny scene, timed: ``bsrt doctor``."""

from __future__ import annotations

import time

import numpy as np

from bsrt.errors import InputError, RenderError
from bsrt.kernels.trim import kept_many
from bsrt.methods import METHODS, REFERENCE_METHOD
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import Geometry, render
from bsrt.scene import parse_scene


def warm_up() -> float:
    """Compile (or load) every kernel by rendering a tiny trimmed scene with each method and a
    shadow-casting light (GL included), and the AOVs once, and on the GPU path where the context
    can run it; returns the seconds it took."""
    square = [
        {"degree": 1, "knots": [0, 0, 1, 1], "points": [a, b]}
        for a, b in (
            ([0.2, 0.2], [0.8, 0.2]),
            ([0.8, 0.2], [0.8, 0.8]),
            ([0.8, 0.8], [0.2, 0.8]),
            ([0.2, 0.8], [0.2, 0.2]),
        )
    ]
    plate = {
        "degree": [1, 1],
        "knots_u": [0, 0, 1, 1],
        "knots_v": [0, 0, 1, 1],
        "points": [[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]]],
    }
    scene = parse_scene(
        {
            "film": {"width": 8, "height": 8},
            "camera": {"eye": [0.5, -1.0, 2.0], "look_at": [0.5, 0.5, 0.0]},
            "light": [{"kind": "point", "position": [0.5, 0.5, 3.0], "intensity": 9.0}],
            "material": [{"name": "mirror", "reflectance": 0.5}],
            "surface": [
                {**plate, "material": "mirror"},
                {**plate, "trim": [{"curves": square}], "transform": {"translate": [0.0, 0.0, 0.5]}},
            ],
        },
        "<warm-up>",
    )
    clock = time.perf_counter()
    for method in METHODS:
        result = render(scene, RenderOptions.resolve(scene, method=method))
    result.aovs()  # the AOVs' frames (--aov)
    try:  # the GPU path's own kernels (the hits of its roots, its shading), where it can run
        render(scene, RenderOptions.resolve(scene, method=REFERENCE_METHOD, device="gpu"))
    except (InputError, RenderError):  # no OpenGL 4.5 compute with float64 here
        pass
    # the trim test of points one by one: a model's automatic framing (scene/auto.py), --edges
    kept_many(Geometry(scene).patches.trims, np.array([1]), np.array([0.5]), np.array([0.5]))
    return time.perf_counter() - clock

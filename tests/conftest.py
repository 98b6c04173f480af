"""Shared fixtures. GL tests use a real headless context: if none can be
created the test fails (it is never skipped)."""

from __future__ import annotations

import numpy as np
import pytest

from bsrt import gl


@pytest.fixture(scope="session")
def ctx():
    """The process's headless EGL context (Mesa llvmpipe in CI)."""
    context = gl.headless_context()
    assert context.error == "GL_NO_ERROR"
    yield context
    assert context.error == "GL_NO_ERROR"


def scene_dict(surfaces, *, width=64, height=64, eye=(0.0, -4.0, 0.0), look_at=(0.0, 0.0, 0.0),
               up=(0.0, 0.0, 1.0), fov=40.0, method="newton", **render):
    """A minimal scene document (as tomllib would return it)."""
    return {
        "film": {"width": width, "height": height},
        "camera": {"eye": list(eye), "look_at": list(look_at), "up": list(up), "fov": fov},
        "render": {"method": method, **render},
        "light": [{"kind": "ambient", "intensity": 1.0}],
        "surface": surfaces,
    }


def flat_patch(x0=-1.0, x1=1.0, z0=-1.0, z1=1.0, y=0.0, degree=(1, 1), **extra):
    """A square in the plane y = const, as a [[surface]] table; u along x, v along z."""
    p, q = degree
    xs = np.linspace(x0, x1, p + 1)
    zs = np.linspace(z0, z1, q + 1)
    points = [[[float(x), y, float(z)] for z in zs] for x in xs]
    return {
        "degree": [p, q],
        "knots_u": [0.0] * (p + 1) + [1.0] * (p + 1),
        "knots_v": [0.0] * (q + 1) + [1.0] * (q + 1),
        "points": points,
        **extra,
    }

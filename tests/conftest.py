"""Shared fixtures. GL tests use a real headless context: if none can be
created the test fails (it is never skipped)."""

from __future__ import annotations

import functools
import hashlib
import os
import re
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

from bsrt.rendering import gl
# The converted-model cache (bsrt/io/cache.py) of this test session: a fresh
# temporary folder, never the user's ~/.cache. Set at import, so the CLI's
# child processes inherit it; removed when the session ends.
_CACHE_DIR = tempfile.mkdtemp(prefix="bsrt-test-model-cache-")
os.environ["BSRT_CACHE_DIR"] = _CACHE_DIR


@pytest.fixture(scope="session", autouse=True)
def _model_cache_folder():
    yield _CACHE_DIR
    shutil.rmtree(_CACHE_DIR, ignore_errors=True)

MODELS = Path(__file__).resolve().parent / "data" / "models"
"""Third-party model files (IGES, STEP, .bez, .g2, .nurbs) kept in the repository
for the tests; MODELS / "SOURCES.md" says where each comes from, under which
licence, and its sha256."""


@functools.cache
def model_files() -> tuple[Path, ...]:
    """Every model file listed in MODELS/SOURCES.md, in its order.

    Checked first: each listed file exists with the listed sha256, and no
    other file sits beside them (licence texts, SOURCES.md and .gitattributes
    aside). A broken checkout fails the collection of the modules that use
    this, with one message naming every problem; it is never skipped."""
    table = (MODELS / "SOURCES.md").read_text(encoding="utf-8")
    listed = re.findall(r"^\| `([^`]+)` \|.*\| `([0-9a-f]{64})` \|$", table, re.MULTILINE)
    problems = []
    for name, digest in listed:
        path = MODELS / name
        if not path.is_file():
            problems.append(f"{name}: missing")
        elif hashlib.sha256(path.read_bytes()).hexdigest() != digest:
            problems.append(f"{name}: sha256 differs from SOURCES.md")
    names = {name for name, _ in listed}
    for path in sorted(MODELS.rglob("*")):
        rel = path.relative_to(MODELS)
        if path.is_file() and rel.parts[0] != "LICENSES" and rel.name not in ("SOURCES.md", ".gitattributes") \
                and rel.as_posix() not in names:
            problems.append(f"{rel.as_posix()}: not listed in SOURCES.md")
    if problems or not listed:
        raise AssertionError(f"{MODELS}: " + ("; ".join(problems) or "SOURCES.md lists no files"))
    return tuple(MODELS / name for name, _ in listed)


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

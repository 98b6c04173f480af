"""Golden images of the bundled scenes: a supplement to the closed-form tests.

Regenerate after an intended change of the pictures with

    BSRT_UPDATE_GOLDEN=1 pytest tests/test_golden.py

and look at the new files in tests/golden/ before committing them. On a
mismatch the test writes the render and a difference image (x8) next to
pytest's temporary folder and names them in the failure message.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from bsrt.rendering.image import write_png
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import render
from bsrt.scene import load_scene

pytestmark = pytest.mark.gl  # every test here needs it (tests/conftest.py checks)

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = Path(__file__).resolve().parent / "golden"
# (scene, size, spp, extra settings, file suffix): the first four without adaptive anti-aliasing (the
# pictures from before it), then the defaults (adaptive anti-aliasing) and edges
CASES = [
    ("column", 96, 1, {"adaptive_spp": 0}, ""),
    ("water-lily", 128, 1, {"adaptive_spp": 0}, ""),
    ("water-lily", 96, 4, {"adaptive_spp": 0}, ""),
    ("quad", 64, 1, {"adaptive_spp": 0}, ""),
    ("water-lily", 128, 1, {}, "-adaptive"),
    ("column", 96, 1, {"edges": True, "hidden_edges": True}, "-edges"),
]


@pytest.mark.parametrize("name,size,spp,keys,suffix", CASES, ids=[f"{n}-{s}-spp{p}{x}" for n, s, p, _, x in CASES])
def test_golden_image(tmp_path, name, size, spp, keys, suffix):
    scene = load_scene(ROOT / "scenes" / f"{name}.toml")
    got = render(scene, RenderOptions.resolve(scene, width=size, height=size, spp=spp, **keys)).pixels
    path = GOLDEN / f"{name}-{size}-spp{spp}{suffix}.png"
    if os.environ.get("BSRT_UPDATE_GOLDEN"):
        write_png(path, got)
    want = np.asarray(Image.open(path).convert("RGB"))
    diff = np.abs(got.astype(int) - want.astype(int)).max(axis=-1)
    off = diff > 2
    if off.mean() > 0.002 or (diff.max() > 64 and off.sum() > 4):
        write_png(tmp_path / "got.png", got)
        write_png(tmp_path / "diff.png", np.repeat(np.clip(diff * 8, 0, 255).astype(np.uint8)[..., None], 3, axis=-1))
        pytest.fail(
            f"{path.name}: {off.sum()} pixels differ by more than 2/255 (max {diff.max()}); "
            f"see {tmp_path / 'got.png'} and {tmp_path / 'diff.png'}"
        )

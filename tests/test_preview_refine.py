"""The preview's coarse-to-fine refinement in a real glfw window (Xvfb, GLX on
llvmpipe), driven frame by frame in this process: the 1/4 level is shown
first, a real X event (a resize) is handled while the solver works and
cancels the refinement under way, and the sequence ends with the exact image
that render() gives for the same camera and size (bsrt render's pipeline,
adaptive anti-aliasing off)."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest
from test_preview import SCENES, display  # noqa: F401  (display: the X display fixture)

from bsrt import preview
from bsrt.preview.refine import LEVELS
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import Geometry, render
from bsrt.scene import load_scene

DEADLINE = 240.0  # seconds: the solver processes start (imports, kernels) on a loaded machine


def _frames(window, until, what: str) -> int:
    """Run the window's frame loop (two frames a call: the first ends by handling
    input) until until() holds; returns how many frames that took."""
    deadline, first = time.monotonic() + DEADLINE, window.frame
    while not until():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        window.options = dataclasses.replace(window.options, frames=window.frame + 2)
        window.run()
    return window.frame - first


def _same(got: np.ndarray, want: np.ndarray, what: str) -> None:
    """Equal within 1/255 (the map of the window's context seeds the roots, the
    test's EGL map those of render(): a seed may differ, the converged root not)."""
    assert got.shape == want.shape, what
    diff = np.abs(got.astype(np.int16) - want.astype(np.int16)).max(axis=-1)
    assert (diff <= 1).mean() >= 0.999, f"{what}: {(diff > 1).sum()} pixels differ by more than 1/255"


def _render(scene, geometry, camera, size) -> np.ndarray:
    options = RenderOptions.resolve(scene, camera=camera, width=size[0], height=size[1], spp=1, adaptive_spp=0)
    return render(scene, options, geometry=geometry).pixels


@pytest.mark.window
@pytest.mark.gl
def test_coarse_then_exact_cancelled_by_a_resize_while_refining(display, monkeypatch):  # noqa: F811
    monkeypatch.setenv("DISPLAY", display)
    path = SCENES / "column.toml"
    scene = load_scene(path)
    window = preview.Preview(scene, path, preview.WindowOptions(480, 360))
    window.open()
    try:
        refine, log = window.refine, window.log
        assert LEVELS == refine.levels and refine.levels[0] == 4
        first_size = window.fb_size
        # the 1/4 level is shown while the exact level is still being solved
        _frames(window, lambda: refine.shown == 0 or refine.complete, "the 1/4 level")
        assert refine.shown == 0 and not refine.complete, "the exact level came before the 1/4 level was shown"
        assert window.state() == "refining" and window.image_tex is not None
        coarse = window.view.screenshot(window.image_tex.size, window.image_tex, window.camera)
        generation, camera = refine.generation, window.camera
        # a real X event while the solver works: the window takes a new size (glfw's callback
        # from the X server), which restarts the refinement at the new framebuffer size
        window.window.set_size(320, 240)
        frames = _frames(window, lambda: window.fb_size != first_size, "the resize event")
        assert frames <= 20, f"the resize took {frames} frames to be handled"
        assert refine.generation > generation and not refine.complete
        _frames(window, lambda: refine.complete or refine.failed is not None, "the exact image")
        assert refine.failed is None, refine.failed
        exact, final_camera, final_size = refine.exact, window.camera, window.fb_size
        assert window.state() == "exact"
    finally:
        window.close()
    assert window.gl_error == "GL_NO_ERROR" and not window.view.owned
    assert final_size == (320, 240) and np.array_equal(final_camera.eye, camera.eye)
    # the cancelled generation's exact level was never shown
    old = [e for e in log.levels if e["generation"] == generation]
    assert old[0]["divisor"] == 4 and old[0]["verdict"] == "shown"
    assert [e.get("verdict") for e in old[1:]] in ([], [None])
    # the last generation: 1/4 shown, then the exact image, in that order
    last = [e for e in log.levels if e["generation"] == refine.generation]
    assert [(e["divisor"], e["size"], e.get("verdict")) for e in last] == [
        (4, [80, 60], "shown"),
        (1, [320, 240], "exact"),
    ]
    assert last[0]["shown"] <= last[1]["shown"]
    geometry = Geometry(scene)
    _same(coarse, _render(scene, geometry, camera, (120, 90)), "the 1/4 level")
    _same(exact, _render(scene, geometry, final_camera, (320, 240)), "the exact image")

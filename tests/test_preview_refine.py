"""The preview's coarse-to-fine refinement in a real glfw window (Xvfb, GLX on
llvmpipe), driven frame by frame in this process: the 1/4 level is shown
first, a real X event (a resize) is handled while the solver works and
cancels the refinement under way, so does a camera move, and the sequence
ends with the exact image that render() gives for the same camera and size
(bsrt render's pipeline, adaptive anti-aliasing off); and bsrt bench
--preview's reading of the frame log."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import time

import numpy as np
import pytest
from test_preview import ROOT, SCENES, display  # noqa: F401  (display: the X display fixture)

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
def test_coarse_then_exact_cancelled_by_a_resize_and_a_move_while_refining(display, monkeypatch):  # noqa: F811
    monkeypatch.setenv("DISPLAY", display)
    path = SCENES / "column.toml"
    scene = load_scene(path)
    window = preview.Preview(scene, path, preview.WindowOptions(480, 360))
    window.open()

    def coarse_shown(what):
        """Frames until the 1/4 level of the newest camera is shown, the exact one not yet."""
        _frames(window, lambda: refine.shown == 0 or refine.complete or refine.failed is not None, what)
        assert refine.shown == 0 and not refine.complete, f"{what}: the exact level came first ({refine.failed})"
        assert window.state() == "refining" and window.image_tex is not None

    try:
        refine, log = window.refine, window.log
        assert LEVELS == refine.levels and refine.levels[0] == 4
        first_size = window.fb_size
        coarse_shown("the 1/4 level")
        coarse = window.view.screenshot(window.image_tex.size, window.image_tex, window.camera)
        first, camera = refine.generation, window.camera
        # a real X event while the solver works: the window takes a new size (glfw's callback
        # from the X server), which restarts the refinement at the new framebuffer size
        window.window.set_size(320, 240)
        # (how many frames the X server takes to deliver the event depends on its load: 188 in a
        # CI run; what matters is that the window keeps running frames until it comes)
        _frames(window, lambda: window.fb_size != first_size, "the resize event")
        assert refine.generation > first and not refine.complete
        # the camera moves (the left arrow key) while that size's exact level is being solved
        coarse_shown("the resized 1/4 level")
        resized = refine.generation
        window.press("left")
        assert refine.generation == resized + 1 and window.state() == "moving"
        _frames(window, lambda: refine.complete or refine.failed is not None, "the exact image")
        assert refine.failed is None, refine.failed
        exact, final_camera, final_size = refine.exact, window.camera, window.fb_size
        assert window.state() == "exact"
    finally:
        window.close()
    assert window.gl_error == "GL_NO_ERROR" and not window.view.owned
    assert final_size == (320, 240) and not np.allclose(final_camera.eye, camera.eye)
    # the cancelled generations' exact levels were never shown
    for generation in (first, resized):
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


def test_preview_timeline_of_a_frame_log():
    """bsrt bench --preview's reading of a frame log, on a log written by hand: the start-up's
    stop is left out, a cancelled generation (no exact level) too."""
    from bsrt.rendering.bench import preview_timeline

    states = [(0.0, "moving"), (1.0, "refining"), (2.0, "exact"), (2.5, "moving"), (3.0, "moving")]
    states += [(3.2, "moving"), (3.4, "refining"), (5.0, "exact")]

    def level(generation, divisor, **times):
        return {"generation": generation, "level": int(divisor == 1), "divisor": divisor, "size": [1, 1], **times}

    solved = dict(waited=0.01, seconds=0.2, cpu_seconds=0.25)
    log = {
        "frames": [{"t": t, "state": s, "ms": {}} for t, s in states],
        "levels": [
            level(1, 4, map=0.05, submitted=0.06, shown=0.5, verdict="shown", **solved),
            level(1, 1, map=0.1, submitted=0.2, shown=2.0, verdict="exact", waited=0.2, seconds=1.5, cpu_seconds=2.0),
            level(2, 4, changed=2.5, map=2.6, submitted=2.61, shown=2.9, verdict="shown", **solved),
            level(2, 1, changed=2.5, map=2.7),  # cancelled by the next move
            level(3, 4, changed=3.1, map=3.35, submitted=3.36, shown=3.6, verdict="shown", **solved),
            level(
                3,
                1,
                changed=3.1,
                map=3.4,
                submitted=3.5,
                shown=4.9,
                verdict="exact",
                waited=0.3,
                seconds=1.0,
                cpu_seconds=1.8,
            ),
        ],
    }
    (stop,) = preview_timeline(log)
    assert stop.pop("solve") == {4: (0.2, 0.25), 1: (1.0, 1.8)}
    want = dict(first=0.4, exact=1.7, changed_first=0.5, changed_exact=1.8, map=0.1, waited=0.3, back=0.1)
    assert stop == pytest.approx(want, abs=1e-12)


def test_bench_preview_without_a_display_is_refused_before_benchmarking(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    argv = [sys.executable, "-m", "bsrt", "bench", "--preview", "--json", "out.json"]
    run = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr.splitlines() == [
        "bsrt: error: bench --preview: needs an X display (set DISPLAY, or run it under xvfb-run)"
    ]
    assert list(tmp_path.iterdir()) == []

"""``bsrt preview``: the application. Orbit with the left mouse button, pan
with the right or middle one, zoom with the wheel; the keys of
:data:`bindings.BINDINGS`. While the camera moves the window draws the fast
GL view (view.py); when it stops, the refinement (refine.py) asks for the
exact ray-traced image, coarse to fine, from the solver processes
(solver.py), which run the one pipeline, :func:`bsrt.rendering.pipeline.render`, on
maps the window rasterises band by band (one band per frame). The window
(window.py) turns glfw's input into named events; scripts (script.py) drive
the same application. The window traces one sample per pixel (spp = 1).
Where the solver runs on a GPU the refinement goes live (refine.LIVE_LEVELS):
the exact level only, solved whenever the solver is free, moving or not, and
shown even when the camera has moved on since (docs/usage.md).
"""

from __future__ import annotations

import collections
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from bsrt.errors import InputError, RenderError
from bsrt.preview import script
from bsrt.preview.bindings import BINDINGS, ORBIT_DEGREES_PER_PIXEL
from bsrt.preview.framelog import FrameLog
from bsrt.preview.refine import MAP_BAND_PIXELS, Refinement
from bsrt.preview.solver import Job, Solver
from bsrt.preview.view import View
from bsrt.preview.window import Window
from bsrt.scene.camera import Camera, orbit, pan, zoom
from bsrt.scene.document import camera_toml


@dataclass(frozen=True)
class WindowOptions:
    """How the window runs (the CLI's ``bsrt preview`` options, checked by :meth:`checked`).

    width, height: the window in screen coordinates. frames: quit after that
    many frames (None: run until closed). screenshot: with frames, write the
    last frame there (.png). max_fps: the frame-rate cap (0: none).
    frame_log: write per-frame timestamps and states there (JSON).
    commands: the parsed script (script.parse_script). cache: the window and the
    solver take the patch table and hierarchy from the prepared-geometry cache
    (bsrt/rendering/prepared.py; the CLI's ``--no-cache`` turns it off).
    """

    width: int = 800
    height: int = 600
    frames: int | None = None
    screenshot: str | None = None
    max_fps: float = 60.0
    frame_log: str | None = None
    commands: tuple = ()
    cache: bool = True

    def checked(self) -> WindowOptions:
        for name in ("width", "height"):
            if getattr(self, name) < 1:
                raise InputError(f"--{name}: must be at least 1, got {getattr(self, name)}")
        if self.frames is not None and self.frames < 1:
            raise InputError(f"--frames: must be at least 1, got {self.frames}")
        if self.screenshot and not self.frames:
            raise InputError("--screenshot needs --frames N (the frame to write)")
        if self.screenshot and not self.screenshot.lower().endswith(".png"):
            raise InputError(f"{self.screenshot}: the output file name must end in .png")
        if self.max_fps < 0:
            raise InputError(f"--max-fps: must be 0 (no cap) or more, got {self.max_fps}")
        return self


def script_commands(events: str | None, script_file: str | None) -> tuple:
    """The commands of a script file and then of an events string (InputError on a bad one)."""
    commands = []
    if script_file:
        try:
            text = Path(script_file).read_text(encoding="utf-8")
        except OSError as exc:
            raise InputError(f"{script_file}: cannot read the script ({exc.strerror})") from None
        commands += script.parse_script(text, script_file)
    if events:
        commands += script.parse_script(events, "--events")
    return tuple(commands)


class Preview:
    """The application: camera, method, what is shown, the script, the frame
    loop. Main thread only. Input arrives as named events from :class:`Window`
    (``on_*``) or the script; ``self.refine`` decides what to solve next."""

    def __init__(self, scene, scene_path: Path, options: WindowOptions):
        from bsrt.rendering.pipeline import Geometry

        self.scene, self.scene_path, self.options = scene, scene_path, options
        self.map_mode = scene.render.map
        self.method = scene.render.method
        self.geometry = Geometry(scene, options.cache)
        self.home = self.camera = scene.camera
        self.commands = collections.deque(options.commands)
        self.log = FrameLog()
        self.window = Window(self, scene_path)
        self.view: View | None = None
        self.solver = Solver(scene, self.map_mode, options.cache, wake=self.window.wake)
        self.refine = Refinement()
        self.fb_size = (0, 0)
        self.released = 0  # how many GL objects close() released
        self.gl_error: str | None = None  # ctx.error when the window closed
        self.image_tex = None  # the finest level shown of this generation
        self.map_tex = None  # its map's picture (key M)
        self.map_level = -1
        self.keep_image = False  # method switch: show the old image until the new one
        self.live = False  # the solver runs on a GPU: exact images while the camera moves (refine.LIVE_LEVELS)
        self.show_map = False
        self.held = {"orbit": False, "pan": False}  # mouse buttons down
        self.pending_saves: list[Path | None] = []
        self.pending_screenshots: list[Path] = []
        self.quit = False
        self.frame = 0
        self.title = ""
        self.shown_key = None  # what the window shows now: (image, camera, size); redraw when it changes

    # ---- set-up and tear-down

    def open(self) -> None:
        ctx = self.window.open(self.options.width, self.options.height, self._title_text())
        self.fb_size = self.window.framebuffer_size()
        try:
            self.view = View(ctx, self.scene, self.geometry, self.camera, self.fb_size)
        except BaseException:
            self.close()
            raise
        self.solver.start()
        self._changed(settle=True)

    def close(self) -> None:
        """Stop the solver, release every GL object, check GL errors, close the window."""
        self.solver.stop()
        error = None
        ctx = self.window.ctx
        if ctx is not None:
            self.window.make_current()
            if self.view is not None:
                self.released = self.view.close()
            error = self.gl_error = ctx.error
            ctx.release()
            self.window.ctx = None
        self.window.close()
        if error not in (None, "GL_NO_ERROR"):
            raise RenderError(f"OpenGL reported {error} in the preview window")

    # ---- changes

    def _changed(self, settle: bool = True, keep_image: bool = False) -> None:
        """Camera, method or size changed: a new generation, refinement restarts."""
        generation = self.refine.restart(time.perf_counter(), settle)
        self.solver.cancel_before(generation)
        self.keep_image = (keep_image or self.live) and self.image_tex is not None
        if not self.keep_image:
            self.view.release(self.image_tex)
            self.image_tex = None
        self.view.release(self.map_tex)
        self.map_tex, self.map_level = None, -1

    def move(self, camera: Camera) -> None:
        self.camera = camera
        self._changed(settle=True)

    def aspect(self) -> float:
        w, h = self.fb_size
        return w / max(h, 1)

    def press(self, name: str) -> None:
        """A key, by name (also the script's ``key NAME``): its action in
        BINDINGS, run by the ``_do_<action>`` method of that name."""
        binding = BINDINGS.get(name.lower())
        if binding is not None:
            action, *arguments = binding
            getattr(self, f"_do_{action}")(*arguments)

    def _do_quit(self) -> None:
        self.quit = True

    def _do_toggle_map(self) -> None:
        self.show_map = not self.show_map
        if self.live and self.show_map and self.map_tex is None:  # live jobs send the map only when asked
            self._changed(settle=False, keep_image=True)

    def _do_method(self, method: str) -> None:
        self.set_method(method)

    def _do_save(self) -> None:
        self.request_save(None)  # next to the scene

    def _do_print_camera(self) -> None:
        print(camera_toml(self.camera), flush=True)

    def _do_reset(self) -> None:
        self.move(self.home)

    def _do_zoom(self, factor: float) -> None:
        self.move(zoom(self.camera, factor))

    def _do_orbit(self, yaw: float, pitch: float) -> None:
        self.move(orbit(self.camera, yaw, pitch))

    def _do_pan(self, dx: float, dy: float) -> None:
        self.move(pan(self.camera, dx, dy, self.aspect()))

    def set_method(self, method: str) -> None:
        if method != self.method:
            self.method = method
            self._changed(settle=False, keep_image=True)

    # ---- window events

    def on_key(self, name: str) -> None:
        self.press(name)

    def on_drag(self, button: str, down: bool) -> None:
        self.held[button] = down
        if not down:
            self.refine.touch(time.perf_counter())  # settle from the release

    def on_cursor(self, dx: float, dy: float, window_height: int) -> None:
        if self.held["orbit"]:
            # the scene turns with the cursor: drag right, the camera goes left; drag up, it goes down
            self.move(orbit(self.camera, dx * ORBIT_DEGREES_PER_PIXEL, dy * ORBIT_DEGREES_PER_PIXEL))
        elif self.held["pan"]:
            h = max(window_height, 1)
            self.move(pan(self.camera, dx / h, -dy / h, self.aspect()))

    def on_scroll(self, dy: float) -> None:
        self.move(zoom(self.camera, BINDINGS["plus"][1] ** dy))

    def on_framebuffer(self, width: int, height: int) -> None:
        if (width, height) != self.fb_size:
            self.fb_size = (width, height)
            self._changed(settle=True)

    def on_refresh(self) -> None:
        self.shown_key = None  # the window's contents were lost: draw again

    # ---- refinement

    def state(self) -> str:
        return self.refine.state(time.perf_counter(), self.held["orbit"] or self.held["pan"])

    def _refine(self, now: float) -> None:
        """Rasterise the next band of the next level's map (one per frame, so
        the window never waits for a whole full-size map); when a level's map
        is complete, hand it to the solver. Live: hand the solver the exact
        level (it draws the map) whenever it is free, moving or not."""
        if self.live:
            self._submit_live()
            return
        level = self.refine.next_level(now, self.held["orbit"] or self.held["pan"])
        if level is None or min(self.fb_size) < 1:
            return
        from bsrt.rendering.prelim import render_map

        width, height = self.refine.size(level, self.fb_size)
        divisor, changed = self.refine.levels[level], self.refine.last_change
        entry = self.log.level(self.refine.generation, level, divisor, (width, height), changed)
        prelim = None
        if self.method != "martin" or self.show_map:
            rows, count = self.refine.next_band(width, height)
            try:
                part = render_map(
                    self.geometry.patches, self.camera, width, height, self.map_mode, ctx=self.window.ctx, rows=rows
                )
            except (InputError, RenderError) as exc:
                self.refine.fail(f"map: {exc}")
                return
            finally:
                self.window.ctx.screen.use()
            prelim = self.refine.add_band(part, count)
            if prelim is None:
                return
            if level > self.map_level:
                self.view.release(self.map_tex)
                self.map_tex, self.map_level = self.view.texture(prelim.picture), level
            # render() needs the seeds only; the picture stays here for key M
            prelim = replace(prelim, picture=np.zeros((0, 0, 3), dtype=np.uint8))
        job = Job(self.refine.generation, level, self.method, self.camera, width, height, prelim, time.time())
        self.solver.submit(job)
        self.refine.submitted()
        entry["submitted"] = self.log.now()

    def _submit_live(self) -> None:
        """Live: the current camera's exact level to the solver, unless it is busy or has it."""
        refine = self.refine
        if refine.failed or refine.to_submit >= len(refine.levels) or self.solver.busy() or min(self.fb_size) < 1:
            return
        width, height = refine.size(0, self.fb_size)
        entry = self.log.level(refine.generation, 0, refine.levels[0], (width, height), refine.last_change)
        job = Job(refine.generation, 0, self.method, self.camera, width, height, None, time.time(), True, self.show_map)
        self.solver.submit(job)
        refine.submitted()
        entry["submitted"] = self.log.now()

    def _go_live(self) -> None:
        """The solver turned out to run on a GPU: refine live from now on."""
        self.live = True
        self.solver.cancel_before(self.refine.go_live(time.perf_counter()))
        self.solver.drop_spare()  # a live job is never cut short: no process waits to take over
        print("bsrt preview: solving on the GPU: the exact image follows the camera", file=sys.stderr)

    def _collect(self) -> None:
        if not self.live and self.solver.device() == "gpu":
            self._go_live()
        for outcome in self.solver.outcomes():
            job = outcome.job
            if job.generation == -1:  # the solver process is gone: nothing more will come
                self.refine.solver_died(outcome.error)
                print(f"bsrt preview: {outcome.error}", file=sys.stderr)
                continue
            error = None if outcome.error is None else f"{job.method} failed: {outcome.error}"
            verdict = self.refine.accept(job.generation, job.level, outcome.pixels, error, outcome.seconds)
            if verdict == "stale" and job.live and outcome.pixels is not None:
                verdict = "live"  # the camera has moved on since: the newest exact image, shown meanwhile
            if job.live and outcome.map_picture is not None and verdict != "stale":
                self.view.release(self.map_tex)
                self.map_tex, self.map_level = self.view.texture(outcome.map_picture), job.level
            if verdict != "stale":
                entry = self.log.level(
                    job.generation, job.level, self.refine.levels[job.level], (job.width, job.height)
                )
                entry.update(shown=self.log.now(), verdict=verdict, seconds=round(outcome.seconds, 4))
                entry.update(cpu_seconds=round(outcome.cpu_seconds, 4), waited=round(outcome.waited, 4))
            if verdict == "failed":
                print(f"bsrt preview: {error}", file=sys.stderr)
            elif verdict in ("shown", "exact", "live"):
                self.view.release(self.image_tex)
                self.image_tex = self.view.texture(outcome.pixels)
                self.keep_image = False
                if verdict == "exact":
                    self._flush_saves()

    def request_save(self, path: Path | None) -> None:
        self.pending_saves.append(path)
        self._flush_saves()

    def _flush_saves(self) -> None:
        if not self.refine.complete:
            return
        from bsrt.rendering.image import write_png

        for path in self.pending_saves:
            path = path or self._free_name()
            write_png(path, self.refine.exact)
            print(f"bsrt preview: saved {path}", file=sys.stderr)
        self.pending_saves = []

    def _free_name(self) -> Path:
        folder, stem = self.scene_path.parent, self.scene_path.stem
        for k in range(1, 10000):
            path = folder / f"{stem}-preview-{k:03d}.png"
            if not path.exists():
                return path
        raise InputError(f"{folder}: too many {stem}-preview-NNN.png files")

    # ---- drawing

    def _image(self, state: str):
        """The texture to show (None: the fast view)."""
        if state != "moving" or self.live:
            if self.show_map and self.map_tex is not None:
                return self.map_tex
            return self.image_tex
        return self.image_tex if self.keep_image else None

    def draw(self, state: str) -> bool:
        """Write pending screenshots, then draw the frame if it differs from
        the one shown (a still frame is not drawn again: llvmpipe's cores are
        the solver's meanwhile). True if the window's buffer changed."""
        from bsrt.rendering.image import write_png

        image = self._image(state)
        for path in self.pending_screenshots:
            write_png(path, self.view.screenshot(self.fb_size, image, self.camera))
        self.pending_screenshots = []
        key = (image, self.camera if image is None else None, self.fb_size)
        if self.shown_key is not None and all(a is b for a, b in zip(key, self.shown_key)):
            return False
        self.view.draw(self.window.ctx.screen, self.fb_size, image, self.camera)
        self.shown_key = key
        return True

    def _title_text(self) -> str:
        parts = [f"bsrt preview: {self.scene_path.name}", self.method]
        state = self.state() if self.view is not None else "opening"
        if self.refine.failed:
            parts.append(self.refine.failed.splitlines()[0][:120])
        elif state == "refining":
            parts.append(self.refine.progress_text())
        else:
            parts.append(state)
        if self.refine.solve_seconds is not None:
            parts.append(f"last solve {self.refine.solve_seconds:.2f} s")
        if self.show_map:
            parts.append("map (M)")
        if self.pending_saves:
            parts.append("will save when refined")
        return " | ".join(parts)

    # ---- the loop

    def run(self) -> None:
        """The frame loop: script, solver outcomes, refinement, drawing, input;
        paced by --max-fps, idle until input once exact."""
        if not self.log.times:
            self.log.start = time.perf_counter()
        start = self.log.start
        frame_seconds = 1.0 / self.options.max_fps if self.options.max_fps > 0 else 0.0
        next_frame = start
        limit = self.options.frames
        while not self.quit and not self.window.should_close():
            if min(self.fb_size) < 1:  # minimised: nothing to draw
                self.window.wait(0.25)
                continue
            clock = time.perf_counter()
            script.advance(self, self.commands)
            if self.quit:
                break
            work = {}
            now = time.perf_counter()
            work["script"] = (now - clock) * 1e3
            self._collect()
            clock = time.perf_counter()
            work["collect"] = (clock - now) * 1e3
            self._refine(clock)
            last = limit is not None and self.frame + 1 >= limit
            if last and self.options.screenshot:
                self.pending_screenshots.append(Path(self.options.screenshot))
            state = self.state()
            now = time.perf_counter()
            work["refine"] = (now - clock) * 1e3
            if self.draw(state):
                self.window.swap()
            clock = time.perf_counter()
            work["draw"] = (clock - now) * 1e3
            self.log.add(clock - start, state, work)
            self.frame += 1
            title = self._title_text()
            if title != self.title:
                self.window.set_title(title)
                self.title = title
            if last:
                break
            idle = state in ("exact", "failed") and not self.commands and not self.pending_saves
            next_frame = max(next_frame + frame_seconds, time.perf_counter())
            self.window.wait(0.25 if idle else next_frame - time.perf_counter())


def run(scene, scene_path: Path, options: WindowOptions) -> int:
    """Open the window on ``scene`` (its [render] settings already final) and run it until it is
    closed or ``options.frames`` have passed; returns the exit code (errors raise InputError/RenderError)."""
    options = options.checked()
    for note in scene.notes:
        print(f"bsrt: warning: {note}", file=sys.stderr)
    preview = Preview(scene, Path(scene_path), options)
    try:
        preview.open()
        preview.run()
    finally:
        if preview.window.handle is not None:
            preview.close()
    if options.frame_log:
        preview.log.write(
            Path(options.frame_log),
            {
                "scene": str(scene_path),
                "framebuffer": list(preview.fb_size),
                "levels": list(preview.refine.levels),
                "max_fps": options.max_fps,
                "map_band_pixels": MAP_BAND_PIXELS,
                "gl_error": preview.gl_error,
                "gl_objects_released": preview.released,
                "gl_objects_left": len(preview.view.owned) if preview.view else 0,
                "solver_swaps": preview.solver.swaps,
            },
        )
    return 0

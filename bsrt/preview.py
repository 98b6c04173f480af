"""Interactive preview window: ``bsrt preview SCENE``.

Orbit with the left mouse button, pan with the right or middle one, zoom with
the wheel; the arrow keys orbit (with Shift: pan) and +/- zoom. While the
camera moves the window draws a fast GL view: the preliminary map's
tessellation (``prelim.tessellate``) shaded with the scene's lights. When it
stops, the window refines to the exact ray-traced image, coarse to fine
(``LEVELS``: 1/4, 1/2, then the full framebuffer), through the one pipeline,
:func:`bsrt.pipeline.render`.

Processes. The main thread owns the glfw window and its moderngl context:
it handles input, draws every frame and rasterises each level's preliminary
map on the window's context (``prelim.render_map(..., ctx=window_ctx,
rows=band)``, one band per frame, stitched). A solver process
(:class:`Solver`) calls ``render(..., prelim=that_map)``, which is NumPy only;
it never touches GL. Every camera, method or size change bumps a generation
counter: queued jobs of older generations are dropped, a running one is
abandoned at render's next stage (its ``progress`` callback raises) or, if a
warm spare process is ready, at once (the busy process is killed), and the
window discards stale results. The fast view ignores shadows and mirrors;
the exact image has them. The window traces one sample per pixel (spp = 1).

Keys: M the preliminary map (paper's Figure 1), 1-4 the method (gradient,
fast, newton, martin), S save the exact image next to the scene, C print the
camera as a TOML ``[camera]`` table, R reset the camera, Esc/Q quit.

Scripting (tests, demos, measurements): ``--events "orbit 30 0; wait; save
out.png; quit"`` or ``--script FILE`` (one command a line or ';'-separated,
'#' comments), see :data:`SCRIPT_HELP`; ``--frames N [--screenshot OUT.png]``
quits after N frames; ``--frame-log FILE.json`` records every frame's time
and state, and the longest gap between frames.
"""

from __future__ import annotations

import argparse
import collections
import json
import math
import os
import re
import shlex
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import moderngl
import numpy as np

from . import gl
from .camera import Camera, clip_from_eye
from .errors import InputError, RenderError
from .settings import MAP_MODES, METHODS, RenderOptions

LEVELS = (4, 2, 1)  # refinement: the framebuffer divided by these, coarse to fine
SETTLE_SECONDS = 0.15  # the camera counts as stopped after this long without a change
# The main thread rasterises a level's map in bands of about this many pixels,
# one band per frame (render_map's rows=): a whole 800x600 map blocks the
# window for ~80 ms on llvmpipe; the bands share one cached tessellation.
MAP_BAND_PIXELS = 100_000
ORBIT_DEGREES_PER_PIXEL = 0.4  # mouse drag, screen coordinates
KEY_ORBIT_DEGREES = 10.0
KEY_PAN_FRACTION = 0.05  # of the view height
ZOOM_STEP = 0.9  # distance factor per wheel notch or '+' press
SOLVER_NICENESS = 10  # os.nice of the solver process
MAX_LIGHTS = 8
# The fast view's mesh is the map's tessellation for a film this fraction of
# the window (chord error <= 1 / (2 * FAST_VIEW_DETAIL) pixels): a quarter of
# the triangles at 0.5, which llvmpipe needs for many frames a second.
FAST_VIEW_DETAIL = 0.5  # shaders/preview.glsl
METHOD_KEYS = {"1": "gradient", "2": "fast", "3": "newton", "4": "martin"}

KEYS_HELP = """\
mouse: left drag orbits, right or middle drag pans, the wheel zooms
keys:  arrows orbit (Shift+arrows pan), +/- zoom, M the preliminary map,
       1-4 method (gradient, fast, newton, martin), S save the exact image
       next to the scene, C print the camera as a [camera] table,
       R reset the camera, Esc/Q quit
"""

SCRIPT_HELP = """\
script commands (';' or newline separated, '#' starts a comment):
  orbit DYAW DPITCH [FRAMES]  orbit by degrees (spread over FRAMES frames, default 1)
  pan DX DY [FRAMES]          move the scene by DX, DY view heights (right, up)
  zoom FACTOR [FRAMES]        multiply the eye's distance to look_at by FACTOR
  key NAME                    press a key: m, s, c, r, 1-4, q, left, right, up, down, plus, minus
  method NAME                 switch the method (gradient, fast, newton, martin)
  resize W H                  resize the window (screen coordinates)
  wait                        until the exact full-resolution image (or its failure)
  frames N                    let N frames pass
  sleep SECONDS               let time pass
  save FILE.png               wait, then write the exact image
  screenshot FILE.png         write the next drawn frame (what the window shows)
  camera [FILE.toml]          print (or write) the camera as a [camera] table
  reset                       reset the camera
  quit                        close the window"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``bsrt preview`` (called by cli.py)."""
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.description = "An interactive window: a fast GL view while the camera moves, then the exact image."
    parser.epilog = KEYS_HELP + "\n" + SCRIPT_HELP
    parser.add_argument("scene", help="scene file (.toml) or model file (.bez .bpt .g2 .igs .iges .obj .nurbs)")
    parser.add_argument("--width", type=int, default=800, help="window width in screen coordinates (default 800)")
    parser.add_argument("--height", type=int, default=600, help="window height (default 600)")
    parser.add_argument("--method", choices=METHODS, help="root finder to start with (overrides [render].method)")
    parser.add_argument("--map", choices=MAP_MODES, dest="map_mode", help="preliminary map precision")
    parser.add_argument("--frames", type=int, help="quit after N frames")
    parser.add_argument("--screenshot", metavar="OUT.png", help="with --frames: write the last frame")
    parser.add_argument("--events", metavar="SCRIPT", help="drive the window: e.g. \"orbit 30 0; wait; save out.png; quit\"")
    parser.add_argument("--script", metavar="FILE", help="the same commands from a file")
    parser.add_argument("--frame-log", metavar="FILE.json", help="write per-frame timestamps and states as JSON")
    parser.add_argument("--max-fps", type=float, default=60.0, help="frame rate cap (default 60; 0: none)")


# ---------------------------------------------------------------- camera moves


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _rotate(v: np.ndarray, axis: np.ndarray, degrees: float) -> np.ndarray:
    """v (3,) rotated about the unit axis (3,) by degrees (right-handed, Rodrigues)."""
    a = math.radians(degrees)
    return v * math.cos(a) + np.cross(axis, v) * math.sin(a) + axis * float(axis @ v) * (1.0 - math.cos(a))


def orbit(camera: Camera, yaw: float, pitch: float) -> Camera:
    """Turn the eye about look_at: yaw degrees about ``up`` (positive turns the
    view to the left, the object to the right), then pitch degrees about the
    view's right axis (positive raises the eye), kept at least 1 degree away
    from ``up`` so the camera stays valid."""
    up = _unit(camera.up)
    offset = _rotate(camera.eye - camera.look_at, up, -yaw)
    right = _unit(np.cross(-offset, up))
    tilted = _rotate(offset, right, -pitch)
    angle = math.degrees(math.acos(np.clip(_unit(tilted) @ up, -1.0, 1.0)))
    if 1.0 <= angle <= 179.0:
        offset = tilted
    return replace(camera, eye=camera.look_at + offset)


def pan(camera: Camera, dx: float, dy: float, aspect: float) -> Camera:
    """Move eye and look_at together by (dx, dy) view heights at look_at's
    distance (dx to the right, dy up): the scene follows a dragged cursor."""
    right, up, _ = camera.basis()
    _, ty = camera.half_extents(aspect, 1.0)
    scale = 2.0 * ty * float(np.linalg.norm(camera.look_at - camera.eye))
    shift = -(dx * right + dy * up) * scale
    return replace(camera, eye=camera.eye + shift, look_at=camera.look_at + shift)


def zoom(camera: Camera, factor: float) -> Camera:
    """Multiply the eye's distance to look_at by factor (< 1: closer)."""
    return replace(camera, eye=camera.look_at + (camera.eye - camera.look_at) * factor)


def camera_toml(camera: Camera) -> str:
    """The camera as a scene file's [camera] table (floats round-trip exactly)."""

    def vec(v) -> str:
        return "[" + ", ".join(repr(float(x)) for x in v) + "]"

    return (
        "[camera]\n"
        f"eye = {vec(camera.eye)}\n"
        f"look_at = {vec(camera.look_at)}\n"
        f"up = {vec(camera.up)}\n"
        f"fov = {float(camera.fov)!r}\n"
        f'fov_axis = "{camera.fov_axis}"\n'
    )


# ---------------------------------------------------------------- script


@dataclass
class Command:
    name: str
    args: list
    text: str


_ARITY = {  # name: (min args, max args, converters)
    "orbit": (2, 3, (float, float, int)),
    "pan": (2, 3, (float, float, int)),
    "zoom": (1, 2, (float, int)),
    "key": (1, 1, (str,)),
    "method": (1, 1, (str,)),
    "resize": (2, 2, (int, int)),
    "wait": (0, 0, ()),
    "frames": (1, 1, (int,)),
    "sleep": (1, 1, (float,)),
    "save": (1, 1, (str,)),
    "screenshot": (1, 1, (str,)),
    "camera": (0, 1, (str,)),
    "reset": (0, 0, ()),
    "quit": (0, 0, ()),
}
_KEY_NAMES = set("msc1234rq") | {"left", "right", "up", "down", "plus", "minus", "escape",
                                 "shift+left", "shift+right", "shift+up", "shift+down"}


def parse_script(text: str, where: str = "--events") -> list[Command]:
    """Commands of SCRIPT_HELP; raises InputError naming the bad one."""
    out = []
    for raw_line in text.splitlines():
        line = raw_line.split("#", 1)[0]
        for part in line.split(";"):
            part = part.strip()
            if not part:
                continue
            words = shlex.split(part)
            name, args = words[0].lower(), words[1:]
            if name not in _ARITY:
                raise InputError(f"{where}: unknown command {name!r} in {part!r} (expected one of {', '.join(_ARITY)})")
            lo, hi, kinds = _ARITY[name]
            if not lo <= len(args) <= hi:
                raise InputError(f"{where}: {part!r}: {name} takes {lo}{'' if lo == hi else f' to {hi}'} arguments")
            try:
                values = [kind(a) for kind, a in zip(kinds, args)]
            except ValueError:
                raise InputError(f"{where}: {part!r}: bad number") from None
            if name in ("frames", "orbit", "pan", "zoom") and len(values) == hi and values[-1] < 1:
                raise InputError(f"{where}: {part!r}: the frame count must be at least 1")
            if name == "resize" and min(values) < 1:
                raise InputError(f"{where}: {part!r}: the size must be at least 1x1")
            if name == "key" and values[0].lower() not in _KEY_NAMES:
                raise InputError(f"{where}: {part!r}: unknown key (expected one of {', '.join(sorted(_KEY_NAMES))})")
            if name == "method" and values[0] not in METHODS:
                raise InputError(f"{where}: {part!r}: unknown method (expected one of {', '.join(METHODS)})")
            if name in ("save", "screenshot") and not values[0].lower().endswith(".png"):
                raise InputError(f"{where}: {part!r}: the file name must end in .png")
            out.append(Command(name, values, part))
    return out


# ---------------------------------------------------------------- the solver process


class _Cancelled(Exception):
    pass


class _NoGLHere:
    """render()'s ``ctx`` in the solver process. The map comes from the
    window, so render() must never need GL there; if it does, say so instead
    of silently creating a second context."""

    def __getattr__(self, name):
        raise RenderError("render() asked for OpenGL in the solver process instead of using the map it was given")


@dataclass
class Job:
    generation: int
    level: int  # index into LEVELS
    method: str
    camera: Camera
    width: int
    height: int
    prelim: object  # PrelimMap or None (only for the way there)


@dataclass
class Outcome:
    job: Job  # without its map
    pixels: np.ndarray | None = None  # (H, W, 3) uint8 sRGB; None: failed or abandoned
    error: str | None = None
    seconds: float = 0.0


STARTING, IDLE = -2, -1  # a worker's ``running`` value besides the generation it solves


def _solver_process(scene, map_mode, jobs, outcomes, generation, running) -> None:
    """A solver process's loop: render() each job that is still current.

    jobs: Queue of Job (None: stop), at most one at a time; outcomes: Queue
    of Outcome, one per job (pixels None when abandoned); generation: shared
    int, the window's newest generation (older jobs are abandoned at
    render's next stage, through its progress callback); running: shared
    int, STARTING, IDLE or the generation of the job being solved.
    """
    import multiprocessing
    import queue
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl+C is the window's business

    from .pipeline import Geometry, render

    geometry = Geometry(scene)
    try:
        _ = geometry.bvh  # shadow rays and "martin" need it: build it before the first job
    except Exception:  # render() reports it when a job needs it
        pass
    running.value = IDLE
    parent = multiprocessing.parent_process()
    no_gl = _NoGLHere()
    while True:
        try:
            job = jobs.get(timeout=1.0)
        except queue.Empty:
            if parent is not None and not parent.is_alive():
                return
            continue
        if job is None:
            return
        light = replace(job, prelim=None)
        if job.generation < generation.value:
            outcomes.put(Outcome(light))
            continue
        running.value = job.generation

        def progress(stage, fraction=0.0, job=job):
            if job.generation < generation.value:
                raise _Cancelled

        clock = time.perf_counter()
        outcome = Outcome(light)
        try:
            options = RenderOptions.resolve(scene, method=job.method, map=map_mode, width=job.width,
                                            height=job.height, spp=1, camera=job.camera)
            result = render(scene, options, geometry=geometry, ctx=no_gl, prelim=job.prelim, progress=progress)
            outcome.pixels = result.pixels
        except _Cancelled:
            pass
        except (InputError, RenderError) as exc:
            outcome.error = str(exc)
        except Exception as exc:  # shown in the title; the window keeps running
            outcome.error = f"{type(exc).__name__}: {exc}"
        outcome.seconds = time.perf_counter() - clock
        running.value = IDLE
        outcomes.put(outcome)


class _Worker:
    """One solver process, its queues and its state (main process side)."""

    def __init__(self, mp, scene, map_mode, generation):
        self.jobs, self.outcomes = mp.Queue(), mp.Queue()
        self.running = mp.Value("q", STARTING, lock=False)
        self.job: Job | None = None  # in flight: sent, its outcome not back yet
        self.process = mp.Process(
            target=_solver_process, args=(scene, map_mode, self.jobs, self.outcomes, generation, self.running),
            name="bsrt-preview-solver", daemon=True,
        )
        self.process.start()
        if hasattr(os, "setpriority"):  # from the start (its imports too): the window keeps its core
            try:
                os.setpriority(os.PRIO_PROCESS, self.process.pid, SOLVER_NICENESS)
            except OSError:
                pass

    def send(self, job: Job) -> None:
        self.job = job
        self.jobs.put(job)

    def receive(self) -> list[Outcome]:
        import queue

        out = []
        while True:
            try:
                out.append(self.outcomes.get_nowait())
            except queue.Empty:
                return out

    def kill(self) -> None:
        """End the process now (it is inside render(): nothing to save)."""
        self.process.terminate()
        self._close_queues()

    def stop(self, timeout: float) -> None:
        if self.process.is_alive():
            if self.running.value >= 0:  # inside render(): nothing to wait for
                self.process.terminate()
            else:
                self.jobs.put(None)
                self.process.join(timeout)
                if self.process.is_alive():
                    self.process.terminate()
        self.process.join(timeout)
        self._close_queues()

    def _close_queues(self) -> None:
        for q in (self.jobs, self.outcomes):
            q.cancel_join_thread()
            q.close()


class Solver:
    """render() in solver processes, newest generation only (main process side).

    Processes, not a thread: the solver's NumPy code holds the GIL for much
    of its time (many small array operations, the hierarchy's traversal), and
    a thread doubled the time the window's own map bands took (frame gaps of
    130-180 ms at 800x600); the processes run niced, so the window also wins
    the CPU. Maps go there and images come back through queues (pickled in
    multiprocessing's feeder threads, off the frame loop), one job in flight
    per process.

    Cancelling. render() can only be stopped between its stages (its
    progress callback), and a full-size shading stage with shadow rays takes
    seconds. So a spare process waits, warm (geometry and hierarchy built):
    when the camera moves while the active process solves an older
    generation, that process is killed and the spare takes over at once; a
    new spare starts once the active process is warm.
    """

    def __init__(self, scene, map_mode):
        import multiprocessing

        self._mp = multiprocessing.get_context("spawn")  # never fork a process holding a GL context
        self._scene, self._map_mode = scene, map_mode
        self._generation = self._mp.Value("q", 0, lock=False)
        self._pending: collections.deque[Job] = collections.deque()
        self.active: _Worker | None = None
        self.spare: _Worker | None = None
        self._dying: list[_Worker] = []
        self._lost: str | None = None
        self.swaps = 0

    def _worker(self) -> _Worker:
        return _Worker(self._mp, self._scene, self._map_mode, self._generation)

    def start(self) -> None:
        self.active = self._worker()

    def submit(self, job: Job) -> None:
        self._pending.append(job)
        self._feed()

    def cancel_before(self, generation: int) -> None:
        """Abandon every job older than generation."""
        self._generation.value = generation
        self._pending = collections.deque(j for j in self._pending if j.generation >= generation)
        active, spare = self.active, self.spare
        if (active is not None and active.job is not None and active.job.generation < generation
                and active.running.value == active.job.generation  # read whole and being solved
                and spare is not None and spare.running.value == IDLE):
            active.kill()
            self._dying.append(active)
            self.active, self.spare = spare, None
            self.swaps += 1

    def _feed(self) -> None:
        worker = self.active
        if worker is None or worker.job is not None:
            return
        while self._pending:
            job = self._pending.popleft()
            if job.generation >= self._generation.value:
                worker.send(job)
                return

    def outcomes(self) -> list[Outcome]:
        """Finished jobs (current or not); call every frame."""
        out = []
        worker = self.active
        if worker is not None:
            for outcome in worker.receive():
                worker.job = None
                if outcome.pixels is not None or outcome.error is not None:
                    out.append(outcome)
            if self.spare is None and worker.running.value != STARTING:
                self.spare = self._worker()  # once the active one is warm: they never start together
            if worker.process.exitcode is not None and self._lost is None:
                self._lost = f"the solver process died (exit code {worker.process.exitcode})"
                out.append(Outcome(Job(-1, -1, "", None, 0, 0, None), None, self._lost))
        self._feed()
        for dying in list(self._dying):
            if dying.process.exitcode is not None:
                dying.process.join(0)
                self._dying.remove(dying)
        return out

    def stop(self, timeout: float = 2.0) -> None:
        self._generation.value = 2**62
        for worker in [self.active, self.spare, *self._dying]:
            if worker is not None:
                worker.stop(timeout)
        self.active = self.spare = None
        self._dying = []


def map_bands(width: int, height: int) -> list[tuple[int, int]]:
    """Film rows (first, stop) of the map's bands: about MAP_BAND_PIXELS each."""
    count = max(1, min(height, round(width * height / MAP_BAND_PIXELS)))
    edges = np.linspace(0, height, count + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


def stitch_maps(parts: list):
    """One PrelimMap from the maps of consecutive bands (top band first)."""
    from dataclasses import fields

    from .prelim import PrelimMap

    if len(parts) == 1:
        return parts[0]
    return PrelimMap(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(PrelimMap)))


# ---------------------------------------------------------------- the fast view geometry


def fast_view_mesh(scene, geometry, camera: Camera, width: int, height: int):
    """The shaded tessellation: (vertices (V, 11) float32 rows (x, y, z
    relative to origin, normal, albedo, specular, shininess), indices (T, 3)
    uint32, origin (3,) float64 the scene box centre).

    Vertices come from ``prelim.tessellate`` (the map's own grid, as dense as
    the map needs at this camera and size); normals are the exact S_u x S_v
    at each vertex, or the mesh's area-weighted normal where that vanishes.
    """
    from .prelim import segments_per_patch, tessellate

    patches = geometry.patches
    lo, hi = patches.scene_box()
    origin = 0.5 * (lo + hi)
    coarse = max(1, round(width * FAST_VIEW_DETAIL)), max(1, round(height * FAST_VIEW_DETAIL))
    verts, tris = tessellate(patches, segments_per_patch(patches, camera, *coarse), origin)
    surface = np.rint(verts[:, 5]).astype(np.int64) - 1
    d = patches.domain[surface]
    u = d[:, 0] + (d[:, 1] - d[:, 0]) * verts[:, 3].astype(np.float64)
    v = d[:, 2] + (d[:, 3] - d[:, 2]) * verts[:, 4].astype(np.float64)
    u, v = patches.clamp(surface, u, v)
    _, su, sv = patches.evaluate(patches.locate(surface, u, v), u, v)
    normal = np.cross(su.T, sv.T)
    length = np.linalg.norm(normal, axis=1)
    scale = np.linalg.norm(su, axis=0) * np.linalg.norm(sv, axis=0)
    good = length > 1e-9 * np.maximum(scale, 1e-300)
    normal[good] /= length[good, None]
    if not good.all():
        p = verts[:, :3].astype(np.float64)
        a, b, c = p[tris[:, 0]], p[tris[:, 1]], p[tris[:, 2]]
        face = np.cross(b - a, c - a)
        mesh = np.zeros_like(p)
        for k in range(3):
            np.add.at(mesh, tris[:, k], face)
        mesh_len = np.linalg.norm(mesh, axis=1)
        mesh_len[mesh_len == 0] = 1.0
        normal[~good] = mesh[~good] / mesh_len[~good, None]
    material = geometry.material[surface]
    mats = scene.materials
    out = np.empty((verts.shape[0], 11), dtype=np.float32)
    out[:, :3] = verts[:, :3]
    out[:, 3:6] = normal
    out[:, 6:9] = np.array([m.color for m in mats], dtype=np.float64).reshape(-1, 3)[material]
    out[:, 9] = np.array([m.specular for m in mats], dtype=np.float64)[material]
    out[:, 10] = np.array([m.shininess for m in mats], dtype=np.float64)[material]
    return out, tris, origin


# ---------------------------------------------------------------- the window


def _glfw_message(exc) -> str:
    """glfw's "(65550) b'X11: ...'" as "X11: ..."."""
    match = re.fullmatch(r"\((\d+)\) b?(['\"])(.*)\2", str(exc).strip(), re.S)
    return match.group(3) if match else str(exc)


@dataclass
class FrameLog:
    """Per-frame times (seconds since the window opened) and states."""

    times: list = field(default_factory=list)
    states: list = field(default_factory=list)
    work: list = field(default_factory=list)  # per frame: {step: milliseconds} of the main thread

    def add(self, t: float, state: str, work: dict) -> None:
        self.times.append(t)
        self.states.append(state)
        self.work.append(work)

    def summary(self) -> dict:
        t = np.array(self.times)
        gaps = np.diff(t) if t.size > 1 else np.zeros(0)
        prev = np.array(self.states[:-1])
        refining = gaps[prev == "refining"] if gaps.size else gaps
        moving = gaps[prev == "moving"] if gaps.size else gaps
        return {
            "frames": int(t.size),
            "seconds": float(t[-1] - t[0]) if t.size > 1 else 0.0,
            "max_gap_ms": float(gaps.max() * 1e3) if gaps.size else 0.0,
            "max_gap_refining_ms": float(refining.max() * 1e3) if refining.size else 0.0,
            "p99_gap_refining_ms": float(np.percentile(refining, 99) * 1e3) if refining.size else 0.0,
            "refining_frames": int(refining.size),
            "fps_moving": float(moving.size / moving.sum()) if moving.size and moving.sum() > 0 else None,
            "moving_frames": int(moving.size),
        }

    def write(self, path: Path, extra: dict) -> None:
        doc = dict(extra)
        doc["summary"] = self.summary()
        doc["frames"] = [{"t": round(t, 6), "state": s, "ms": {k: round(v, 2) for k, v in w.items()}}
                         for t, s, w in zip(self.times, self.states, self.work)]
        path.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")


class Preview:
    """The window, its GL resources and the refinement state. Main thread only."""

    def __init__(self, scene, scene_path: Path, args, commands: list[Command]):
        from .pipeline import Geometry

        self.scene, self.scene_path, self.args = scene, scene_path, args
        self.map_mode = args.map_mode or scene.render.map
        self.method = args.method or scene.render.method
        self.geometry = Geometry(scene)
        self.home = scene.camera
        self.camera = scene.camera
        self.commands = collections.deque(commands)
        self.max_fps = args.max_fps
        self.log = FrameLog()
        self.window = None
        self.ctx = None
        self._owned: list = []  # GL objects this module created, released at close
        self.released = 0  # how many GL objects close() released
        self.gl_error: str | None = None  # ctx.error when the window closed
        self.solver = Solver(scene, self.map_mode)

        self.generation = 0
        self.last_change = -math.inf
        self.next_level = 0  # the next refinement level to submit
        self.map_parts: list = []  # bands of its map rasterised so far
        self.done_level = -1  # the finest level shown for this generation
        self.failed: str | None = None
        self.dead: str | None = None  # the solver process died
        self.solve_seconds: float | None = None
        self.image_tex = None  # exact image of done_level
        self.exact_pixels: np.ndarray | None = None  # full resolution, this generation
        self.map_tex = None
        self.map_level = -1
        self.keep_image = False  # method switch: show the old image until the new one
        self.show_map = False
        self.pending_saves: list[Path] = []
        self.pending_screenshots: list[Path] = []
        self.quit = False
        self.frame = 0
        self.mouse = {"left": False, "pan": False, "x": 0.0, "y": 0.0}
        self.title = ""

    # ---- set-up and tear-down

    def open(self) -> None:
        import glfw

        glfw.ERROR_REPORTING = {
            getattr(glfw, "FEATURE_UNAVAILABLE", 0x1000C): "ignore",
            getattr(glfw, "FEATURE_UNIMPLEMENTED", 0x1000D): "ignore",
            None: "raise",
        }
        if sys.platform.startswith("linux") and os.environ.get("DISPLAY") and hasattr(glfw, "PLATFORM_X11"):
            glfw.init_hint(glfw.PLATFORM, glfw.PLATFORM_X11)  # GLX, what moderngl finds first
        try:
            ok = glfw.init()
        except glfw.GLFWError as exc:
            raise self._no_display(_glfw_message(exc)) from None
        if not ok:
            raise self._no_display("glfw.init() failed")
        try:
            glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
            glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
            glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
            glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
            glfw.window_hint(glfw.DEPTH_BITS, 24)
            glfw.window_hint(glfw.SCALE_TO_MONITOR, True)
            self.window = glfw.create_window(self.args.width, self.args.height, self._title_text(), None, None)
        except glfw.GLFWError as exc:
            glfw.terminate()
            raise RenderError(f"cannot open the preview window: {_glfw_message(exc)}; render without a window: "
                              f"bsrt render {self.scene_path} -o out.png") from None
        if not self.window:
            glfw.terminate()
            raise RenderError(f"cannot open the preview window; render without a window: bsrt render {self.scene_path} -o out.png")
        glfw.make_context_current(self.window)
        glfw.swap_interval(0)  # frames are paced by max_fps; a blocking swap would delay input
        try:
            self.ctx = gl.create_window_context()
        except RenderError:
            self._close_window()
            raise
        w = self.window
        glfw.set_key_callback(w, self._on_key)
        glfw.set_mouse_button_callback(w, self._on_mouse_button)
        glfw.set_cursor_pos_callback(w, self._on_cursor)
        glfw.set_scroll_callback(w, self._on_scroll)
        glfw.set_framebuffer_size_callback(w, self._on_framebuffer_size)
        self.fb_size = tuple(glfw.get_framebuffer_size(w))
        self._create_gl()
        gl.program(self.ctx, "prelim")  # compile the map's program now, not in the first map band
        self.solver.start()
        self._changed(settle=True)

    def _no_display(self, detail: str) -> InputError:
        return InputError(
            f"no display for the preview window ({detail.strip()}); set DISPLAY (or run it under xvfb-run), "
            f"or render without a window: bsrt render {self.scene_path} -o out.png"
        )

    def _own(self, obj):
        self._owned.append(obj)
        return obj

    def _release(self, obj) -> None:
        if obj is not None:
            obj.release()
            self._owned.remove(obj)

    def _create_gl(self) -> None:
        ctx = self.ctx
        self.program = self._own(gl.load_program(ctx, "preview"))
        verts, tris, self.origin = fast_view_mesh(self.scene, self.geometry, self.camera, *self.fb_size)
        self.vbo = self._own(ctx.buffer(verts.tobytes()))
        self.ibo = self._own(ctx.buffer(tris.astype(np.uint32).tobytes()))
        self.mesh_vao = self._own(ctx.vertex_array(
            self.program, [(self.vbo, "3f 3f 3f 2f", "position", "normal", "albedo", "gloss")],
            index_buffer=self.ibo, index_element_size=4,
        ))
        self.quad_vao = self._own(ctx.vertex_array(self.program, []))
        self._set_lights()
        self.program["image"].value = 0
        from .image import srgb_encode

        self.background = srgb_encode(np.asarray(self.scene.film.background, dtype=np.float64)) / 255.0

    def _set_lights(self) -> None:
        lights = list(self.scene.lights)
        ambient = [light for light in lights if light.kind == "ambient"]
        others = [light for light in lights if light.kind != "ambient"]
        if ambient:  # ambient lights add up: one slot for all of them
            total = sum(np.array(light.color) * light.intensity for light in ambient)
            others.insert(0, replace(ambient[0], color=tuple(total), intensity=1.0))
        if len(others) > MAX_LIGHTS:
            print(f"bsrt preview: the fast view uses the first {MAX_LIGHTS} of {len(others)} lights", file=sys.stderr)
            others = others[:MAX_LIGHTS]
        kind = np.zeros(MAX_LIGHTS, dtype=np.int32)
        vector = np.zeros((MAX_LIGHTS, 3), dtype=np.float32)
        strength = np.zeros((MAX_LIGHTS, 3), dtype=np.float32)
        for k, light in enumerate(others):
            strength[k] = np.array(light.color) * light.intensity
            if light.kind == "point":
                kind[k] = 1
                vector[k] = np.array(light.position) - self.origin
            elif light.kind == "directional":
                kind[k] = 2
                vector[k] = -_unit(np.array(light.direction, dtype=np.float64))
        self.program["light_count"].value = len(others)
        self.program["light_kind"].write(kind.tobytes())
        self.program["light_vector"].write(vector.tobytes())
        self.program["light_strength"].write(strength.tobytes())

    def close(self) -> None:
        """Stop the solver, release every GL object, check GL errors, close the window."""
        import glfw

        self.solver.stop()
        error = None
        if self.ctx is not None:
            glfw.make_context_current(self.window)
            self.released = len(self._owned)
            for obj in reversed(list(self._owned)):
                self._release(obj)
            self.released += gl.release_cached(self.ctx)
            error = self.gl_error = self.ctx.error
            self.ctx.release()
            self.ctx = None
        self._close_window()
        if error not in (None, "GL_NO_ERROR"):
            raise RenderError(f"OpenGL reported {error} in the preview window")

    def _close_window(self) -> None:
        import glfw

        if self.window is not None:
            glfw.destroy_window(self.window)
            self.window = None
        glfw.terminate()

    # ---- input

    def _changed(self, settle: bool = True, keep_image: bool = False) -> None:
        """Camera, method or size changed: a new generation, refinement restarts."""
        self.generation += 1
        self.solver.cancel_before(self.generation)
        self.last_change = time.perf_counter() if settle else -math.inf
        self.next_level = 0
        self.map_parts = []
        self.done_level = -1
        self.failed = self.dead
        self.exact_pixels = None
        self.keep_image = keep_image and self.image_tex is not None
        if not self.keep_image:
            self._release(self.image_tex)
            self.image_tex = None
        self._release(self.map_tex)
        self.map_tex = None
        self.map_level = -1

    def _move(self, camera: Camera) -> None:
        self.camera = camera
        self._changed(settle=True)

    def _aspect(self) -> float:
        w, h = self.fb_size
        return w / max(h, 1)

    def press(self, name: str) -> None:
        """A key, by name (also the script's ``key NAME``)."""
        name = name.lower()
        if name in ("q", "escape"):
            self.quit = True
        elif name == "m":
            self.show_map = not self.show_map
        elif name in METHOD_KEYS:
            self.set_method(METHOD_KEYS[name])
        elif name == "s":
            self.request_save(None)
        elif name == "c":
            print(camera_toml(self.camera), flush=True)
        elif name == "r":
            self._move(self.home)
        elif name in ("plus", "minus"):
            self._move(zoom(self.camera, ZOOM_STEP if name == "plus" else 1.0 / ZOOM_STEP))
        elif name in ("left", "right", "up", "down"):
            dx = {"left": -1, "right": 1}.get(name, 0)
            dy = {"down": -1, "up": 1}.get(name, 0)
            self._move(orbit(self.camera, dx * KEY_ORBIT_DEGREES, dy * KEY_ORBIT_DEGREES))
        elif name.startswith("shift+"):
            d = name[6:]
            dx = {"left": -1, "right": 1}.get(d, 0) * KEY_PAN_FRACTION
            dy = {"down": -1, "up": 1}.get(d, 0) * KEY_PAN_FRACTION
            self._move(pan(self.camera, dx, dy, self._aspect()))

    def set_method(self, method: str) -> None:
        if method != self.method:
            self.method = method
            self._changed(settle=False, keep_image=True)

    def _on_key(self, window, key, scancode, action, mods) -> None:
        import glfw

        if action not in (glfw.PRESS, glfw.REPEAT):
            return
        shift = bool(mods & glfw.MOD_SHIFT)
        arrows = {glfw.KEY_LEFT: "left", glfw.KEY_RIGHT: "right", glfw.KEY_UP: "up", glfw.KEY_DOWN: "down"}
        if key in arrows:
            self.press(("shift+" if shift else "") + arrows[key])
        elif key in (glfw.KEY_KP_ADD, glfw.KEY_EQUAL, glfw.KEY_PAGE_UP):
            self.press("plus")
        elif key in (glfw.KEY_KP_SUBTRACT, glfw.KEY_MINUS, glfw.KEY_PAGE_DOWN):
            self.press("minus")
        elif key == glfw.KEY_ESCAPE:
            self.press("escape")
        elif action == glfw.PRESS:
            names = {glfw.KEY_M: "m", glfw.KEY_S: "s", glfw.KEY_C: "c", glfw.KEY_R: "r", glfw.KEY_Q: "q",
                     glfw.KEY_1: "1", glfw.KEY_2: "2", glfw.KEY_3: "3", glfw.KEY_4: "4",
                     glfw.KEY_KP_1: "1", glfw.KEY_KP_2: "2", glfw.KEY_KP_3: "3", glfw.KEY_KP_4: "4"}
            if key in names:
                self.press(names[key])

    def _on_mouse_button(self, window, button, action, mods) -> None:
        import glfw

        down = action == glfw.PRESS
        if button == glfw.MOUSE_BUTTON_LEFT:
            self.mouse["left"] = down
        elif button in (glfw.MOUSE_BUTTON_RIGHT, glfw.MOUSE_BUTTON_MIDDLE):
            self.mouse["pan"] = down
        self.mouse["x"], self.mouse["y"] = glfw.get_cursor_pos(window)
        if not down:
            self.last_change = time.perf_counter()  # settle from the release

    def _on_cursor(self, window, x, y) -> None:
        import glfw

        dx, dy = x - self.mouse["x"], y - self.mouse["y"]
        self.mouse["x"], self.mouse["y"] = x, y
        if not (dx or dy):
            return
        if self.mouse["left"]:
            # the scene turns with the cursor: drag right, the camera goes left; drag up, it goes down
            self._move(orbit(self.camera, dx * ORBIT_DEGREES_PER_PIXEL, dy * ORBIT_DEGREES_PER_PIXEL))
        elif self.mouse["pan"]:
            _, height = glfw.get_window_size(window)
            self._move(pan(self.camera, dx / max(height, 1), -dy / max(height, 1), self._aspect()))

    def _on_scroll(self, window, xoffset, yoffset) -> None:
        if yoffset:
            self._move(zoom(self.camera, ZOOM_STEP ** yoffset))

    def _on_framebuffer_size(self, window, width, height) -> None:
        if (width, height) != self.fb_size:
            self.fb_size = (width, height)
            self._changed(settle=True)

    # ---- refinement

    def level_size(self, level: int) -> tuple[int, int]:
        w, h = self.fb_size
        d = LEVELS[level]
        return max(1, -(-w // d)), max(1, -(-h // d))

    def _refine(self, now: float) -> None:
        """Rasterise the next band of the next level's map (one per frame, so
        the window never waits for a whole full-size map); when a level's map
        is complete, hand it to the solver."""
        if self.failed or self.next_level >= len(LEVELS) or min(self.fb_size) < 1:
            return
        if self.mouse["left"] or self.mouse["pan"] or now - self.last_change < SETTLE_SECONDS:
            return
        from .prelim import render_map

        level = self.next_level
        width, height = self.level_size(level)
        prelim = None
        if self.method != "martin" or self.show_map:
            bands = map_bands(width, height)
            band = bands[len(self.map_parts)]
            try:
                part = render_map(self.geometry.patches, self.camera, width, height, self.map_mode, ctx=self.ctx,
                                  rows=band if len(bands) > 1 else None)
            except (InputError, RenderError) as exc:
                self.failed = f"map: {exc}"
                return
            finally:
                self.ctx.screen.use()
            self.map_parts.append(part)
            if len(self.map_parts) < len(bands):
                return
            prelim = stitch_maps(self.map_parts)
            self.map_parts = []
            self._show_map(prelim, level)
        if prelim is not None:  # render() needs the seeds only; the picture stays here for key M
            prelim = replace(prelim, picture=np.zeros((0, 0, 3), dtype=np.uint8))
        self.solver.submit(Job(self.generation, level, self.method, self.camera, width, height, prelim))
        self.next_level += 1

    def _show_map(self, prelim, level: int) -> None:
        if level > self.map_level:
            self._release(self.map_tex)
            self.map_tex = self._texture(prelim.picture)
            self.map_level = level

    def _texture(self, pixels: np.ndarray):
        """An RGB8 texture of pixels (H, W, 3) uint8, row 0 at the top."""
        h, w = pixels.shape[:2]
        tex = self._own(self.ctx.texture((w, h), 3, np.ascontiguousarray(pixels[::-1]).tobytes(), alignment=1))
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        tex.repeat_x = tex.repeat_y = False
        return tex

    def _collect(self) -> None:
        for outcome in self.solver.outcomes():
            job = outcome.job
            if job.generation == -1:  # the solver process is gone: nothing more will come
                self.dead = self.failed = outcome.error
                print(f"bsrt preview: {outcome.error}", file=sys.stderr)
                continue
            if job.generation != self.generation:
                continue  # stale: the camera moved meanwhile
            if outcome.error is not None:
                self.failed = f"{job.method} failed: {outcome.error}"
                print(f"bsrt preview: {self.failed}", file=sys.stderr)
                continue
            if job.level <= self.done_level:
                continue
            self.solve_seconds = outcome.seconds
            self._release(self.image_tex)
            self.image_tex = self._texture(outcome.pixels)
            self.keep_image = False
            self.done_level = job.level
            if job.level == len(LEVELS) - 1:
                self.exact_pixels = outcome.pixels
                self._flush_saves()

    def refined(self) -> bool:
        return self.exact_pixels is not None

    def request_save(self, path: Path | None) -> None:
        self.pending_saves.append(path)
        self._flush_saves()

    def _flush_saves(self) -> None:
        if self.exact_pixels is None:
            return
        from .image import write_png

        for path in self.pending_saves:
            if path is None:
                path = self._free_name()
            write_png(path, self.exact_pixels)
            print(f"bsrt preview: saved {path}", file=sys.stderr)
        self.pending_saves = []

    def _free_name(self) -> Path:
        folder, stem = self.scene_path.parent, self.scene_path.stem
        for k in range(1, 10000):
            path = folder / f"{stem}-preview-{k:03d}.png"
            if not path.exists():
                return path
        raise InputError(f"{folder}: too many {stem}-preview-NNN.png files")

    def state(self) -> str:
        if self.mouse["left"] or self.mouse["pan"] or time.perf_counter() - self.last_change < SETTLE_SECONDS:
            return "moving"
        if self.failed:
            return "failed"
        if self.refined():
            return "exact"
        return "refining"

    # ---- drawing

    def draw(self) -> None:
        """Draw the frame on the window; pending screenshots get the same
        frame drawn into an offscreen framebuffer and read back (reading the
        window's own framebuffer sets GL_INVALID_OPERATION in moderngl)."""
        w, h = self.fb_size
        for path in self.pending_screenshots:
            from .image import write_png

            color = depth = fbo = None
            try:
                color = self._own(self.ctx.texture((w, h), 3))
                depth = self._own(self.ctx.depth_renderbuffer((w, h)))
                fbo = self._own(self.ctx.framebuffer(color_attachments=[color], depth_attachment=depth))
                self._draw_on(fbo, w, h)
                raw = fbo.read(viewport=(0, 0, w, h), components=3, dtype="f1", alignment=1)
            finally:
                gl.bind_default_framebuffer(self.ctx)
                for obj in (fbo, depth, color):
                    self._release(obj)
            write_png(path, np.frombuffer(raw, dtype=np.uint8).reshape(h, w, 3)[::-1].copy())
        self.pending_screenshots = []
        self._draw_on(self.ctx.screen, w, h)

    def _draw_on(self, target, w: int, h: int) -> None:
        ctx = self.ctx
        target.use()
        ctx.viewport = (0, 0, w, h)
        state = self.state()
        image = None
        if state != "moving":
            if self.show_map and self.map_tex is not None:
                image = self.map_tex
            elif self.image_tex is not None:
                image = self.image_tex
        elif self.keep_image and self.image_tex is not None:
            image = self.image_tex
        if image is not None:
            ctx.disable(moderngl.DEPTH_TEST)
            image.use(0)
            self.program["image_pass"].value = True
            self.quad_vao.render(moderngl.TRIANGLE_STRIP, vertices=4)
        else:
            self._draw_fast(w, h)

    def _draw_fast(self, w: int, h: int) -> None:
        from .prelim import depth_range

        ctx, cam = self.ctx, self.camera
        near, far = depth_range(self.geometry.patches, cam)
        local_eye = cam.eye - self.origin
        eye_from_local = np.eye(4)
        eye_from_local[:3, 3] = -local_eye
        clip_from_local = clip_from_eye(cam, w, h, near, far) @ eye_from_local
        self.program["image_pass"].value = False
        self.program["clip_from_local"].write(clip_from_local.T.astype("f4").tobytes())
        self.program["eye"].value = tuple(float(x) for x in local_eye)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        bg = self.background
        ctx.clear(float(bg[0]), float(bg[1]), float(bg[2]), 1.0, depth=1.0)
        self.mesh_vao.render(moderngl.TRIANGLES)

    def _title_text(self) -> str:
        parts = [f"bsrt preview: {self.scene_path.name}", self.method]
        state = self.state() if self.window else "opening"
        if self.failed:
            parts.append(self.failed.splitlines()[0][:120])
        elif state == "refining":
            divisors = LEVELS
            shown = divisors[self.done_level] if self.done_level >= 0 else None
            parts.append(f"refining {self.done_level + 1}/{len(divisors)}" + (f" (1/{shown} shown)" if shown and shown > 1 else ""))
        elif state == "exact":
            parts.append("exact")
        else:
            parts.append(state)
        if self.solve_seconds is not None:
            parts.append(f"last solve {self.solve_seconds:.2f} s")
        if self.show_map:
            parts.append("map (M)")
        if self.pending_saves:
            parts.append("will save when refined")
        return " | ".join(parts)

    # ---- the loop

    def _script_step(self) -> None:
        """Advance the script by what this frame allows."""
        while self.commands:
            cmd = self.commands[0]
            if not self._run_command(cmd):
                return
            self.commands.popleft()

    def _run_command(self, cmd: Command) -> bool:
        """Do (part of) cmd; True when it is finished."""
        name, a = cmd.name, cmd.args
        state = getattr(cmd, "state", None)
        if name in ("orbit", "pan", "zoom"):
            frames = a[-1] if len(a) == (3 if name != "zoom" else 2) else 1
            done = state or 0
            if name == "orbit":
                self._move(orbit(self.camera, a[0] / frames, a[1] / frames))
            elif name == "pan":
                self._move(pan(self.camera, a[0] / frames, a[1] / frames, self._aspect()))
            else:
                self._move(zoom(self.camera, a[0] ** (1.0 / frames)))
            cmd.state = done + 1
            return cmd.state >= frames
        if name == "key":
            self.press(a[0])
            return True
        if name == "method":
            self.set_method(a[0])
            return True
        if name == "resize":
            import glfw

            glfw.set_window_size(self.window, a[0], a[1])
            return True
        if name == "wait":
            return self.refined() or self.failed is not None
        if name == "frames":
            cmd.state = (state or 0) + 1
            return cmd.state > a[0]
        if name == "sleep":
            if state is None:
                cmd.state = time.perf_counter() + a[0]
                return False
            return time.perf_counter() >= state
        if name == "save":
            if self.failed is not None:
                raise RenderError(f"{cmd.text}: {self.failed}")
            if not self.refined():
                return False
            self.request_save(Path(a[0]))
            return True
        if name == "screenshot":  # finished once this frame is drawn (and written)
            if state is None:
                cmd.state = Path(a[0])
                self.pending_screenshots.append(cmd.state)
                return False
            return state not in self.pending_screenshots
        if name == "camera":
            text = camera_toml(self.camera)
            if a:
                Path(a[0]).write_text(text, encoding="utf-8")
            else:
                print(text, flush=True)
            return True
        if name == "reset":
            self._move(self.home)
            return True
        if name == "quit":
            self.quit = True
            return True
        raise AssertionError(name)

    def run(self) -> None:
        import glfw

        start = time.perf_counter()
        frame_seconds = 1.0 / self.max_fps if self.max_fps > 0 else 0.0
        next_frame = start
        limit = self.args.frames
        while not self.quit and not glfw.window_should_close(self.window):
            if min(self.fb_size) < 1:  # minimised: nothing to draw
                glfw.wait_events_timeout(0.25)
                continue
            clock = time.perf_counter()
            self._script_step()
            if self.quit:
                break
            work = {}
            now = time.perf_counter()
            work["script"] = (now - clock) * 1e3
            self._collect()
            clock = time.perf_counter()
            work["collect"] = (clock - now) * 1e3
            self._refine(now)
            last = limit is not None and self.frame + 1 >= limit
            if last and self.args.screenshot:
                self.pending_screenshots.append(Path(self.args.screenshot))
            state = self.state()
            now = time.perf_counter()
            work["refine"] = (now - clock) * 1e3
            self.draw()
            glfw.swap_buffers(self.window)
            clock = time.perf_counter()
            work["draw"] = (clock - now) * 1e3
            self.log.add(clock - start, state, work)
            self.frame += 1
            title = self._title_text()
            if title != self.title:
                glfw.set_window_title(self.window, title)
                self.title = title
            if last:
                break
            idle = state in ("exact", "failed") and not self.commands and not self.pending_saves
            next_frame = max(next_frame + frame_seconds, time.perf_counter())
            wait = next_frame - time.perf_counter()
            if idle:
                glfw.wait_events_timeout(0.25)  # nothing changes until an input
            elif wait > 0:
                glfw.wait_events_timeout(wait)
            else:
                glfw.poll_events()


def main(args) -> int:
    """``bsrt preview``: returns the exit code (errors raise InputError/RenderError)."""
    from .scene import load_scene

    for name in ("width", "height"):
        if getattr(args, name) < 1:
            raise InputError(f"--{name}: must be at least 1, got {getattr(args, name)}")
    if args.frames is not None and args.frames < 1:
        raise InputError(f"--frames: must be at least 1, got {args.frames}")
    if args.screenshot and not args.frames:
        raise InputError("--screenshot needs --frames N (the frame to write)")
    if args.screenshot and not args.screenshot.lower().endswith(".png"):
        raise InputError(f"{args.screenshot}: the output file name must end in .png")
    if args.max_fps < 0:
        raise InputError(f"--max-fps: must be 0 (no cap) or more, got {args.max_fps}")
    commands = []
    if args.script:
        try:
            text = Path(args.script).read_text(encoding="utf-8")
        except OSError as exc:
            raise InputError(f"{args.script}: cannot read the script ({exc.strerror})") from None
        commands += parse_script(text, args.script)
    if args.events:
        commands += parse_script(args.events, "--events")
    scene_path = Path(args.scene)
    if scene_path.suffix.lower() == ".toml":
        scene = load_scene(scene_path)
    else:  # a model file: the automatic camera and lights of `bsrt render MODEL`
        from .io import load_model
        from .scene import scene_for_model

        if not scene_path.is_file():
            raise InputError(f"{scene_path}: no such file")
        scene = scene_for_model(load_model(scene_path), args.width, args.height)
    for note in scene.notes:
        print(f"bsrt: warning: {note}", file=sys.stderr)
    preview = Preview(scene, scene_path, args, commands)
    try:
        preview.open()
        preview.run()
    finally:
        if preview.window is not None:
            preview.close()
    if args.frame_log:
        preview.log.write(Path(args.frame_log), {
            "scene": str(scene_path), "framebuffer": list(preview.fb_size), "levels": list(LEVELS),
            "max_fps": args.max_fps, "map_band_pixels": MAP_BAND_PIXELS, "gl_error": preview.gl_error,
            "gl_objects_released": preview.released, "gl_objects_left": len(preview._owned),
            "solver_swaps": preview.solver.swaps,
        })
    return 0

"""The preview's solver processes and their job protocol.

The window (main process) sends :class:`Job` s, each a level's camera, size,
method and preliminary map (rasterised by the window, so a solver process
never touches GL); a solver process answers each with an :class:`Outcome`:
the exact pixels, an error message, or neither (abandoned). A shared
generation counter marks every job older than the window's newest camera as
stale: queued ones are dropped, a running one stops at render()'s next stage
(its progress callback raises), or its process is killed when a warm spare
can take over at once.

Each process keeps one :class:`bsrt.rendering.pipeline.Geometry` (patches, hierarchy,
materials) for its whole life: jobs of the same scene never set it up again.
"""

from __future__ import annotations

import collections
import multiprocessing
import os
import queue
import signal
import sys
import threading
import time
from dataclasses import dataclass, replace

import numpy as np

from bsrt.errors import InputError, RenderError
from bsrt.rendering.options import RenderOptions
from bsrt.scene.camera import Camera

SOLVER_NICENESS = 10  # os.nice of the solver processes: the window keeps its core
STARTING, IDLE = -2, -1  # a worker's ``running`` value besides the generation it solves
DEVICE_CODES = {None: 0, "cpu": 1, "gpu": 2}  # a worker's ``device`` value (None: not warm yet)


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
    level: int  # index into the refinement's levels
    method: str
    camera: Camera
    width: int
    height: int
    prelim: object  # PrelimMap or None (only on the way there)
    sent: float = 0.0  # time.time() when the window submitted it
    # live (the GPU preview): the solver draws the map on its own context and solves to the end
    # even when the camera has moved on, so an exact image is shown while the camera moves
    live: bool = False
    map_picture: bool = False  # live: send the map's picture back (key M)


@dataclass
class Outcome:
    job: Job  # without its map
    pixels: np.ndarray | None = None  # (H, W, 3) uint8 sRGB; None: failed or abandoned
    error: str | None = None
    seconds: float = 0.0  # wall-clock seconds of the solve
    cpu_seconds: float = 0.0  # CPU seconds of the solver process (all its threads) during the solve
    waited: float = 0.0  # seconds from submitted to the solve's start (queue, transfer, an earlier job)
    map_picture: np.ndarray | None = None  # (H, W, 3) uint8: a live job's map, when it asked


def _solve(scene, map_mode, geometry, job: Job, generation) -> Outcome:
    """One job through render(); errors become the outcome's message."""
    from bsrt.rendering.pipeline import render

    def progress(stage, fraction=0.0):
        if job.generation < generation.value and not job.live:
            raise _Cancelled

    clock, cpu = time.perf_counter(), time.process_time()
    outcome = Outcome(replace(job, prelim=None), waited=time.time() - job.sent if job.sent else 0.0)
    try:
        options = RenderOptions.resolve(
            scene,
            method=job.method,
            map=map_mode,
            width=job.width,
            height=job.height,
            spp=1,
            adaptive_spp=0,
            camera=job.camera,
        )  # one sample per pixel: the interactive picture
        ctx = None if job.live else _NoGLHere()  # live: the map on this process's headless context
        result = render(scene, options, geometry=geometry, ctx=ctx, prelim=job.prelim, progress=progress)
        outcome.pixels = result.pixels
        if job.map_picture and result.prelim is not None:
            outcome.map_picture = result.prelim.picture
    except _Cancelled:
        pass
    except (InputError, RenderError) as exc:
        outcome.error = str(exc)
    except Exception as exc:  # shown in the title and on stderr; the window keeps running
        outcome.error = f"{type(exc).__name__}: {exc}"
    outcome.seconds = time.perf_counter() - clock
    outcome.cpu_seconds = time.process_time() - cpu
    return outcome


def _solver_process(scene, map_mode, jobs, outcomes, generation, running, device, cache=False) -> None:
    """A solver process's loop: render() each job that is still current (a live one in any case).

    jobs: Queue of Job (None: stop), at most one at a time; outcomes: the
    writing end of a pipe, an Outcome per job (pixels None when abandoned); generation: shared
    int, the window's newest generation; running: shared int, STARTING, IDLE
    or the generation of the job being solved; device: shared int, set once
    warm to the device the scene's ``device`` setting takes here (DEVICE_CODES).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl+C is the window's business
    from bsrt.allocator import keep_freed_memory

    keep_freed_memory()  # bsrt's own process, rendering again and again (bsrt/allocator.py)
    from bsrt.rendering.pipeline import Geometry

    geometry = Geometry(scene, cache)  # cache: through the prepared-geometry cache
    try:
        _ = geometry.bvh  # shadow rays and "martin" need it: build it before the first job
    except (InputError, RenderError) as exc:  # reported now; each job that needs it reports it again
        print(f"bsrt preview: warning: the solver could not build the hierarchy: {exc}", file=sys.stderr, flush=True)
    device.value = DEVICE_CODES[_device_here(scene.render.device)]
    running.value = IDLE
    parent = multiprocessing.parent_process()
    while True:
        try:
            job = jobs.get(timeout=1.0)
        except queue.Empty:
            if parent is not None and not parent.is_alive():
                return
            continue
        if job is None:
            return
        if job.generation < generation.value and not job.live:
            outcome = Outcome(replace(job, prelim=None))
        else:
            running.value = job.generation
            outcome = _solve(scene, map_mode, geometry, job, generation)
            running.value = IDLE
        try:
            outcomes.send(outcome)
        except OSError:  # the window is gone (its end of the pipe closed)
            return


def _device_here(setting: str) -> str:
    """The device ("cpu" or "gpu") that the ``device`` setting takes in this (solver) process, whose GL is its own
    headless context; "cpu" where that cannot be had or probed (a job then reports the error itself)."""
    from bsrt.rendering.gpu import choose_device

    try:
        return choose_device(setting)[0]
    except Exception:  # any failure to probe (EGL missing or broken): the CPU; the jobs report it
        return "cpu"


class _Worker:
    """One solver process, its job queue, its outcomes and its state (main process side).

    Outcomes come back through a pipe whose reading end a thread of the
    window's process watches: it takes each outcome as it comes (the image's
    transfer and unpickling off the frame loop) and calls ``wake``, so the
    window, waiting for its next frame, shows it at once (8 ms sooner on
    average at 60 frames a second). Only the solver process holds the writing
    end: when it ends, killed mid-message or not, the thread reads the end of
    the file and ends too."""

    def __init__(self, mp, scene, map_mode, generation, cache=False, wake=None):
        self.jobs = mp.Queue()
        reader, writer = mp.Pipe(duplex=False)
        self.arrived: queue.SimpleQueue[Outcome] = queue.SimpleQueue()  # filled by the watcher thread
        self.running = mp.Value("q", STARTING, lock=False)
        self.device = mp.Value("b", DEVICE_CODES[None], lock=False)
        self.job: Job | None = None  # in flight: sent, its outcome not back yet
        self.process = mp.Process(
            target=_solver_process,
            args=(scene, map_mode, self.jobs, writer, generation, self.running, self.device, cache),
            name="bsrt-preview-solver",
            daemon=True,
        )
        try:
            self.process.start()
        finally:
            writer.close()  # the solver process has its own
        if hasattr(os, "setpriority"):  # from the start (its imports too): the window keeps its core
            try:
                os.setpriority(os.PRIO_PROCESS, self.process.pid, SOLVER_NICENESS)
            except OSError as exc:  # it still works, competing with the window for the CPU
                print(f"bsrt preview: warning: cannot lower the solver's priority ({exc.strerror})", file=sys.stderr)
        self.watcher = threading.Thread(
            target=self._watch, args=(reader, wake), name="bsrt-preview-outcomes", daemon=True
        )
        self.watcher.start()

    def _watch(self, reader, wake) -> None:
        """The watcher thread: each outcome into ``arrived``, then wake(), until the process ends."""
        with reader:
            while True:
                try:
                    outcome = reader.recv()
                except (EOFError, OSError):  # the process ended (perhaps mid-message)
                    return
                self.arrived.put(outcome)
                if wake is not None:
                    try:
                        wake()
                    except Exception:  # (a window closing) the frame loop collects it at its next frame anyway
                        pass

    def send(self, job: Job) -> None:
        self.job = job
        self.jobs.put(job)

    def receive(self) -> list[Outcome]:
        out = []
        while True:
            try:
                out.append(self.arrived.get_nowait())
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
        self.watcher.join(timeout)  # the end of the pipe reached: no wake() after the window closes
        self._close_queues()

    def _close_queues(self) -> None:
        self.jobs.cancel_join_thread()
        self.jobs.close()


class Solver:
    """render() in solver processes, newest generation only (main process side).

    Processes, not a thread: the solver's NumPy code holds the GIL for much
    of its time (many small array operations, the hierarchy's traversal), and
    a thread doubled the time the window's own map bands took (frame gaps of
    130-180 ms at 800x600); the processes run niced, so the window also wins
    the CPU. Maps go there through a queue (pickled in multiprocessing's
    feeder thread, off the frame loop) and images come back through a pipe
    (read by a thread, _Worker), one job in flight per process.

    Cancelling. render() can only be stopped between its stages (its
    progress callback), and a full-size shading stage with shadow rays takes
    seconds. So a spare process waits, warm (geometry and hierarchy built):
    when the camera moves while the active process solves an older
    generation, that process is killed and the spare takes over at once; a
    new spare starts once the active process is warm. A live job (Job.live,
    the GPU preview) is never cancelled, and a live window keeps no spare.
    """

    def __init__(self, scene, map_mode, cache=False, wake=None):
        """wake: called from another thread as each outcome arrives (the window collects it then)."""
        self._mp = multiprocessing.get_context("spawn")  # never fork a process holding a GL context
        self._scene, self._map_mode, self._cache, self._wake = scene, map_mode, cache, wake
        self._generation = self._mp.Value("q", 0, lock=False)
        self._pending: collections.deque[Job] = collections.deque()
        self.active: _Worker | None = None
        self.spare: _Worker | None = None
        self._dying: list[_Worker] = []
        self._lost: str | None = None
        self._spares = True  # keep a warm spare (False once live: a live job is never cut short)
        self.swaps = 0

    def _worker(self) -> _Worker:
        return _Worker(self._mp, self._scene, self._map_mode, self._generation, self._cache, self._wake)

    def start(self) -> None:
        self.active = self._worker()

    def submit(self, job: Job) -> None:
        self._pending.append(job)
        self._feed()

    def device(self) -> str | None:
        """Where the active process solves: "cpu", "gpu", or None until it is warm."""
        code = self.active.device.value if self.active is not None else 0
        return {v: k for k, v in DEVICE_CODES.items()}[code]

    def drop_spare(self) -> None:
        """Stop the spare process and start no other."""
        self._spares = False
        if self.spare is not None:
            self.spare.stop(0.5)
            self.spare = None

    def busy(self) -> bool:
        """A job is queued or in flight."""
        return bool(self._pending) or (self.active is not None and self.active.job is not None)

    def cancel_before(self, generation: int) -> None:
        """Abandon every job older than generation (a live one in flight runs to its end)."""
        self._generation.value = generation
        self._pending = collections.deque(j for j in self._pending if j.generation >= generation)
        active, spare = self.active, self.spare
        if (
            active is not None
            and active.job is not None
            and not active.job.live
            and active.job.generation < generation
            and active.running.value == active.job.generation  # read whole and being solved
            and spare is not None
            and spare.running.value == IDLE
        ):
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
            if self._spares and self.spare is None and worker.running.value != STARTING:
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

"""``bsrt batch`` and ``bsrt animate`` on Dask, and the Python API ``bsrt.batch`` / ``bsrt.animate``.

Dask (``pip install 'bsrt[dask]'``) is optional: it is imported only here,
when one of these runs. By default a local cluster is started: one worker
process per core, one thread each (``--workers N`` to choose); with
``--scheduler ADDRESS`` the tasks go to a running cluster instead. The
engine (inputs, tasks, outputs, summary) is bsrt/batches/engine.py; the camera
paths bsrt/batches/animation.py.
The command line's ``bsrt batch`` / ``bsrt animate`` are bsrt/cli/batch.py.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import time
from pathlib import Path

from bsrt.errors import InputError
from bsrt.settings import checked_overrides

ANIMATION_KINDS = {"webp": ".webp", "apng": ".png"}


def require_dask(command: str):
    """The ``distributed`` module, or InputError naming the extra to install."""
    try:
        import distributed
    except ImportError:
        raise InputError(f"bsrt {command} needs Dask: pip install 'bsrt[dask]'") from None
    return distributed


@contextlib.contextmanager
def connect(command: str, workers: int | None = None, scheduler: str | None = None, client=None):
    """A Dask client: ``client`` itself, one for ``scheduler``, or a new local cluster
    of ``workers`` processes (default: one per core) with one thread each. A local cluster's
    own log messages below CRITICAL stay off stderr, in its workers too: bsrt reports each
    item's failure itself, and a worker's heartbeat meeting the closing scheduler at the end
    logged a 30-line traceback after the summary."""
    distributed = require_dask(command)
    if client is not None:
        yield client
        return
    if scheduler:
        try:
            connection = distributed.Client(scheduler, timeout="20s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
        with connection:
            yield connection
        return
    n = workers or os.cpu_count() or 1
    with (
        distributed.LocalCluster(
            n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0", silence_logs=logging.CRITICAL
        ) as cluster,
        distributed.Client(cluster) as local,
    ):
        yield local


def _output_folder(out) -> Path:
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{out}: cannot create the folder ({exc.strerror or exc})") from None
    return out


def _summary_path(path) -> Path | None:
    if path is None:
        return None
    path = Path(path)
    if path.suffix.lower() != ".json":
        raise InputError(f"{path}: the summary file name must end in .json")
    if not path.parent.is_dir():
        raise InputError(f"{path}: the folder {str(path.parent)!r} does not exist")
    return path


def batch(
    inputs,
    out,
    *,
    aov=False,
    workers=None,
    scheduler=None,
    client=None,
    resume=False,
    summary=None,
    progress=None,
    report=None,
    cache=True,
    **settings,
):
    """Render every scene or model file of ``inputs`` (files, folders, globs) to
    ``out/<name>.png`` (and ``<name>.npz`` with ``aov``) on Dask; returns the
    :class:`bsrt.batches.engine.Summary` (``.items``, ``.exit_code``, ``.to_dict()``).

    client: a ``distributed.Client`` to use; else scheduler (an address); else a
    local cluster of ``workers`` processes. summary: also write the JSON there.
    progress(stage, fraction), report(item): optional callbacks. cache: False
    reads the model files without the converted-model cache. settings: render
    settings overriding every file's (bsrt.settings.SETTINGS: width, spp, method, ...).
    Raises InputError for bad usage (an input that does not exist, no Dask).
    """
    from bsrt.batches import engine as batching

    start = time.perf_counter()
    require_dask("batch")
    paths = batching.discover([inputs] if isinstance(inputs, (str, os.PathLike)) else inputs)
    options = {"settings": checked_overrides(settings), "cache": bool(cache)}
    summary_file = _summary_path(summary)
    out = _output_folder(out)
    work, notes = batching.plan(paths, out, options, aov)
    for item, _ in work:
        item.notes = [n for n in notes if n.startswith(f"{item.input}: ")]
    with connect("batch", workers, scheduler, client) as c:
        items = batching.run(c, work, resume=resume, progress=progress, report=report)
    result = batching.Summary(items, time.perf_counter() - start, str(out))
    _write_summary(summary_file, result)
    return result


def animate(
    input,
    out,
    *,
    frames=None,
    orbit=None,
    fps=24.0,
    animation=None,
    workers=None,
    scheduler=None,
    client=None,
    resume=False,
    summary=None,
    progress=None,
    report=None,
    cache=True,
    **settings,
):
    """Render the frames of ``input`` (a scene or model file) to ``out/frame_0001.png``
    ... on Dask: an orbit of ``orbit`` degrees, else the scene's
    ``[[camera.keyframe]]`` path; ``animation`` "webp" or "apng" also writes
    ``out/<name>.webp`` / ``.png``. Returns the Summary (the animated file, if
    any, is its last item). cache: False reads the model files without the
    converted-model cache. settings: render settings, as for :func:`batch`."""
    from bsrt.batches import animation as camera_path
    from bsrt.batches import engine as batching
    from bsrt.scene.loading import CameraOverrides

    start = time.perf_counter()
    require_dask("animate")
    camera_path.check_fps(fps)
    if animation not in (None, *ANIMATION_KINDS):
        raise InputError(f"animation: expected 'webp' or 'apng', got {animation!r}")
    options = {"settings": checked_overrides(settings), "cache": bool(cache)}
    path = Path(input)
    root, files = batching.pack(path)
    # an orbit of a model file: the automatic camera centred on the model's up axis (bsrt/scene/auto.py)
    template = batching.Job(str(path), path.stem, files, root, options, CameraOverrides(turntable=orbit is not None))
    with batching.Unpacked(template) as local:
        scene = batching.load_job(template, local)
    if orbit is None and not scene.keyframes:
        raise InputError(f"{path}: no [[camera.keyframe]] tables in the file: give --orbit DEGREES or add keyframes")
    if frames is None:
        if orbit is not None:
            raise InputError("--frames: required with --orbit")
        frames = scene.keyframes[-1].frame
    cameras = camera_path.frame_cameras(scene, frames, orbit)
    summary_file = _summary_path(summary)
    out = _output_folder(out)
    work = []
    for k, cam in enumerate(cameras, start=1):
        name = f"frame_{k:04d}"
        overrides = CameraOverrides(tuple(cam.eye), tuple(cam.look_at), tuple(cam.up), float(cam.fov))
        job = batching.Job(str(path), name, files, root, options, overrides)
        work.append((batching.Item(str(path), str(out / f"{name}.png")), job))
    with connect("animate", workers, scheduler, client) as c:
        items = batching.run(c, work, resume=resume, progress=progress, report=report)
    if animation and not any(item.status == "failed" for item in items):
        items.append(_write_animation(items, out / f"{path.stem}{ANIMATION_KINDS[animation]}", fps, animation))
        if report:
            report(items[-1])
    result = batching.Summary(items, time.perf_counter() - start, str(out), frames=len(cameras))
    _write_summary(summary_file, result)
    return result


def _write_animation(frames, target: Path, fps: float, kind: str):
    """The animated file from the frames' PNGs (read once, in frame order), written atomically."""
    from bsrt.batches.animation import animation_writer
    from bsrt.batches.engine import Item
    from bsrt.errors import OutputError
    from bsrt.outputs import write_file

    start = time.perf_counter()
    item = Item(str(target), str(target))
    try:
        write_file(target, animation_writer([Path(f.output).read_bytes() for f in frames], fps, kind))
        item.status = "ok"
    except (OSError, OutputError) as exc:
        item.message = str(exc)
    item.seconds = time.perf_counter() - start
    return item


def _write_summary(path: Path | None, summary) -> None:
    if path is not None:
        from bsrt.rendering.image import write_text

        write_text(path, json.dumps(summary.to_dict(), indent=2) + "\n")

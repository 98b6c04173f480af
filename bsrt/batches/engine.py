"""Many renders as Dask tasks: the engine of ``bsrt batch`` and ``bsrt animate``.

The client finds the inputs (:func:`discover`), names their outputs
(:func:`output_names`), and packs each into a :class:`Job` that carries the
input's bytes and, for a scene, the bytes of the model files its
``[[import]]`` tables name by relative path, laid out as on the client's
disk. So workers need not share a file system with the client: a worker writes the files into a
private temporary folder, renders (:func:`render_job`) and returns the encoded PNG (and AOVs); the
client writes them atomically. An import given by absolute path is not carried: the worker reads it.

Each worker process renders with the process's one headless OpenGL context
(``gl.headless_context``, created by its first task and reused) and the
compiled kernels loaded once. Dask schedules; a task whose worker dies is
run again elsewhere (the scheduler's ``allowed-failures``, 3 by default). A
failing item (bad file, render error) is an item of the summary with its
message; it never stops the batch.
"""

from __future__ import annotations

import glob
import io
import os
import re
import tempfile
import time
import tomllib
import zipfile
from dataclasses import asdict, dataclass, field
from pathlib import Path

from bsrt.errors import InputError, OutputError, RenderError
from bsrt.scene.loading import CameraOverrides

SCENE_SUFFIX = ".toml"


def known_suffixes() -> tuple[str, ...]:
    """File name endings a folder or a glob is searched for: scenes and model files."""
    from bsrt.io import FORMATS

    return (SCENE_SUFFIX,) + tuple(FORMATS)


# ---------------------------------------------------------------------------
# Inputs and output names


def discover(inputs) -> list[Path]:
    """Files, folders (searched recursively for known endings) and glob patterns
    -> the input files, in the order given (each folder's and glob's sorted),
    each once. A path that does not exist, a folder with no input and a glob
    that matches none are InputErrors (bad usage: nothing is rendered)."""
    suffixes = known_suffixes()
    found: list[Path] = []
    for text in map(str, inputs):
        path = Path(text)
        if path.is_dir():
            files = _search(path, suffixes)
            if not files:
                raise InputError(f"{text}: no scene or model files in this folder ({' '.join(suffixes)})")
        elif path.exists():
            files = [path]
        elif re.search(r"[*?[]", text):
            files = []
            for match in sorted(glob.glob(text, recursive=True)):
                m = Path(match)
                files += _search(m, suffixes) if m.is_dir() else [m] if m.suffix.lower() in suffixes else []
            if not files:
                raise InputError(f"{text}: no scene or model file matches")
        else:
            raise InputError(f"{text}: no such file or folder")
        found += files
    seen, unique = set(), []
    for path in found:
        key = os.path.realpath(path)
        if key not in seen:
            seen.add(key)
            unique.append(path)
    return unique


def _search(folder: Path, suffixes) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.suffix.lower() in suffixes and p.is_file())


def output_names(paths: list[Path]) -> tuple[list[str], list[str]]:
    """(one output name per input, without extension; notes on renamed inputs).

    An input's name is its file name without the extension. Inputs whose
    names clash (case-insensitively: ``a/part.igs``, ``b/part.step``) are
    named by their path below the folder they share, ``/`` written ``-``
    (``a-part``, ``b-part``), with the extension kept where that is still
    ambiguous (``part.igs``, ``part.step``); a name still taken gets ``-2``,
    ``-3``, ... in input order. Depends only on the inputs, never on what
    is on disk, so a resumed batch finds the same names.
    """
    groups: dict[str, list[int]] = {}
    for i, p in enumerate(paths):
        groups.setdefault(p.stem.lower(), []).append(i)
    names = [p.stem for p in paths]
    notes = []
    for members in groups.values():
        if len(members) < 2:
            continue
        full = [os.path.abspath(paths[i]) for i in members]
        common = os.path.commonpath([os.path.dirname(f) for f in full])
        rel = [os.path.relpath(f, common) for f in full]
        bare = [os.path.splitext(r)[0] for r in rel]
        chosen = bare if len({b.lower() for b in bare}) == len(bare) else rel
        for i, name in zip(members, chosen):
            names[i] = name.replace(os.sep, "-")
    taken: set[str] = set()
    for i, name in enumerate(names):
        base, n = name, 1
        while name.lower() in taken:
            n += 1
            name = f"{base}-{n}"
        taken.add(name.lower())
        names[i] = name
        if name != paths[i].stem:
            notes.append(f"{paths[i]}: another input has the same name: written as {name}.png")
    return names, notes


# ---------------------------------------------------------------------------
# Jobs: what travels to a worker


@dataclass(frozen=True)
class Job:
    """One render task.

    input: the path the user gave. name: the output name (no extension).
    files: ((path relative to root, bytes), ...): the input first, then the
      model files a scene imports by relative path. root: the client's folder
      the files are laid out from (a worker's messages name it, not its own
      temporary folder). options: "settings" (checked render settings,
      bsrt.settings: name -> value, overriding the file's), "cache" (False:
      the worker reads model files without the converted-model cache; default True). camera: overrides (an animation's frame camera). aov: also
      return the per-pixel arrays.
    """

    input: str
    name: str
    files: tuple
    root: str
    options: dict
    camera: CameraOverrides = CameraOverrides()
    aov: bool = False


def pack(path: Path, cache: dict | None = None) -> tuple[str, tuple]:
    """(root, files) of a Job for ``path``: its bytes and, for a scene, those of
    the model files it imports by relative path that exist. ``cache`` (realpath
    -> bytes) keeps a file shared by several scenes read once. OS errors are
    InputErrors naming the path."""
    from bsrt.files import check_input_file

    cache = {} if cache is None else cache
    main = os.path.abspath(check_input_file(path, "scene or model file"))
    entries = [(main, _read(main, cache))]
    if Path(main).suffix.lower() == SCENE_SUFFIX:
        folder = os.path.dirname(main)
        for name in _relative_imports(entries[0][1]):
            target = os.path.join(folder, name)
            if os.path.isfile(target):
                entries.append((os.path.normpath(target), _read(target, cache)))
    root = os.path.commonpath([os.path.dirname(p) for p, _ in entries])
    return root, tuple((os.path.relpath(p, root), data) for p, data in entries)


def _read(path: str, cache: dict) -> bytes:
    key = os.path.realpath(path)
    if key not in cache:
        try:
            cache[key] = Path(path).read_bytes()
        except OSError as exc:
            raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    return cache[key]


def _relative_imports(scene_bytes: bytes) -> list[str]:
    """The ``file`` of each ``[[import]]`` given by relative path ([] for a scene
    that does not parse: the worker then reports what is wrong with it)."""
    try:
        data = tomllib.loads(scene_bytes.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError):
        return []
    imports = data.get("import", [])
    if not isinstance(imports, list):
        return []
    files = [t.get("file") for t in imports if isinstance(t, dict)]
    return [f for f in files if isinstance(f, str) and f and not os.path.isabs(f)]


class Unpacked:
    """``with Unpacked(job) as path``: the job's files written to a private
    temporary folder, ``path`` the input there; removed afterwards. ``mapped(text)``
    names the client's folder instead of the temporary one."""

    def __init__(self, job: Job):
        self.job = job
        self.folder: str | None = None

    def __enter__(self) -> Path:
        self._tmp = tempfile.TemporaryDirectory(prefix="bsrt-job-")
        self.folder = self._tmp.name
        for rel, data in self.job.files:
            target = Path(self.folder, rel)
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
        return Path(self.folder, self.job.files[0][0])

    def __exit__(self, *exc) -> None:
        self._tmp.cleanup()

    def mapped(self, text: str) -> str:
        return text.replace(self.folder, self.job.root) if self.folder else text


def load_job(job: Job, path: Path):
    """The Scene of a job's input (already unpacked at ``path``)."""
    from bsrt.scene.loading import load_input
    from bsrt.settings import with_settings

    settings = job.options.get("settings", {})
    scene = load_input(
        path,
        width=settings.get("width"),
        height=settings.get("height"),
        camera=job.camera,
        cache=job.options.get("cache", True),
    )
    return with_settings(scene, settings)


def render_job(job: Job) -> dict:
    """Run on a worker: unpack, load, render, encode. Never raises for a bad
    item: returns {"status": "ok" | "failed", "message", "png": bytes or None,
    "npz": bytes or None, "notes": [str], "seconds", "worker"}."""
    start = time.perf_counter()
    out = {"status": "failed", "message": "", "png": None, "npz": None, "notes": []}
    unpacked = Unpacked(job)
    try:
        with unpacked as path:
            scene = load_job(job, path)
            out["notes"] = [unpacked.mapped(n) for n in scene.notes]
            out["png"], out["npz"] = _render(scene, job)
            out["status"] = "ok"
    except (InputError, RenderError, OutputError) as exc:
        out["message"] = unpacked.mapped(str(exc))
    except MemoryError:
        out["message"] = "out of memory (a smaller film or fewer samples per pixel needs less)"
    except Exception as exc:  # a bug: reported with the item, the batch goes on
        out["message"] = unpacked.mapped(f"internal error: {type(exc).__name__}: {exc}")
    out["seconds"] = time.perf_counter() - start
    out["worker"] = _worker_name()
    return out


def _render(scene, job: Job) -> tuple[bytes, bytes | None]:
    from bsrt import npz
    from bsrt.rendering.image import png_writer
    from bsrt.rendering.pipeline import render

    # the job's settings are in the scene (load_job); no AOVs: a streamed film
    result = render(scene, keep=False, aovs=bool(job.aov))
    return _encoded(png_writer(result.image)), _encoded(npz.writer(result.aovs())) if job.aov else None


def _encoded(write) -> bytes:
    buffer = io.BytesIO()
    write(buffer)
    return buffer.getvalue()


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


# ---------------------------------------------------------------------------
# Outputs and the summary


_IEND = b"\x00\x00\x00\x00IEND\xaeB`\x82"  # the last chunk of every PNG: length 0, type, CRC


def complete_png(path: Path) -> bool:
    """True if ``path`` is a PNG that decodes to its end (every chunk's CRC, IEND)."""
    from PIL import Image

    try:
        with open(path, "rb") as f:  # Pillow reads a PNG cut before its IEND chunk without complaint
            f.seek(-len(_IEND), os.SEEK_END)
            if f.read() != _IEND:
                return False
        with Image.open(path) as image:
            if image.format != "PNG":
                return False
            image.load()
        with Image.open(path) as image:
            image.verify()
        return True
    except Exception:  # any decoding failure: not complete
        return False


def complete_npz(path: Path) -> bool:
    """True if ``path`` is a zip archive (.npz) whose every member reads back with its CRC."""
    try:
        with zipfile.ZipFile(path) as archive:
            return archive.testzip() is None
    except (OSError, zipfile.BadZipFile, EOFError):
        return False


@dataclass
class Item:
    """One input's outcome. status: "ok", "failed" or "skipped" (its outputs were
    complete already); output: the PNG (aov: the .npz, or None); worker: the Dask
    worker's address (None when nothing ran); seconds: the task's time on it."""

    input: str
    output: str
    status: str = "failed"
    message: str = ""
    seconds: float = 0.0
    worker: str | None = None
    aov: str | None = None
    notes: list = field(default_factory=list)


@dataclass
class Summary:
    """A batch's outcome: items in input order, wall-clock seconds, the output folder."""

    items: list[Item]
    seconds: float
    out: str
    frames: int | None = None  # an animation's frames: the items after them are its animated file

    def count(self, status: str, items: list[Item] | None = None) -> int:
        return sum(item.status == status for item in (self.items if items is None else items))

    @property
    def exit_code(self) -> int:
        """0 if every item succeeded (or was skipped), 1 if any failed."""
        return 1 if self.count("failed") else 0

    def line(self) -> str:
        """``12 frames: 12 rendered, 0 skipped, 0 failed, and the animated file x.webp, 3.1 s, into out``
        (an animation), else ``N items: ...``."""
        if self.frames is None:
            head, items, extra = f"{len(self.items)} items", self.items, ""
        else:
            head, items = f"{self.frames} frame{'s' if self.frames != 1 else ''}", self.items[: self.frames]
            extra = "".join(f", and the animated file {Path(i.output).name}" for i in self.items[self.frames :])
        return (
            f"{head}: {self.count('ok', items)} rendered, {self.count('skipped', items)} skipped, "
            f"{self.count('failed', items)} failed{extra}, {self.seconds:.1f} s, into {self.out}"
        )

    def to_dict(self) -> dict:
        return {
            "out": self.out,
            "seconds": self.seconds,
            "ok": self.count("ok"),
            "skipped": self.count("skipped"),
            "failed": self.count("failed"),
            **({} if self.frames is None else {"frames": self.frames}),  # an animation: items after them are its file
            "items": [asdict(item) for item in self.items],
        }


# ---------------------------------------------------------------------------
# Running


def run(
    client,
    work: list[tuple[Item, Job | None]],
    *,
    resume: bool = False,
    progress=None,
    report=None,
    window: int | None = None,
) -> list[Item]:
    """Render every (item, job) through ``client`` and write the outputs.

    An item whose job is None has already failed (its message set). With
    ``resume``, an item whose outputs are complete is skipped. At most
    ``window`` jobs are in flight at once (default: 4 per worker thread, at
    least 8), so the scheduler holds few jobs' bytes at a time.
    progress(stage, fraction): "starting" before the first job, then the items
    done; report(item) is called as each one finishes.
    """
    from distributed import as_completed

    total = len(work)
    done = 0

    def finished(item: Item) -> None:
        nonlocal done
        done += 1
        if report:
            report(item)
        if progress:
            progress(f"{done}/{total} items", done / max(total, 1))

    pending = []
    for item, job in work:
        if job is None:
            finished(item)
        elif resume and complete_png(Path(item.output)) and (item.aov is None or complete_npz(Path(item.aov))):
            item.status, item.message = "skipped", "outputs complete already"
            finished(item)
        else:
            pending.append((item, job))
    if pending and progress:
        progress("starting", 0.0)  # the inputs are checked: the work begins (the CLI compiles here on a first run)
    if window is None:
        threads = sum(w.get("nthreads", 1) for w in client.scheduler_info()["workers"].values())
        window = max(8, 4 * threads)
    queue = iter(pending)
    items = {}
    futures = as_completed()
    for item, job in _take(queue, window):
        items[_submit(client, futures, job)] = item
    for future in futures:
        item = items.pop(future.key)
        _collect(future, item)
        future.release()
        finished(item)
        for next_item, job in _take(queue, 1):
            items[_submit(client, futures, job)] = next_item
    return [item for item, _ in work]


def _take(queue, n: int):
    for _ in range(n):
        entry = next(queue, None)
        if entry is None:
            return
        yield entry


def _submit(client, futures, job: Job):
    future = client.submit(render_job, job, pure=False, key=f"bsrt-{job.name}-{os.urandom(4).hex()}")
    futures.add(future)
    return future.key


def _collect(future, item: Item) -> None:
    """The task's result into ``item``, its outputs written (all or none)."""
    from bsrt.outputs import Outputs

    try:
        result = future.result()
    except Exception as exc:  # the task could not run (e.g. its worker died again and again)
        item.message = f"{type(exc).__name__}: {exc}"
        return
    item.seconds, item.worker = result["seconds"], result["worker"]
    item.notes += result["notes"]
    if result["status"] != "ok":
        item.message = result["message"]
        return
    try:
        with Outputs() as outputs:
            outputs.write(item.output, lambda f: f.write(result["png"]))
            if item.aov:
                outputs.write(item.aov, lambda f: f.write(result["npz"]))
            outputs.commit()
    except OutputError as exc:
        item.message = str(exc)
        return
    item.status = "ok"


def plan(paths: list[Path], out: Path, options: dict, aov: bool) -> tuple[list[tuple[Item, Job | None]], list[str]]:
    """(item, job) per input file (job None: it could not be read), and the renaming notes."""
    names, notes = output_names(paths)
    cache: dict = {}
    work = []
    for path, name in zip(paths, names):
        item = Item(str(path), str(out / f"{name}.png"), aov=str(out / f"{name}.npz") if aov else None)
        try:
            root, files = pack(path, cache)
        except InputError as exc:
            item.message = str(exc)
            work.append((item, None))
            continue
        work.append((item, Job(str(path), name, files, root, options, aov=aov)))
    return work, notes

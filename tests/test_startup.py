"""Start-up and the first run (issue 24): what the render path imports, where the kernels are
cached, the first run's compile (announced, ahead of the render, in parallel), ``bsrt doctor
--compile``. Speed itself is measured by ``bsrt bench`` (start-up and first-run rows), never here."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from bsrt.kernels import compile as kernels
from bsrt.kernels import jit, tables
from bsrt.progress import Progress
from bsrt.rendering import bench

ROOT = Path(__file__).resolve().parent.parent
COLUMN = ROOT / "scenes" / "column.toml"
HEAVY = ("OCP", "dask", "distributed", "glfw", "bsrt.preview", "bsrt.batches.engine", "scipy.linalg")


def _env(**changes) -> dict:
    """This checkout's bsrt in a child, the kernel cache as ``changes`` say (None: unset)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONDONTWRITEBYTECODE": "1"}
    for key, value in changes.items():
        if value is None:
            env.pop(key, None)
        else:
            env[key] = str(value)
    return env


def _modules_after(code: str, env=None) -> set[str]:
    """The top names of sys.modules (and bsrt's own modules) after ``code`` runs in a new process."""
    probe = code + "\nimport sys, json; print(json.dumps(sorted(sys.modules)))"
    out = subprocess.run(
        [sys.executable, "-c", probe], env=env or _env(), capture_output=True, text=True, timeout=600, check=True
    ).stdout
    return set(json.loads(out.strip().splitlines()[-1]))


def test_the_command_line_parser_imports_neither_numba_nor_any_extra():
    loaded = _modules_after(
        "from bsrt.cli.parser import _parser; _parser().parse_args(['render', 'x.toml', '-o', 'x.png'])"
    )
    assert not loaded & {"numba", "moderngl", *HEAVY}, sorted(loaded & {"numba", "moderngl", *HEAVY})


def test_import_bsrt_loads_nothing_heavy():
    loaded = _modules_after("import bsrt")
    assert not loaded & {"numpy", "numba", "moderngl", *HEAVY}


@pytest.mark.gl
def test_a_cli_render_imports_no_opencascade_dask_window_or_preview(tmp_path):
    loaded = _modules_after(
        f"from bsrt.cli import main\nassert main(['render', {str(COLUMN)!r}, '-o', {str(tmp_path / 'c.png')!r}, "
        "'--width', '8', '--height', '8']) == 0"
    )
    assert (tmp_path / "c.png").stat().st_size > 0
    assert "numba" in loaded and "moderngl" in loaded  # it did render
    assert not loaded & set(HEAVY), sorted(loaded & set(HEAVY))


def test_importing_the_kernels_compiles_and_loads_none_of_the_explicitly_typed_ones(tmp_path):
    """njit_typed kernels compile (or load) when a caller first needs them, not at import."""
    code = (
        "import sys; sys.path.insert(0, 'tests')\n"
        "from kernel_signatures import dispatchers\n"
        "from bsrt.kernels.jit import OneSignatureDispatcher\n"
        "typed = {n: d for n, d in dispatchers().items() if isinstance(d, OneSignatureDispatcher)}\n"
        "print(sorted(typed), sorted(n for n, d in typed.items() if d.signatures))"
    )
    env = _env(NUMBA_CACHE_DIR=tmp_path / "cache")
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True, check=True)
    typed, compiled = out.stdout.split("] [")
    assert "'flatten._cut'" in typed and "'nets.split_half'" in typed
    assert compiled == "]\n"


def test_an_explicitly_typed_kernel_compiles_its_one_signature_at_the_first_call_from_a_kernel():
    from numba import njit

    from bsrt.kernels.jit import njit_typed

    @njit_typed("float64(float64, int64)")
    def scaled(x, k):
        return x * k

    @njit
    def caller(x, k):
        return scaled(x, 2) + scaled(x, k)  # a literal and a variable: one specialisation all the same

    assert scaled.signatures == []
    assert caller(1.5, 3) == 7.5
    assert [str(s) for s in scaled.signatures] == ["(float64, int64)"]


@pytest.fixture
def cache_home(tmp_path, monkeypatch):
    """$XDG_CACHE_HOME in tmp_path, no NUMBA_CACHE_DIR (numba read it at import: its config too)."""
    import numba

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.setattr(numba.config, "CACHE_DIR", "")
    monkeypatch.setattr(jit, "_writable", set())
    monkeypatch.setattr(jit, "_checked", set())
    return tmp_path / "xdg"


def test_the_kernels_cache_in_the_users_cache_folder(cache_home):
    """$XDG_CACHE_HOME/bsrt/kernels/<source folder>, not inside the package; other functions
    are left to numba's own locators."""
    from numba.core import caching

    kernel = tables.permute_rows.py_func
    locator = jit.KernelCacheLocator.from_function(kernel, tables.__file__)
    folder = Path(locator.get_cache_path())
    assert folder.parent == cache_home / "bsrt" / "kernels"
    assert folder.name.startswith("kernels_")  # numba's naming: the source folder's name and a hash of its path
    assert (folder / "bsrt-kernels-epoch").read_text() == f"{_version()} {jit.CACHE_EPOCH}\n"
    assert jit.KernelCacheLocator.from_function(_version, __file__) is None
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
    assert impl._locator_classes[:3] == list(jit.LOCATORS)


def test_an_unwritable_cache_folder_falls_back_to_the_package_folder(cache_home, monkeypatch, tmp_path):
    """A cache home under a plain file cannot be created (even by root): the package's own
    __pycache__ takes the machine code instead, and last the temporary folder."""
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker / "cache"))
    kernel = tables.permute_rows.py_func
    assert jit.KernelCacheLocator.from_function(kernel, tables.__file__) is None
    package = jit.PackageCacheLocator.from_function(kernel, tables.__file__)
    assert Path(package.get_cache_path()) == Path(tables.__file__).resolve().parent / "__pycache__"
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    last = jit.TemporaryCacheLocator.from_function(kernel, tables.__file__)
    assert Path(last.get_cache_path()).parent.parent == tmp_path / "tmp"


def test_machine_code_of_another_version_is_dropped_once(tmp_path):
    """The stale-cache purge works in the new folder: files under another version's marker go,
    the marker is rewritten, and a second look changes nothing."""
    folder = tmp_path / "kernels"
    folder.mkdir()
    (folder / "bsrt-kernels-epoch").write_text("0.0.1 1\n")
    for name in ("a.f-1.py311.nbi", "a.f-1.py311.1.nbc", "notes.txt"):
        (folder / name).write_text("x")
    jit.drop_stale_machine_code(str(folder))
    assert sorted(p.name for p in folder.iterdir()) == ["bsrt-kernels-epoch", "notes.txt"]
    assert (folder / "bsrt-kernels-epoch").read_text() == f"{_version()} {jit.CACHE_EPOCH}\n"
    (folder / "b.g-2.py311.nbi").write_text("x")
    jit._checked.discard(str(folder))  # a new process
    jit.drop_stale_machine_code(str(folder))
    assert (folder / "b.g-2.py311.nbi").exists()  # the same version: kept


def test_an_edit_to_any_kernel_file_invalidates_every_kernel_of_the_folder(tmp_path, cache_home):
    """A kernel inlines its callees from other files: its machine code is checked against all the
    folder's sources (numba alone checks the kernel's own file), and files that are not sources
    do not count."""
    (tmp_path / "caller.py").write_text("def f():\n    return g()\n")
    (tmp_path / "callee.py").write_text("def g():\n    return 1\n")
    before = jit.folder_source_stamp(str(tmp_path))
    (tmp_path / "notes.txt").write_text("not a source")
    assert jit.folder_source_stamp(str(tmp_path)) == before
    (tmp_path / "callee.py").write_text("def g():\n    return 2\n")
    assert jit.folder_source_stamp(str(tmp_path)) != before
    locator = jit.KernelCacheLocator.from_function(tables.permute_rows.py_func, tables.__file__)
    assert locator.get_source_stamp() == jit.folder_source_stamp(str(Path(tables.__file__).resolve().parent))


def test_a_kernel_loaded_from_the_cache_runs_and_links_into_a_kernel_compiled_after_it(tmp_path):
    """Its cache made at its first call, loaded without numba's registry refresh and with its kept
    bitcode unparsed (jit.KernelCache, jit.LoadedLibrary): it runs, and a kernel compiled later in the same process that calls it
    links its bitcode (parsed then) and gets the same answers."""
    code = (
        "import numpy as np, numba\n"
        "from bsrt.kernels.prelim import normalise_rows\n"
        "from bsrt.kernels.jit import LoadedLibrary\n"
        "d = np.array([[3.0, 0.0, 4.0], [0.0, 2.0, 0.0]]); o = np.array([[1.0, 2.0, 3.0]])\n"
        "out, origin = np.empty_like(d), np.empty_like(d)\n"
        "print(type(normalise_rows._cache).__name__)\n"
        "normalise_rows(0, 2, d, out, o, origin)\n"
        "print(type(normalise_rows._cache).__name__)\n"
        "assert np.allclose(out, [[0.6, 0.0, 0.8], [0.0, 1.0, 0.0]]) and np.all(origin == o)\n"
        "(library,) = [cres.library for cres in normalise_rows.overloads.values()]\n"
        "print(type(library).__name__, library._shared_module is None)\n"
        "@numba.njit\n"
        "def twice(start, d, o):  # start: an argument (a literal 0 would be another specialisation)\n"
        "    out, origin = np.empty_like(d), np.empty_like(d)\n"
        "    normalise_rows(start, d.shape[0], d, out, o, origin)\n"
        "    return 2.0 * out\n"
        "assert np.allclose(twice(0, d, o), 2.0 * out) and len(normalise_rows.overloads) == 1\n"
        "print(library._shared_module is None)\n"
    )
    env = _env(NUMBA_CACHE_DIR=tmp_path / "cache")
    runs = [
        subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True) for _ in "ab"
    ]
    assert [r.returncode for r in runs] == [0, 0], runs[1].stderr
    # the cache is made at the first call (jit._DeferredCache); compiled, then cached
    assert runs[0].stdout.split() == ["_DeferredCache", "KernelCache", "JITCodeLibrary", "False", "False"]
    # loaded from the cache, its bitcode parsed only to link it
    assert runs[1].stdout.split() == ["_DeferredCache", "KernelCache", "LoadedLibrary", "True", "False"]


def test_a_kernel_is_cached_under_the_sources_of_its_modules_import(monkeypatch):
    """Its cache is made at its first use (jit._DeferredCache), maybe after a file of the folder
    was edited: the machine code compiled from the source in memory must not be stored under the
    edited sources' stamp (a later process would load it for code it was not compiled from)."""
    folder = str(Path(tables.__file__).resolve().parent)
    at_import = jit.source_stamp_at_import(tables.permute_rows.py_func)
    assert at_import == jit._import_stamps["bsrt.kernels.tables"] == jit.folder_source_stamp(folder)
    monkeypatch.setattr(jit, "folder_source_stamp", lambda folder: b"edited since")
    locator = jit.KernelCacheLocator.from_function(tables.permute_rows.py_func, tables.__file__)
    assert locator.get_source_stamp() == at_import


@pytest.mark.gl
def test_a_second_cli_render_takes_the_geometry_from_the_cache_and_no_cache_writes_none(tmp_path):
    env = _env(BSRT_CACHE_DIR=tmp_path / "cache")
    entries = tmp_path / "cache" / "geometry"
    pictures = []
    for extra, count in ((["--no-cache"], 0), ([], 1), ([], 1)):
        out = tmp_path / f"{len(pictures)}.png"
        argv = [sys.executable, "-m", "bsrt", "render", str(COLUMN), "--width", "8", "--height", "8", "-o", str(out)]
        run = subprocess.run(argv + extra, env=env, capture_output=True, text=True)
        assert run.returncode == 0 and run.stderr == "", run.stderr
        assert len(list(entries.glob("*.geometry"))) == count
        pictures.append(out.read_bytes())
    assert pictures[0] == pictures[1] == pictures[2]  # built, stored, read back: the same image


def test_the_compile_is_dealt_by_family_longest_first_to_the_least_loaded_worker():
    seconds = {"traverse.a": 10.0, "roots.b": 3.0, "flatten.c": 6.0, "flatten.d": 4.0, "prelim.e": 5.0, "x.f": 1.0}
    # families: hits (traverse, roots) 13, tree (flatten) 10, map (prelim) 5, x.f alone 1
    # hits -> 0 (13); tree -> 1 (10); map -> 1 (15); x.f -> 0 (14)
    record = {"seconds": seconds}  # no solo seconds: families stay whole
    assert kernels._plan(record, 2) == (
        [["traverse.a", "roots.b", "x.f"], ["flatten.c", "flatten.d", "prelim.e"]],
        15.0,
    )
    assert kernels._plan(record, 4) == (
        [["traverse.a", "roots.b"], ["flatten.c", "flatten.d"], ["prelim.e"], ["x.f"]],
        13.0,
    )


def test_a_family_is_split_where_that_shortens_the_longest_share():
    seconds = {"traverse.a": 10, "lighting.g": 6, "roots.b": 3, "flatten.c": 6, "flatten.d": 4, "prelim.e": 5, "x.f": 1}
    solo = {**seconds, "lighting.g": 12, "flatten.d": 5}  # g shares a's callees: 12 s alone, 6 s after a
    record = {"seconds": seconds, "solo": solo}
    # two workers: hits whole (19) against tree, map and x.f (16): 19; hits split (g 12, a 10, b 3) deals
    # g, tree, a, map, b, f -> loads 12+5+3+1 = 21 and 10+10 = 20: longer, so hits stays whole
    assert kernels._plan(record, 2) == (
        [["traverse.a", "lighting.g", "roots.b"], ["flatten.c", "flatten.d", "prelim.e", "x.f"]],
        19,
    )
    # four: hits whole 19; split: g 12 | tree 10 | a 10 | e 5 + b 3 + f 1 = 12; tree split too
    # (c 6, d 5): g 12 | a 10 | c 6 + b 3 + f 1 | e 5 + d 5 = 12, no shorter: tree stays whole
    assert kernels._plan(record, 4) == (
        [["lighting.g"], ["flatten.c", "flatten.d"], ["traverse.a"], ["prelim.e", "roots.b", "x.f"]],
        12,
    )


def test_the_recorded_signatures_cover_every_entry_kernel():
    record = kernels.recorded()
    assert record is not None, "bsrt/kernels/signatures.pickle: run scripts/record_kernel_signatures.py"
    names = {kernels.name_of(k) for k in kernels.ENTRY_KERNELS}
    assert set(record["signatures"]) == names == set(record["seconds"]) == set(record["solo"])
    assert all(len(sigs) == 1 for sigs in record["signatures"].values())  # one specialisation each


def test_the_render_time_left_does_not_count_the_compile():
    class Clock:
        now = 0.0

        def __call__(self):
            return self.now

    clock, out = Clock(), io.StringIO()
    bar = Progress(out, lines=True, clock=clock)
    bar("compile", 0.0)
    clock.now = 30.0  # 30 s of compiling
    bar("setup", 0.0)
    clock.now = 32.0
    bar("map", 0.5)  # 2 s of render for half of it: 2 s left (counting the compile would say 32 s)
    assert out.getvalue().splitlines()[-1] == "bsrt:  50% map, 32 s, about 2.0 s left"


def test_the_startup_rows_of_bench():
    text = bench.format_startup(
        {
            "startup": {
                "repeat": 5,
                "render_wall": 1.25,
                "render_cpu": 1.0,
                "numpy_wall": 0.25,
                "numpy_cpu": 0.125,
                "startup_wall": 1.0,
                "startup_cpu": 0.875,
                "load_average": [2.0, 3.0],
            },
            "first_run": {"first_run_wall": 21.5, "first_run_cpu": 40.25, "load_average": [1.0, 2.5]},
        }
    )
    assert text.splitlines() == [
        "start-up: 16x16 CLI render 1.25 s wall (1.00 s CPU) - python -c 'import numpy' 0.25 s (0.12 s) = "
        "1.00 s wall (0.88 s CPU), medians of 5, load 2.0-3.0",
        "first run (empty kernel cache): 16x16 CLI render 21.5 s wall (40.2 s CPU, compile workers included), "
        "load 1.0-2.5",
    ]


@pytest.mark.gl
def test_a_first_render_with_an_empty_cache_announces_the_compile_and_fills_the_cache(tmp_path):
    """stderr is a pipe here, not a terminal: the compile is still announced, once."""
    env = _env(XDG_CACHE_HOME=tmp_path / "xdg", NUMBA_CACHE_DIR=None)
    argv = [sys.executable, "-m", "bsrt", "render", str(COLUMN), "-o", str(tmp_path / "c.png")]
    argv += ["--width", "8", "--height", "8"]
    first = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=1800)
    assert first.returncode == 0, first.stderr
    assert first.stderr.startswith("bsrt: compiling bsrt's kernels once for this machine (about ")
    assert first.stderr.count("\n") == 1
    assert (tmp_path / "c.png").stat().st_size > 0
    folder = _folder(env)
    assert folder.parent == tmp_path / "xdg" / "bsrt" / "kernels"
    assert len(list(folder.glob("*.nbi"))) >= len(kernels.ENTRY_KERNELS)
    again = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0 and again.stderr == ""


@pytest.mark.parametrize("bad", ["scene", "output folder"])
def test_bad_input_on_a_first_run_is_one_line_the_compile_unsaid_and_stopped(tmp_path, bad):
    """The compile starts before the renderer's imports; a scene that fails to load, or an output
    in a folder that does not exist, is its one message (the compile's notice comes only once the
    load is done), exit 2, nothing written. The workers share stderr's pipe, so the run returns
    only once they have ended: stopped, they have cached far from every kernel."""
    env = _env(XDG_CACHE_HOME=tmp_path / "xdg", NUMBA_CACHE_DIR=None)
    scene, out = tmp_path / "bad.toml", tmp_path / ("c.png" if bad == "scene" else "none/c.png")
    scene.write_text(COLUMN.read_text().replace("[camera]", "[camera]\nzoom = 2", 1) if bad == "scene" else "")
    argv = [sys.executable, "-m", "bsrt", "render", str(scene if bad == "scene" else COLUMN), "-o", str(out)]
    run = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=600)
    expected = (
        "bad.toml: camera.zoom: unknown key" if bad == "scene" else f"{out}: the folder '{out.parent}' does not exist"
    )
    assert (run.returncode, run.stderr) == (2, f"bsrt: error: {expected}\n")
    assert not out.exists()
    assert len(list(_folder(env).glob("*.nbi"))) < len(kernels.ENTRY_KERNELS) // 2


@pytest.mark.gl
def test_doctor_compile_fills_an_empty_cache(tmp_path):
    env = _env(XDG_CACHE_HOME=tmp_path / "xdg", NUMBA_CACHE_DIR=None)
    before = subprocess.run([sys.executable, "-m", "bsrt", "doctor"], env=env, capture_output=True, text=True)
    assert "kernels:         not compiled yet (bsrt doctor --compile does it now)" in before.stdout
    doctor = subprocess.run(
        [sys.executable, "-m", "bsrt", "doctor", "--compile"], env=env, capture_output=True, text=True, timeout=1800
    )
    assert doctor.returncode == 0, doctor.stderr
    assert "kernels:         compiled in " in doctor.stdout
    code = "from bsrt.kernels import compile as k; print(k.is_cached())"
    assert subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True).stdout == "True\n"
    after = subprocess.run([sys.executable, "-m", "bsrt", "doctor"], env=env, capture_output=True, text=True)
    assert "kernels:         cached (cache: " in after.stdout


@pytest.mark.gl
def test_an_unwritable_cache_folder_still_renders(tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    env = _env(XDG_CACHE_HOME=blocker / "cache", NUMBA_CACHE_DIR=None)
    done = subprocess.run(
        [sys.executable, "-m", "bsrt", "render", str(COLUMN), "-o", str(tmp_path / "c.png"), "--width", "8"]
        + ["--height", "8"],
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,
    )
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "c.png").stat().st_size > 0


def _folder(env) -> Path:
    code = "from bsrt.kernels import compile as k; print(k.cache_folder())"
    return Path(subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True).stdout.strip())


def _version() -> str:
    from bsrt import __version__

    return __version__


_REUSE = """
import resource, sys
import numpy as np
from bsrt.allocator import keep_freed_memory
print(keep_freed_memory() if sys.argv[1] == "keep" else False)
faults = []
for _ in range(4):  # a render's pattern: film-sized arrays made, filled and freed together
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    arrays = [np.ones(512 * 512) for _ in range(24)]
    del arrays
    faults.append(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
print(max(faults[1:]))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc (the CI machine's)")
def test_the_program_keeps_freed_memory_for_the_next_renders_arrays():
    """keep_freed_memory (the bsrt program calls it): a second round of film-sized arrays reuses
    the first round's memory instead of faulting in fresh pages (glibc unmaps and trims them by
    default); a user's own thresholds are left alone, other malloc settings do not count."""
    from bsrt import allocator

    # glibc's defaults in the children: Dask's nanny puts its MALLOC_TRIM_THRESHOLD_ into the
    # environment of the process that starts a cluster (this one, after the batch tests)
    defaults = _env(**dict.fromkeys(allocator.user_settings()))
    runs = {}
    for mode in ("default", "keep"):
        out = subprocess.run([sys.executable, "-c", _REUSE, mode], env=defaults, capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
        runs[mode] = out.stdout.split()
    assert runs["keep"][0] == "True"
    pages = 24 * 512 * 512 * 8 // 4096
    assert int(runs["default"][1]) > pages // 2  # the setting is what makes the difference here
    assert int(runs["keep"][1]) < pages // 20
    for variable, kept in (("MALLOC_TOP_PAD_", "False"), ("GLIBC_TUNABLES", "False"), ("MALLOC_ARENA_MAX", "True")):
        user = subprocess.run(
            [sys.executable, "-c", "from bsrt.allocator import keep_freed_memory as k; print(k())"],
            env={**defaults, variable: "2" if variable == "MALLOC_ARENA_MAX" else ""},
            capture_output=True,
            text=True,
        )
        assert user.stdout.strip() == kept, (variable, user.stderr)


def test_a_compile_worker_compiles_this_bsrt_whatever_the_current_folder(tmp_path, monkeypatch):
    """In a folder holding another ``bsrt`` (a clone of the repository, bsrt installed from it),
    ``python -m`` would import that one and fill a cache of its own sources: the worker must
    compile the caller's package into the caller's cache."""
    decoy = tmp_path / "clone" / "bsrt" / "kernels"
    decoy.mkdir(parents=True)
    (decoy.parent / "__init__.py").write_text("")
    (decoy / "__init__.py").write_text("")
    (decoy / "compile.py").write_text("open('decoy-ran', 'w').close()\nraise SystemExit(3)\n")
    monkeypatch.chdir(decoy.parent.parent)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "kernels"))
    child = kernels.spawn(["prelim.normalise_rows"])
    assert child.wait(timeout=600) == 0
    assert not (decoy.parent.parent / "decoy-ran").exists()
    probe = "from bsrt.kernels import prelim; print(prelim.normalise_rows._cache._cache_file._load_index() != {})"
    here = Path(kernels.__file__).resolve().parents[2]  # the folder holding the bsrt this test imported
    env = _env(NUMBA_CACHE_DIR=tmp_path / "kernels", PYTHONPATH=here)
    out = subprocess.run([sys.executable, "-P", "-c", probe], env=env, capture_output=True, text=True, cwd=tmp_path)
    assert out.stdout.strip() == "True", out.stderr


def test_the_workers_compile_at_their_optimisation_level_and_the_caller_loads_it_at_its_own(tmp_path, monkeypatch):
    """Workers compile at OPT_LEVEL (unless the user set NUMBA_OPT); a caller at numba's default
    level loads that machine code from the cache, compiling nothing."""
    monkeypatch.setenv("NUMBA_OPT", "1")
    assert kernels.worker_env()["NUMBA_OPT"] == "1"  # the user's choice stands
    monkeypatch.delenv("NUMBA_OPT")
    assert kernels.worker_env()["NUMBA_OPT"] == str(kernels.OPT_LEVEL) != "3"
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "kernels"))
    assert kernels.spawn(["prelim.normalise_rows"]).wait(timeout=600) == 0
    probe = (
        "import numpy as np; from bsrt.kernels import prelim; d = np.ones((2, 3)); "
        "prelim.normalise_rows(0, 2, d, np.empty((2, 3)), d[:1], np.empty((2, 3))); "
        "s = prelim.normalise_rows.stats; print(sum(s.cache_hits.values()), sum(s.cache_misses.values()))"
    )
    here = Path(kernels.__file__).resolve().parents[2]  # the bsrt the worker compiled (an install in CI)
    env = _env(NUMBA_CACHE_DIR=tmp_path / "kernels", NUMBA_OPT=None, PYTHONPATH=here)
    run = [sys.executable, "-P", "-c", probe]
    out = subprocess.run(run, env=env, capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert out.stdout.split() == ["1", "0"], out.stderr

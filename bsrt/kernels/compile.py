"""Compiling the kernels once per machine, in parallel, ahead of the first render.

numba compiles a kernel on its first call and caches the machine code on
disk (``jit.py`` says where). One compiler runs per process (numba holds a
global lock), so :func:`compile_all` shares the entry kernels among worker
processes, each compiling its share from the signatures recorded in
``signatures.pickle`` (written by ``scripts/record_kernel_signatures.py``;
``tests/test_compile.py`` checks that it matches what renders compile). The workers write the cache;
the caller then loads it. Where the recorded signatures cannot be read (a
numba whose types pickle differently), or with one worker, nothing is done
here and the first render compiles as it goes.

:func:`bsrt.rendering.warm_up.warm_up` calls every entry kernel on a tiny
scene (GL included): ``bsrt doctor --compile`` runs both. ``bsrt render``
announces the compile when the cache is cold, starts the workers before
the model loads (:func:`start`) and waits for them before the render
(:func:`finish`), which then loads only the kernels it uses.

    python -m bsrt.kernels.compile NAME...   # a worker: compile these entry kernels
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import time
from pathlib import Path

from bsrt.kernels import (
    antialias,
    film,
    flatten,
    lighting,
    patches,
    prelim,
    roots,
    shading,
    tables,
    traverse,
    trim,
    trim_pieces,
)

# the kernels called from Python (the rest are compiled as part of them)
ENTRY_KERNELS = (
    roots.solve_items,
    traverse.trace_rays,
    patches.evaluate_many,
    patches.locate_many,
    flatten.count_leaves,
    flatten.flatten_patches,
    flatten.leaf_boxes,
    flatten.build_tree,
    tables.permute_rows,
    tables.power_coefficients,
    shading.frames_many,
    shading.mirror_rays,
    shading.mix_reflections,
    lighting.shade_hits,
    film.add_samples,
    film.put_records,
    film.encode_values,
    film.srgb_table,
    antialias.mark_rows,
    antialias.block_samples,
    prelim.decode_tile,
    prelim.decode_merged,
    prelim.gather_roots,
    prelim.pixel_rays_into,
    prelim.film_rays_into,
    prelim.normalise_rows,
    prelim.map_suspects,
    prelim.seeded_hits,
    trim._kept_many,
    trim._rect_states,
    trim.classify_grid,
    trim_pieces.bezier_spans,
    trim_pieces.monotone_pieces,
)
SIGNATURES = Path(__file__).with_name("signatures.pickle")
DEFAULT_SECONDS = 35.0  # one core's cold compile of everything (2-core machine, measured: 32-35 s), without a record


def name_of(kernel) -> str:
    """``"module.function"``: the key of a kernel in the record."""
    return f"{kernel.py_func.__module__.rsplit('.', 1)[1]}.{kernel.py_func.__name__}"


def cache_folder() -> str | None:
    """Where the machine code is cached (None if numba cannot cache here)."""
    cache = getattr(roots.solve_items, "_cache", None)
    return getattr(getattr(cache, "_cache_file", None), "_cache_path", None)


def is_cached() -> bool:
    """Whether every entry kernel has machine code on disk for its current source (an index
    written for other source, or by another numba, does not count)."""
    for kernel in ENTRY_KERNELS:
        cache_file = getattr(getattr(kernel, "_cache", None), "_cache_file", None)
        if cache_file is None:
            return False
        try:
            if not cache_file._load_index():
                return False
        except Exception:  # an unreadable index: numba recompiles, so it is not cached
            return False
    return True


def recorded() -> dict | None:
    """{"signatures": {name: [signature]}, "seconds": {name: s}} from signatures.pickle; None if it
    cannot be read with this numba."""
    try:
        with open(SIGNATURES, "rb") as f:
            record = pickle.load(f)
        return record if set(record["signatures"]) >= {name_of(k) for k in ENTRY_KERNELS} else None
    except Exception:  # missing, or types that do not unpickle with this numba: compile as we go
        return None


def estimate_seconds(workers: int | None = None) -> float:
    """The cold compile's expected wall time on this machine's cores (from the record)."""
    record = recorded()
    if not record:
        return DEFAULT_SECONDS
    return _plan(record, min(workers or _cores(), 4))[1]


def compile_all(workers: int | None = None) -> float:
    """Compile every entry kernel into the cache in ``workers`` processes (default: the cores,
    at most 4); returns the seconds it took. Does nothing where the record cannot be read or
    there is one core: the caller's first calls compile then."""
    clock = time.perf_counter()
    finish(start(workers))
    return time.perf_counter() - clock


def start(workers: int | None = None) -> list[subprocess.Popen]:
    """Start the worker processes that compile every entry kernel into the cache (``workers``:
    default the cores, at most 4) and return them at once; none where the record cannot be read
    or there is one core. The workers inherit the environment (NUMBA_CACHE_DIR, XDG_CACHE_HOME),
    so they fill the cache the caller reads."""
    record = recorded()
    workers = min(workers or _cores(), 4)
    if record is None or workers < 2:
        return []
    return [spawn(share) for share in _plan(record, workers)[0] if share]


def spawn(names: list[str]) -> subprocess.Popen:
    """A worker process compiling the entry kernels ``names`` of this very bsrt package. The
    machine code is cached under its package's sources, so a worker that imported another copy
    (``python -m`` puts the current folder first: a user rendering in their clone of the
    repository, bsrt installed from it) fills a cache the caller never reads, and the caller
    then compiles alone, on every later run too. So the worker's path starts with the folder
    that holds this package, and not with the current folder (-P)."""
    command = [sys.executable, "-P", "-m", "bsrt.kernels.compile", *names]
    return subprocess.Popen(command, stdout=subprocess.DEVNULL, env=worker_env())


# LLVM's optimisation level for the workers' compile (numba's default: 3). Measured on two
# cores: compile_all 15.7 s at 2 against 17.2-17.5 s at 3; the renders of scenes/ and of the
# STEP and IGES test parts byte-identical, AOVs included, and as fast (within 2%); at 1 the
# compile is 15 s but the renders 3-7% slower.
OPT_LEVEL = 2


# The folder holding this bsrt package: a child that must run this very copy has it first on
# PYTHONPATH and runs with -P or in this folder (``python -m`` puts the current folder first).
PACKAGE_FOLDER = Path(__file__).resolve().parents[2]


def this_bsrt_env(**extra) -> dict:
    """The caller's environment with PACKAGE_FOLDER first on PYTHONPATH, then ``extra``."""
    path = [str(PACKAGE_FOLDER)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(path), **extra}


def worker_env() -> dict:
    """The environment of a compile worker (:func:`spawn`): :func:`this_bsrt_env`, with
    NUMBA_OPT = OPT_LEVEL unless the caller set one. numba's cache does not key machine code
    by the level, so the caller loads it."""
    env = this_bsrt_env()
    env.setdefault("NUMBA_OPT", str(OPT_LEVEL))
    return env


def finish(children: list[subprocess.Popen], stop: bool = False) -> None:
    """Wait for the workers :func:`start` returned; stop: end them instead (a half-written cache
    entry is never renamed in). Interrupted, the workers are ended too."""
    try:
        for child in children:
            if not stop:
                child.wait()
    finally:
        for child in children:
            if child.poll() is None:
                child.kill()
                child.wait()


# kernels of one family share heavy callees (compiled once per process that needs them): dealt together
# while that is quickest. lighting's shadow rays run traverse's piece solver: shade_hits compiles in
# 11.8 s of CPU alone, 5.2 s after trace_rays (signatures.pickle).
FAMILIES = {"traverse": "hits", "lighting": "hits", "roots": "hits", "patches": "hits", "shading": "hits"}
FAMILIES |= {"trim": "trims", "trim_pieces": "trims", "flatten": "tree", "prelim": "map", "tables": "map"}


def _plan(record: dict, workers: int) -> tuple[list[list[str]], float]:
    """(shares, seconds): the entry kernels dealt to ``workers`` processes, and the longest
    share's expected CPU seconds (the wall time on idle cores).

    Each family (FAMILIES; a kernel of no family is one alone) is first a unit costing its
    kernels' seconds in a row (record["seconds"]); the units go longest first to the least loaded
    worker. Then, while it shortens the longest share, the costliest family still whole is split
    into its kernels, each costing its seconds compiled alone (record["solo"]: its callees
    compiled again in each process that needs them). On two cores that never pays (the shared
    callees would be compiled twice on the same two cores); with more, the family of the tracing
    and shading kernels (16.7 s of one core in a row) is the first run's floor unless it is split."""
    seconds, solo = record["seconds"], record.get("solo", {})
    families: dict[str, list[str]] = {}
    for name in seconds:
        families.setdefault(FAMILIES.get(name.split(".")[0], name), []).append(name)
    units = [
        (sum(seconds[n] for n in names), sorted(names, key=seconds.get, reverse=True)) for names in families.values()
    ]
    best = _deal(units, workers)
    while True:
        whole = [unit for unit in units if len(unit[1]) > 1 and all(n in solo for n in unit[1])]
        if not whole:
            return best
        family = max(whole, key=lambda unit: unit[0])
        split = [unit for unit in units if unit is not family] + [(solo[n], [n]) for n in family[1]]
        trial = _deal(split, workers)
        if trial[1] >= best[1]:
            return best
        units, best = split, trial


def _deal(units: list[tuple[float, list[str]]], workers: int) -> tuple[list[list[str]], float]:
    """Units (seconds, kernel names) dealt longest first to the least loaded of ``workers``:
    (shares, the largest load)."""
    loads = [0.0] * workers
    shares: list[list[str]] = [[] for _ in range(workers)]
    for cost, names in sorted(units, key=lambda unit: unit[0], reverse=True):
        i = loads.index(min(loads))
        shares[i] += names
        loads[i] += cost
    return shares, max(loads)


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def compile_named(names: list[str], record: dict | None = None) -> dict:
    """Compile the entry kernels ``names`` for their recorded signatures (a worker's job), in
    this order; returns {name: CPU seconds} (a kernel's callees compiled by an earlier one are
    not counted again)."""
    record = record or recorded()
    kernels = {name_of(k): k for k in ENTRY_KERNELS}
    seconds = {}
    for name in names:
        clock = time.process_time()
        for signature in record["signatures"][name]:
            kernels[name].compile(signature)
        seconds[name] = round(time.process_time() - clock, 2)
    return seconds


def signatures_now() -> dict:
    """{name: [signature]} of every entry kernel as compiled (or loaded) in this process."""
    return {name_of(k): list(k.signatures) for k in ENTRY_KERNELS}


def main(argv: list[str]) -> int:
    """A worker: ``python -m bsrt.kernels.compile NAME...``; with ``--record FILE`` first, the
    signatures come from FILE (a pickle of {"signatures": ...}) and the seconds are printed
    as JSON (scripts/record_kernel_signatures.py)."""
    record = None
    if argv[:1] == ["--record"]:
        with open(argv[1], "rb") as f:
            record = pickle.load(f)
        argv = argv[2:]
    seconds = compile_named(argv, record)
    if record is not None:
        import json

        print(json.dumps(seconds))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

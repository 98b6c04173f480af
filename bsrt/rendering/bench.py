"""``bsrt bench``: time every method on the paper's scenes, shaped like its tables.

Each method is rendered once untimed (the GL context, caches), then
``repeat`` rounds render every method once each, so that all methods see the
same machine load; the median of each stage is reported, and Table 2 gives
the median over rounds of each round's ratio. All methods run to the scene's tolerance (default 1e-9 of the scene
diagonal), so they do the same job: the paper's eps is not given, and a
looser one would favour gradient descent, which converges linearly.
Disagreements are counted against ``newton`` at the same size (on the first
device). ``devices``: each method is timed on each device (the ``device``
setting's cpu and gpu), side by side in the same rounds: a GPU row is named
``METHOD@gpu``; the results give the devices and the cores the CPU kernels use.
"""

from __future__ import annotations

import resource
import statistics
import time
from pathlib import Path

import numpy as np

from bsrt.errors import InputError
from bsrt.kernels import compile as compile_kernels
from bsrt.kernels.threads import workers
from bsrt.methods import MAP_METHODS, REFERENCE_METHOD
from bsrt.rendering.options import RenderOptions
from bsrt.rendering.pipeline import Geometry, render
from bsrt.scene import load_scene
from bsrt.settings import DEVICES

PAPER = {  # Sisojevs & Glazs, 512x512, 1 ray/pixel, 3.2 GHz Xeon: seconds
    "column": {"gradient": 74.9, "fast": 31.2, "martin": 60.8},
    "water-lily": {"gradient": 180.2, "fast": 98.3, "martin": 205.6},
}
DEFAULT_SCENES = ("column", "water-lily")
DEFAULT_METHODS = MAP_METHODS
BENCH_DEVICES = tuple(d for d in DEVICES if d != "auto")


def bench_devices(text: str | None) -> tuple[str, ...]:
    """``--devices``: a comma-separated list of BENCH_DEVICES; None: cpu, and gpu where the
    context is a hardware one that runs it (gpu.hardware_gpu: OpenGL 4.5, compute and float64)."""
    if text is None:
        from bsrt.rendering import gpu

        return ("cpu", "gpu") if gpu.hardware_gpu() else ("cpu",)
    named = tuple(dict.fromkeys(d.strip() for d in text.split(",") if d.strip()))
    unknown = [d for d in named if d not in BENCH_DEVICES]
    if unknown or not named:
        what = f"unknown device {unknown[0]!r}" if unknown else "names no device"
        raise InputError(f"--devices: {what} (expected a comma-separated list of {', '.join(BENCH_DEVICES)})")
    return named


def row_name(method: str, device: str) -> str:
    """The results' name of a method timed on a device: the method's on the CPU, METHOD@DEVICE otherwise."""
    return method if device == "cpu" else f"{method}@{device}"


def scene_path(name: str) -> Path:
    """A bundled scene name (scenes/NAME.toml under the current folder) or a path."""
    path = Path(name)
    if path.suffix == ".toml" or path.exists():
        return path
    bundled = Path("scenes") / f"{name}.toml"
    if not bundled.exists():
        raise InputError(
            f"{name}: no such scene (looked for {bundled}; run bsrt bench from the repository root or give a path)"
        )
    return bundled


def run(
    scenes=DEFAULT_SCENES, methods=DEFAULT_METHODS, size=512, repeat=3, log=print, embree=(), devices=("cpu",)
) -> dict:
    """Benchmark; returns a JSON-serialisable dict (see format_tables). ``embree``: segment counts
    for the Embree comparison (bench_embree.compare, against the reference method's hits; needs it
    among ``methods``), none by default. ``devices``: of BENCH_DEVICES, each method timed on each."""
    results = {"size": size, "repeat": repeat, "devices": list(devices), "cores": workers(), "scenes": {}}
    reference = row_name(REFERENCE_METHOD, devices[0])
    for name in scenes:
        path = scene_path(name)
        scene = load_scene(path)
        builds = []
        for _ in range(repeat):  # set-up: the patch table and the hierarchy
            clock = time.perf_counter()
            geometry = Geometry(scene)
            _ = geometry.bvh
            builds.append(time.perf_counter() - clock)
        setup = statistics.median(builds)
        label = path.stem
        entry = {
            "surfaces": len(scene.surfaces),
            "patches": geometry.patches.size,
            "setup_seconds": setup,
            "methods": {},
        }
        rows = {  # name: (method, device), the reference first
            row_name(m, d): (m, d) for d in devices for m in sorted(methods, key=lambda m: m != REFERENCE_METHOD)
        }
        order = list(rows)
        options = {  # the tracers compared: one sample per pixel, no adaptive anti-aliasing
            name: RenderOptions.resolve(scene, method=m, device=d, width=size, height=size, adaptive_spp=0)
            for name, (m, d) in rows.items()
        }
        for method in order:
            render(scene, options[method], geometry=geometry)  # warm-up
        runs = {m: [] for m in order}
        last = {}
        for _ in range(repeat):  # rounds: every method once per round, so all see the same machine load
            for method in order:
                clock = time.perf_counter()
                last[method] = render(scene, options[method], geometry=geometry)
                runs[method].append((last[method].stats["seconds"], time.perf_counter() - clock))
        for method in order:
            entry["methods"][method] = _row(
                method, runs[method], last[method], last.get(reference), scene, geometry, reference
            )
            entry["methods"][method]["device"] = rows[method][1]
            med = entry["methods"][method]["seconds"]
            log(f"{label:12s} {method:9s} map+solve {med['map+solve']:7.3f} s  total {med['total']:7.3f} s")
        if embree and reference in last:
            from bsrt.rendering import bench_embree

            exact = entry["methods"][reference]["seconds"]["map+solve"]
            entry["embree"] = bench_embree.compare(
                geometry, options[reference].camera, size, last[reference].hits, exact, embree, repeat
            )
        results["scenes"][label] = entry
    results["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return results


def _row(method, runs, res, reference, scene, geometry, reference_name=REFERENCE_METHOD) -> dict:
    """One method's medians over its runs [(stats seconds, wall seconds)] and its last render's counters
    (``stages``: the device that ran each stage); disagreements with the reference (the last render of
    reference_name, newton on the first device) where it was run."""
    med = {k: statistics.median(r[0][k] for r in runs) for k in runs[0][0]}
    med["map+solve"] = statistics.median(r[0]["map"] + r[0]["solve"] for r in runs)
    med["total"] = statistics.median(r[1] for r in runs)
    hits = res.hits
    rounds = [r[0]["map"] + r[0]["solve"] for r in runs]
    work = hits.iterations[hits.iterations > 0]
    row = {
        "seconds": med,
        "map+solve rounds": rounds,
        "iterations_per_pixel": float(work.mean()) if work.size else 0.0,
        "hits": int(hits.hit.sum()),
        "covered_by_map": res.stats.get("covered_by_map"),
        "non_converged": res.stats.get("non_converged"),
        "suspect": res.stats.get("suspect"),
        "repaired": res.stats.get("repaired"),
        "shadow_rays": res.stats.get("shadow_rays", 0),
        "reflection_rays": res.stats.get("reflection_rays", 0),
        "stages": res.stats.get("devices"),
    }
    if reference is not None and method != reference_name:
        reference = reference.hits
        tol = 1e3 * scene.render.tolerance * geometry.patches.scene_diagonal()
        both = hits.hit & reference.hit
        row["disagree"] = {
            "hit": int((hits.hit != reference.hit).sum()),
            "surface": int((hits.surface[both] != reference.surface[both]).sum()),
            "t": int((np.abs(hits.t[both] - reference.t[both]) > tol).sum()),
        }
    return row


def format_tables(results: dict) -> str:
    """Table 1 (seconds) and Table 2 (percent of martin, or of newton without it)."""
    scenes = results["scenes"]
    methods = list(dict.fromkeys(m for e in scenes.values() for m in e["methods"]))
    base = "martin" if "martin" in methods else REFERENCE_METHOD  # the paper's Table 2 is in percent of martin
    lines = [
        f"Table 1: seconds (median of {results['repeat']}), {results['size']}x{results['size']}, map + solve (total render in brackets); "
        f"devices {', '.join(results['devices'])} (METHOD@gpu: on the GPU), {results['cores']} cores"
    ]
    lines.append(f"{'scene':12s}" + "".join(f"{m:>20s}" for m in methods) + f"{'paper (grad/fast/martin)':>30s}")
    for name, e in scenes.items():
        cells = "".join(
            f"{e['methods'][m]['seconds']['map+solve']:>10.3f} ({e['methods'][m]['seconds']['total']:6.3f})"
            if m in e["methods"]
            else f"{'-':>20s}"
            for m in methods
        )
        paper = PAPER.get(name)
        ptxt = " / ".join(f"{paper[m]:.1f}" for m in ("gradient", "fast", "martin")) if paper else "-"
        lines.append(f"{name:12s}{cells}{ptxt:>30s}")
    lines.append("")
    lines.append(f"Table 2: percent of {base} (map + solve)")
    lines.append(f"{'scene':12s}" + "".join(f"{m:>12s}" for m in methods) + f"{'paper grad/fast':>20s}")
    for name, e in scenes.items():
        ref = e["methods"].get(base)
        if not ref:
            continue
        cells = "".join(
            f"{_percent(e['methods'][m], ref):>11.0f}%" if m in e["methods"] else f"{'-':>12s}" for m in methods
        )
        paper = PAPER.get(name)
        ptxt = (
            f"{100 * paper['gradient'] / paper['martin']:.0f}% / {100 * paper['fast'] / paper['martin']:.0f}%"
            if paper
            else "-"
        )
        lines.append(f"{name:12s}{cells}{ptxt:>20s}")
    lines.append("")
    lines.append(
        "Per method: iterations per pixel, hits, map-covered, non-converged, suspect, repaired; disagreements with newton (hit/surface/t)"
    )
    for name, e in scenes.items():
        for m, row in e["methods"].items():
            dis = row.get("disagree")
            dtxt = f"{dis['hit']}/{dis['surface']}/{dis['t']}" if dis else "-"
            lines.append(
                f"  {name:12s} {m:9s} {row['iterations_per_pixel']:6.2f} it/px  hits {row['hits']:7d}  map {row['covered_by_map'] if row['covered_by_map'] is not None else '-':>7}"
                f"  non-conv {row['non_converged']:5d}  suspect {row['suspect']:6d}  repaired {row['repaired']:5d}  disagree {dtxt}"
            )
    lines.append(f"peak RSS of the process: {results['peak_rss_mb']:.0f} MB")
    return "\n".join(lines)


def _percent(row: dict, base: dict) -> float:
    """Median over rounds of row's map + solve as a percentage of base's in the same round."""
    return statistics.median(100 * a / b for a, b in zip(row["map+solve rounds"], base["map+solve rounds"]))


def format_full(results: dict) -> str:
    """Whole renders by stage (``--full``): seconds per stage (medians), secondary (shadow and mirror) rays per second of shading.

    "whole" is what one ``bsrt render`` of a loaded scene costs: the set-up
    (patch table and hierarchy, measured once) plus the median render.
    """
    lines = [
        f"Whole renders, {results['size']}x{results['size']}, seconds (median of {results['repeat']}); "
        "shade includes the shadow rays and secondary (mirror rays); rays/s: shadow and mirror rays per second of shade"
    ]
    head = ("scene", "method", "setup", "map", "solve", "shade", "secondary", "render", "whole", "rays/s")
    lines.append(f"{head[0]:12s}{head[1]:>9s}" + "".join(f"{h:>11s}" for h in head[2:]))
    for name, e in results["scenes"].items():
        for m, row in e["methods"].items():
            sec = row["seconds"]
            rays = row["shadow_rays"] + row["reflection_rays"]
            rate = rays / sec["shade"] if sec.get("shade") else 0.0
            cells = (
                e["setup_seconds"],
                sec["map"],
                sec["solve"],
                sec["shade"],
                sec.get("secondary", 0.0),
                sec["total"],
                e["setup_seconds"] + sec["total"],
            )
            lines.append(f"{name:12s}{m:>9s}" + "".join(f"{c:>11.3f}" for c in cells) + f"{rate:>11.3g}")
    return "\n".join(lines)


def preview_timeline(log: dict) -> list[dict]:
    """A ``bsrt preview --frame-log`` (bsrt/preview/framelog.py) per camera stop after the first,
    in seconds: from the last frame drawn "moving" to the first level shown (``first``: the
    coarsest) and to the exact one (``exact``); the same from the camera's last change
    (``changed_first``, ``changed_exact``: the settle time included); for the exact level
    ``map`` (first map band to submitted), ``waited`` (submitted to the solve's start: queue,
    the map's transfer, the coarser level), ``back`` (the solve's end to shown); ``solve``:
    divisor -> (wall, CPU) seconds of the solver per level shown."""
    moving = [f["t"] for f in log["frames"] if f["state"] == "moving"]
    by_generation: dict[int, list[dict]] = {}
    for entry in log.get("levels", []):
        by_generation.setdefault(entry["generation"], []).append(entry)
    out = []
    for entries in by_generation.values():
        exact = entries[-1]
        before = [t for t in moving if t <= entries[0]["map"]]
        if exact.get("verdict") != "exact" or not before:
            continue
        last, changed = before[-1], entries[0].get("changed", before[-1])
        shown = [e for e in entries if "shown" in e]
        out.append(
            {
                "first": shown[0]["shown"] - last,
                "exact": exact["shown"] - last,
                "changed_first": shown[0]["shown"] - changed,
                "changed_exact": exact["shown"] - changed,
                "map": exact["submitted"] - exact["map"],
                "waited": exact["waited"],
                "back": exact["shown"] - exact["submitted"] - exact["waited"] - exact["seconds"],
                "solve": {e["divisor"]: (e["seconds"], e["cpu_seconds"]) for e in shown},
            }
        )
    return out[1:]  # the first stop follows the window's start-up


def check_preview_display() -> None:
    """InputError unless there is an X display for bench --preview's window."""
    import os

    if not os.environ.get("DISPLAY"):
        raise InputError("bench --preview: needs an X display (set DISPLAY, or run it under xvfb-run)")


def preview_latency(scene: str = "water-lily", width: int = 800, height: int = 600, moves: int = 5) -> dict:
    """The preview's latency: ``bsrt preview`` in a child on $DISPLAY, orbiting 15 degrees
    ``moves`` times and waiting for the exact image each time; medians over the stops of
    preview_timeline's times, the exact level's solver CPU seconds, the child's CPU seconds
    (window and solvers) and the load average before and after. InputError without a display."""
    import json
    import os
    import subprocess
    import sys
    import tempfile

    check_preview_display()
    events = "wait; " + "; ".join(["orbit 15 0 5; wait"] * moves) + "; quit"
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        log_path = Path(tmp) / "log.json"
        argv = [sys.executable, "-m", "bsrt", "preview", str(scene_path(scene)), "--width", str(width)]
        argv += ["--height", str(height), "--events", events, "--frame-log", str(log_path)]
        before = os.times()
        done = subprocess.run(argv, capture_output=True, text=True)
        after = os.times()
        if done.returncode != 0:
            raise InputError(f"bench --preview: bsrt preview failed ({done.returncode}): {done.stderr.strip()[-300:]}")
        stops = preview_timeline(json.loads(log_path.read_text()))
    out = {"scene": scene, "size": [width, height], "stops": len(stops)}
    for key in ("first", "exact", "changed_first", "changed_exact", "map", "waited", "back"):
        out[key] = statistics.median(s[key] for s in stops)
    out["solve_wall"] = statistics.median(s["solve"][1][0] for s in stops)
    out["solve_cpu"] = statistics.median(s["solve"][1][1] for s in stops)
    out["child_cpu"] = (after.children_user - before.children_user) + (after.children_system - before.children_system)
    out["load_average"] = [load, os.getloadavg()[0]]
    return out


def format_preview(results: dict) -> str:
    """preview_latency's medians as lines."""
    r = results
    return (
        f"preview {r['scene']} {r['size'][0]}x{r['size'][1]}, {r['stops']} stops (medians; load "
        f"{r['load_average'][0]:.1f} -> {r['load_average'][1]:.1f}):\n"
        f"  first image {r['first']:.3f} s, exact image {r['exact']:.3f} s after the camera stops "
        f"({r['changed_first']:.3f} s, {r['changed_exact']:.3f} s after its last change)\n"
        f"  exact level: map {r['map']:.3f} s, waited {r['waited']:.3f} s, solve {r['solve_wall']:.3f} s "
        f"({r['solve_cpu']:.3f} s CPU), back {r['back']:.3f} s; CPU of the whole run {r['child_cpu']:.1f} s"
    )


def trim_cost(paths, size=512, repeat=3, log=print) -> dict:
    """Each model rendered as it is and with its trims ignored (same camera: the trimmed model's), medians.

    Returns {name: {"trimmed": seconds, "untrimmed": seconds, "ratio": ..., "trimmed_surfaces": n}}.
    """
    from dataclasses import replace

    from bsrt.io import load_model
    from bsrt.scene import SceneSurface, scene_for_model

    out = {}
    for path in paths:
        model = load_model(path)
        scene = scene_for_model(model, size, size)
        bare = replace(
            scene,
            surfaces=tuple(SceneSurface(replace(s.geometry, trims=()), s.material, s.name) for s in scene.surfaces),
        )
        row = {"trimmed_surfaces": sum(s.geometry.is_trimmed for s in scene.surfaces)}
        for label, sc in (("trimmed", scene), ("untrimmed", bare)):
            options = RenderOptions.resolve(sc, adaptive_spp=0)
            render(sc, options)  # warm-up
            times = []
            for _ in range(repeat):
                clock = time.perf_counter()
                render(sc, options)
                times.append(time.perf_counter() - clock)
            row[label] = statistics.median(times)
        row["ratio"] = row["trimmed"] / row["untrimmed"]
        out[Path(path).name] = row
        log(
            f"{Path(path).name:24s} trimmed {row['trimmed']:6.3f} s  trims ignored {row['untrimmed']:6.3f} s  "
            f"ratio {row['ratio']:.2f}  ({row['trimmed_surfaces']} trimmed surfaces)"
        )
    return out


def _child_seconds(argv: list[str], env: dict) -> tuple[float, float]:
    """Run ``argv`` in a child; its (wall, CPU user + system) seconds. A failure is an InputError."""
    import os
    import subprocess

    before = os.times()
    clock = time.perf_counter()
    done = subprocess.run(argv, env=env, capture_output=True, text=True, cwd=CHILD_FOLDER)
    wall = time.perf_counter() - clock
    after = os.times()
    if done.returncode != 0:
        raise InputError(f"{' '.join(argv)}: failed ({done.returncode}): {done.stderr.strip()[-300:]}")
    return wall, (after.children_user - before.children_user) + (after.children_system - before.children_system)


def render_argv(scene: str, out: Path) -> list[str]:
    """The argv of a ``bsrt render`` of ``scene`` (bundled name or path) to ``out``, in a new process."""
    import sys

    return [sys.executable, "-m", "bsrt", "render", str(scene_path(scene).resolve()), "-o", str(out)]


# children run in the folder holding this bsrt package, with it first on PYTHONPATH
CHILD_FOLDER = compile_kernels.PACKAGE_FOLDER
child_env = compile_kernels.this_bsrt_env


def startup(scene: str = "column", repeat: int = 5) -> dict:
    """Start-up: a 16x16 ``bsrt render`` in a new process minus ``python -c "import numpy"``,
    medians of ``repeat`` alternating runs (wall and CPU seconds), with the load average.
    The kernels are first compiled (or found) in the cache, and the scene's hierarchy stored in
    the prepared-geometry cache, by one untimed render."""
    import os
    import sys
    import tempfile

    env = child_env()
    with tempfile.TemporaryDirectory() as tmp:
        tiny = render_argv(scene, Path(tmp) / "tiny.png") + ["--width", "16", "--height", "16"]
        _child_seconds(tiny, env)  # untimed: the cache
        numpy, renders = [], []
        load = os.getloadavg()[0]
        for _ in range(repeat):
            numpy.append(_child_seconds([sys.executable, "-c", "import numpy"], env))
            renders.append(_child_seconds(tiny, env))
    med = lambda runs, i: statistics.median(r[i] for r in runs)  # noqa: E731
    return {
        "repeat": repeat,
        "render_wall": med(renders, 0),
        "render_cpu": med(renders, 1),
        "numpy_wall": med(numpy, 0),
        "numpy_cpu": med(numpy, 1),
        "startup_wall": statistics.median(r[0] - n[0] for r, n in zip(renders, numpy)),
        "startup_cpu": statistics.median(r[1] - n[1] for r, n in zip(renders, numpy)),
        "load_average": [load, os.getloadavg()[0]],
    }


def first_run(scene: str = "column") -> dict:
    """The first render on a machine: a 16x16 ``bsrt render`` in a new process with empty
    kernel and geometry caches (NUMBA_CACHE_DIR and BSRT_CACHE_DIR new temporary folders), wall
    and CPU seconds (the CPU of the compile's worker processes included), with the load average."""
    import os
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        env = child_env(NUMBA_CACHE_DIR=str(Path(tmp) / "kernels"), BSRT_CACHE_DIR=str(Path(tmp) / "models"))
        load = os.getloadavg()[0]
        wall, cpu = _child_seconds(
            render_argv(scene, Path(tmp) / "first.png") + ["--width", "16", "--height", "16"], env
        )
    return {"first_run_wall": wall, "first_run_cpu": cpu, "load_average": [load, os.getloadavg()[0]]}


def format_startup(results: dict) -> str:
    """The start-up and first-run rows (either may be missing)."""
    lines = []
    s = results.get("startup")
    if s:
        lines.append(
            f"start-up: 16x16 CLI render {s['render_wall']:.2f} s wall ({s['render_cpu']:.2f} s CPU) - "
            f"python -c 'import numpy' {s['numpy_wall']:.2f} s ({s['numpy_cpu']:.2f} s) = "
            f"{s['startup_wall']:.2f} s wall ({s['startup_cpu']:.2f} s CPU), medians of {s['repeat']}, "
            f"load {s['load_average'][0]:.1f}-{s['load_average'][1]:.1f}"
        )
    f = results.get("first_run")
    if f:
        lines.append(
            f"first run (empty kernel cache): 16x16 CLI render {f['first_run_wall']:.1f} s wall "
            f"({f['first_run_cpu']:.1f} s CPU, compile workers included), "
            f"load {f['load_average'][0]:.1f}-{f['load_average'][1]:.1f}"
        )
    return "\n".join(lines)

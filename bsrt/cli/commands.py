"""The commands: each a thin adapter from parsed arguments to the package (``COMMANDS``)."""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

from bsrt import interrupts
from bsrt.cli.compiling import compile_if_cold, compile_kernels, compiling_if_cold, start_set_up
from bsrt.errors import InputError, RenderError
from bsrt.methods import METHODS
from bsrt.settings import flag_values


def _load_input(args, progress=None):
    """The Scene for ``args.scene`` (bsrt/scene/loading.py), its import warnings on stderr once.
    progress: the render's progress, shown the "load" stage."""
    from bsrt.scene.loading import CameraOverrides, load_input

    scene = load_input(
        args.scene,
        args.format,
        width=getattr(args, "width", None),
        height=getattr(args, "height", None),
        camera=CameraOverrides.from_args(args),
        cache=args.cache,
        progress=progress,
    )
    if progress:
        progress.clear()  # the warnings below get clean lines
    for note in scene.notes:
        print(f"bsrt: warning: {note}", file=sys.stderr)
    return scene


def default_output(source: str) -> str:
    """The output of ``bsrt render MODEL`` without ``-o``: MODEL's stem with ``.png``, in the
    current folder (``bearing.step`` -> ``./bearing.png``; never the input itself)."""
    return str(Path.cwd() / (Path(source).stem + ".png"))


def _check_output(path: str, suffix: str | None) -> Path:
    """An output path the run can write (checked before any work): the right
    suffix (any when None), an existing folder, not a folder itself."""
    out = Path(path)
    if suffix is not None and out.suffix.lower() != suffix:
        raise InputError(f"{path}: the output file name must end in {suffix}")
    if not out.parent.is_dir():
        raise InputError(f"{path}: the folder {str(out.parent)!r} does not exist")
    if out.is_dir():
        raise InputError(f"{path}: is a folder, not an output file")
    return out


def _refuse_overwriting(outputs: list[Path], scene) -> None:
    """No output may be one of the files the scene was read from (its imports
    included), nor two outputs the same file."""

    def same(a, b) -> bool:
        return os.path.realpath(a) == os.path.realpath(b) or (
            os.path.exists(a) and os.path.exists(b) and os.path.samefile(a, b)
        )

    for i, out in enumerate(outputs):
        for source in scene.inputs:
            if same(out, source):
                raise InputError(f"{out}: is an input of this render ({source}); choose another output name")
        for other in outputs[:i]:
            if same(out, other):
                raise InputError(f"{out}: given as two outputs ({other})")


def _print_stdout(text: str) -> None:
    """Print to stdout now; a failing stdout (full disk, closed pipe) is an OutputError."""
    from bsrt.outputs import OutputError

    try:
        print(text, flush=True)
    except OSError as exc:
        # What is still buffered would fail again at exit with a second message: send it nowhere.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        raise OutputError(f"<stdout>: {exc.strerror or exc}") from None


def _progress(args):
    """`bsrt render`'s progress (bsrt/progress.py): a bar on a terminal (not with
    --no-progress, nor in CI), plain lines elsewhere only with --progress."""
    from bsrt.progress import wanted

    return wanted(sys.stderr, args.progress)


def _cmd_render(args) -> int:
    """Render to ``--output`` (and ``--aov``, and ``--stats`` on stdout): all of them or none."""
    progress = _progress(args)
    try:
        # the first run: the kernels compile while the renderer imports and the model loads
        with compiling_if_cold(progress) as start_compiling:
            with interrupts.at_safe_points():  # the set-up thread and this one import at once: a signal waits
                set_up = start_set_up()
                start_compiling()
                from bsrt.outputs import outputs_at_safe_points
                from bsrt.rendering.image import check_image_path, image_writer
                from bsrt.rendering.options import RenderOptions
                from bsrt.rendering.pipeline import render
                from bsrt.scene import loading  # noqa: F401  (imported here, not while the model loads)

                set_up.join(1.0)  # its imports too are over before a signal can raise (a stuck driver: 1 s at most)

            out = _check_output(args.output or default_output(args.scene), None)
            given = flag_values(args, "render")
            check_image_path(out, bool(given.get("transparent")), given.get("bit_depth", 8), "--")
            aov = _check_output(args.aov, ".npz") if args.aov else None
            scene = _load_input(args, progress)
            _refuse_overwriting([out] + ([aov] if aov else []), scene)
            options = RenderOptions.resolve(scene, **given)
            check_image_path(out, options.transparent, options.bit_depth, f"{scene.path}: film.")  # the scene's own
    except BaseException:
        if progress:
            progress.clear()
        raise
    try:
        with outputs_at_safe_points() as outputs:  # signals wait for a safe point; none after the commit
            if progress:
                progress("setup", 0.0)  # at once: the setup (kernels, hierarchy) comes before the first stage
            # no AOVs: a streamed film; the hierarchy from the prepared-geometry cache unless --no-cache
            result = render(scene, options, progress=progress, keep=False, aovs=bool(aov), cache=args.cache)
            clock = time.perf_counter()
            if progress:
                progress("write", 1.0)  # the picture and the AOVs (seconds at 2048 x 2048 with --aov)
            outputs.write(out, image_writer(out, result.image))
            if aov:
                from bsrt import npz  # (its thread pool's imports only when there is an archive to write)

                outputs.write(aov, npz.writer(result.aovs()))
            result.stats["seconds"]["write"] = time.perf_counter() - clock
            if args.stats:
                _print_stdout(json.dumps(result.stats, indent=2))
            outputs.commit()
    except BaseException:
        if progress:
            progress.clear()  # the error message gets a clean line
        raise
    if progress:
        progress.finish(
            f"rendered {out}{f' (AOVs: {aov})' if aov else ''} {options.width}x{options.height}, "
            f"{options.spp} spp, {options.method}, {progress.elapsed():.1f} s"
        )
    return 0


def _cmd_map(args) -> int:
    with interrupts.at_safe_points():  # as render's: a signal waits for the imports' end (bsrt/interrupts.py)
        from bsrt.outputs import outputs_at_safe_points
        from bsrt.rendering.image import png_writer
        from bsrt.rendering.pipeline import Geometry
        from bsrt.rendering.prelim import render_map
        from bsrt.settings import with_settings

    out = _check_output(args.output, ".png")
    scene = _load_input(args)
    _refuse_overwriting([out], scene)
    scene = with_settings(scene, flag_values(args, "map"))
    with outputs_at_safe_points() as outputs:  # as render's: signals wait for a safe point
        prelim = render_map(
            Geometry(scene).patches, scene.camera, scene.film.width, scene.film.height, scene.render.map
        )
        outputs.write(out, png_writer(prelim.picture))
        outputs.commit()
    return 0


def _cmd_scene(args) -> int:
    """``bsrt scene MODEL -o part.toml``: the model's automatic scene as a small scene file that imports it."""
    from bsrt.rendering.image import write_text
    from bsrt.scene.document import dumps_toml, import_scene_document
    from bsrt.settings import with_settings

    if Path(args.model).suffix.lower() == ".toml":
        raise InputError(f"{args.model}: is a scene file already; give a model file")
    out = _check_output(args.output or str(Path.cwd() / (Path(args.model).stem + ".toml")), ".toml")
    args.scene = args.model
    scene = with_settings(_load_input(args), flag_values(args, "render"))
    _refuse_overwriting([out], scene)
    try:
        file = os.path.relpath(Path(args.model).resolve(), out.parent.resolve())
    except ValueError:  # another drive
        file = str(Path(args.model).resolve())
    header = (
        f"Scene file (bsrt scene format version 1), written by `bsrt scene` from {Path(args.model).name}: "
        "its automatic camera and lights,\nspelled out to edit (docs/scene-format.md). Point lights: brightness is "
        "the light's strength at the model's centre."
    )
    write_text(out, dumps_toml(import_scene_document(scene, file.replace(os.sep, "/"), args.format), header))
    print(f"bsrt: wrote {out}", file=sys.stderr)
    return 0


def _cmd_info(args) -> int:
    path = Path(args.file)
    if path.suffix.lower() == ".toml":
        from bsrt.scene import load_scene

        if args.format != "auto":
            raise InputError(f"{path}: --format: only for model files; a .toml file is a scene")

        scene = load_scene(path, cache=args.cache)
        degrees = sorted({s.geometry.degree for s in scene.surfaces})
        rational = sum(s.geometry.is_rational for s in scene.surfaces)
        trimmed = sum(s.geometry.is_trimmed for s in scene.surfaces)
        loops = sum(len(s.geometry.trims) for s in scene.surfaces)
        print(
            f"{path}: scene, {len(scene.surfaces)} surfaces ({trimmed} trimmed, {loops} loops), degrees {degrees}, "
            f"{rational} rational, "
            f"{len(scene.lights)} lights, {len(scene.materials)} materials, film {scene.film.width}x{scene.film.height}"
        )
        if scene.loads:
            from bsrt.io.info import load_line

            print(load_line(scene.loads))
        for note in scene.notes:
            print(f"  {note}")
        return 0
    from bsrt.io import load_model
    from bsrt.io.info import describe

    print(describe(load_model(path, args.format, cache=args.cache)))
    return 0


def _cmd_doctor(args) -> int:
    from bsrt import validate
    from bsrt.rendering import gl

    validate.environment()  # a bad EGL device index: one line, exit 2 (as for a render)
    devices = gl.egl_devices()
    print(f"EGL devices: {len(devices)}")
    for i, name in enumerate(devices):
        print(f"  [{i}] {name}")
    if not devices:
        print("  none found: " + gl.FIX_HINT)
    try:
        ctx = gl.headless_context()
    except RenderError as exc:
        print(f"OpenGL: FAILED: {exc}")
        return 1
    print(f"OpenGL renderer: {ctx.info['GL_RENDERER']}")
    print(f"OpenGL version:  {ctx.info['GL_VERSION']}")
    print(f"OpenGL vendor:   {ctx.info['GL_VENDOR']}")
    caps = gl.capabilities(ctx)
    print(
        f"GPU solve:       compute shaders {'yes' if caps.compute else 'no'}, float64 {'yes' if caps.fp64 else 'no'}, "
        f"{'hardware' if caps.hardware else 'software'} context: "
        + (
            f"--device gpu cannot run (needs {', '.join(caps.missing)})"
            if caps.missing
            else "--device gpu runs here; auto uses the CPU (the faster path: docs/performance.md)"
        )
    )
    chosen = gl.chosen_device()
    print(
        f"device chosen:   {chosen if chosen is not None else 'first that works'} (set GLCONTEXT_DEVICE_INDEX=N to pick)"
    )
    from bsrt.kernels import compile as kernels

    if args.compile:
        state, seconds = compile_kernels()
        print(f"kernels:         {state} in {seconds:.1f} s (cache: {kernels.cache_folder() or 'none'})")
    else:
        state = "cached" if kernels.is_cached() else "not compiled yet (bsrt doctor --compile does it now)"
        print(f"kernels:         {state} (cache: {kernels.cache_folder() or 'none'})")
    from bsrt.io.formats import READERS

    for reader in READERS.values():
        state = "ready" if reader.available() else f"needs pip install 'bsrt[{reader.extra}]'"
        print(f"reader {reader.name + ':':7} {' '.join(reader.extensions):38} {state}")
    for name, state in optional_parts():
        print(f"{name + ':':16} {state}")
    print("OK: bsrt can render headless")
    return 0


def optional_parts() -> list[tuple[str, str]]:
    """``bsrt doctor``'s checks of what only some commands need, each with the fix when it is
    missing: the window (glfw and a display: bsrt preview), OpenCASCADE (the cad extra: STEP,
    BREP, IGES through OCCT) and Dask (the dask extra: bsrt batch, animate)."""
    import importlib.util

    parts = [("window", _window_state())]
    if importlib.util.find_spec("OCP") is None:
        parts.append(("OpenCASCADE", "not installed (STEP and BREP files need it): pip install 'bsrt[cad]'"))
    else:
        try:
            import OCP
            from OCP.BRep import BRep_Builder  # noqa: F401  (loads the OCCT libraries)

            parts.append(("OpenCASCADE", f"ready (OCP {getattr(OCP, '__version__', '?')})"))
        except Exception as exc:  # a broken install: the libraries do not load
            parts.append(("OpenCASCADE", f"FAILED to load ({exc}): pip install --force-reinstall 'bsrt[cad]'"))
    try:
        import dask
        import distributed

        parts.append(("Dask", f"ready (dask {dask.__version__}, distributed {distributed.__version__})"))
    except ImportError:
        parts.append(("Dask", "not installed (bsrt batch and animate need it): pip install 'bsrt[dask]'"))
    return parts


def _window_state() -> str:
    """The preview window's state: glfw initialises on a display, or why not and the fix."""
    fix = "bsrt render works without one; for bsrt preview run on a desktop or under xvfb-run -a"
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return f"no display (neither DISPLAY nor WAYLAND_DISPLAY is set): {fix}"
    try:
        import glfw
    except ImportError:
        return "glfw is not installed: pip install glfw"
    glfw.ERROR_REPORTING = "ignore"
    try:
        if not glfw.init():
            return f"glfw cannot open the display {os.environ.get('DISPLAY') or os.environ.get('WAYLAND_DISPLAY')!r}: {fix}"
        glfw.terminate()
    except Exception as exc:
        return f"glfw failed ({exc}): {fix}"
    return f"ready (glfw {glfw.__version__}, display {os.environ.get('DISPLAY') or os.environ.get('WAYLAND_DISPLAY')})"


def _cmd_bench(args) -> int:
    from bsrt.rendering import bench

    named = [m.strip() for m in args.methods.split(",") if m.strip()]
    unknown = [m for m in named if m not in METHODS]
    if unknown:
        raise InputError(f"--methods: unknown method {unknown[0]!r} (expected {', '.join(METHODS)})")
    if not named:
        raise InputError(f"--methods: names no method (expected a comma-separated list of {', '.join(METHODS)})")
    if args.json:
        _check_output(args.json, ".json")
    embree = _embree_segments(args.embree)
    devices = bench.bench_devices(args.devices)
    if args.preview:
        bench.check_preview_display()  # before the long part
    log = lambda text: print(text, flush=True)  # noqa: E731
    if args.models:
        results = bench.trim_cost(args.models, args.size, args.repeat, log=log)
    else:
        scenes = args.scenes or bench.DEFAULT_SCENES
        results = bench.run(scenes, named, args.size, args.repeat, log=log, embree=embree, devices=devices)
        print()
        print(bench.format_tables(results))
        if args.full:
            print()
            print(bench.format_full(results))
        if embree:
            from bsrt.rendering import bench_embree

            print()
            print(bench_embree.format_rows(results))
        if args.startup:
            scene = (args.scenes or bench.DEFAULT_SCENES)[0]
            results["startup"] = bench.startup(scene)
            results["first_run"] = bench.first_run(scene)
            print()
            print(bench.format_startup(results))
        if args.memory:
            from bsrt.rendering import bench_memory

            scene = (args.scenes or bench.DEFAULT_SCENES)[0]
            results["memory"] = bench_memory.per_pixel(
                lambda out: bench.render_argv(scene, out), bench.child_env(), cwd=bench.CHILD_FOLDER
            )
            print()
            print(bench_memory.format_row(results["memory"]))
        if args.preview:
            results["preview"] = bench.preview_latency(*(args.scenes or ["water-lily"])[:1])
            print()
            print(bench.format_preview(results["preview"]))
    if args.json:
        from bsrt.rendering.image import write_text

        write_text(args.json, json.dumps(results, indent=2))
    return 0


def _embree_segments(wanted: bool | None) -> tuple[int, ...]:
    """bench's Embree comparison: the segment counts to compare, () for none (``--no-embree``, or
    embreex missing without ``--embree``); ``--embree`` without embreex is an InputError."""
    from bsrt.rendering import bench_embree

    if wanted is False or (wanted is None and not bench_embree.available()):
        return ()
    if not bench_embree.available():
        raise InputError("--embree: needs the embreex package (pip install embreex)")
    return bench_embree.DEFAULT_SEGMENTS


def _cmd_preview(args) -> int:
    from bsrt import preview
    from bsrt.scene.loading import CameraOverrides, load_input
    from bsrt.settings import with_settings

    options = preview.WindowOptions(
        args.width,
        args.height,
        args.frames,
        args.screenshot,
        args.max_fps,
        args.frame_log,
        preview.script_commands(args.events, args.script),
        args.cache,
    ).checked()
    scene = load_input(
        args.scene,
        args.format,
        width=args.width,
        height=args.height,
        camera=CameraOverrides.from_args(args),
        cache=args.cache,
    )
    scene = with_settings(scene, flag_values(args, "preview"))
    if scene.render.device == "gpu":  # the solver process needs a compute context: say now, before the window, if not
        from bsrt.rendering.gpu import check_gpu

        check_gpu()
    compile_if_cold()  # the first run on a machine: before the window opens
    return preview.run(scene, Path(args.scene), options)


def _cmd_batch(args) -> int:
    from bsrt.cli.batch import cmd_batch

    return cmd_batch(args)


def _cmd_animate(args) -> int:
    from bsrt.cli.batch import cmd_animate

    return cmd_animate(args)


COMMANDS = {
    "render": _cmd_render,
    "map": _cmd_map,
    "scene": _cmd_scene,
    "info": _cmd_info,
    "doctor": _cmd_doctor,
    "bench": _cmd_bench,
    "preview": _cmd_preview,
    "batch": _cmd_batch,
    "animate": _cmd_animate,
}

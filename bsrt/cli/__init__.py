"""Command line: ``bsrt render | map | info | doctor | bench | preview | batch | animate``.

Exit codes: 0 success, 2 bad usage or bad input (scene, model, options),
1 a render failure (e.g. no OpenGL context) or an output that could not be
written (``bsrt: error: PATH: <reason>``), 130 / 143 / 129 ended by SIGINT /
SIGTERM / SIGHUP (bsrt/interrupts.py). Errors are one line on stderr, never a
traceback (set BSRT_DEBUG=1 to see one). A render's outputs are written all
or nothing (bsrt/outputs.py): a failure or a signal leaves none behind.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import time
from pathlib import Path

from bsrt import __version__
from bsrt import interrupts
from bsrt.errors import InputError, OutputError, RenderError
from bsrt.io.formats import extensions_text, format_choices
from bsrt.methods import MAP_METHODS, METHODS
from bsrt.settings import add_flags, flag_values


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


class _Parser(argparse.ArgumentParser):
    """argparse with bsrt's one-line errors: ``bsrt render: error: argument --width: ...``
    (no usage block before it; ``--help`` shows that). Subcommand parsers are of this class too."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="bsrt", description="Ray-trace B-spline surfaces directly.")
    parser.add_argument("--version", action="version", version=f"bsrt {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    r = sub.add_parser("render", help="render a scene or a model file to a PNG image", epilog=METHODS_HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    r.add_argument("scene", help=INPUT_HELP)
    r.add_argument("-o", "--output", required=True, help="output image (.png)")
    add_flags(r, "render")
    _camera_options(r)
    r.add_argument("--aov", metavar="FILE.npz", help="also write per-pixel arrays (hit, t, surface, u, v, ...)")
    r.add_argument("--stats", action="store_true", help="print timings and counters as JSON on stdout")
    r.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="progress on stderr: a bar with time left, then a summary line (default: only on a "
                        "terminal, not in CI; --progress elsewhere writes plain lines)")

    m = sub.add_parser("map", help="write the preliminary map as a picture (paper's Figure 1)")
    m.add_argument("scene", help=INPUT_HELP)
    m.add_argument("-o", "--output", required=True, help="output image (.png)")
    add_flags(m, "map")
    _camera_options(m)

    i = sub.add_parser("info", help="what a model or scene file holds")
    i.add_argument("file", help=INPUT_HELP)
    _format_option(i)

    sub.add_parser("doctor", help="check the set-up: OpenGL (EGL devices, renderer), kernels, model readers")

    b = sub.add_parser("bench", help="time the methods on the paper's scenes (Tables 1 and 2)")
    b.add_argument("--scenes", nargs="+", help="scene names under scenes/ or paths (default: column water-lily)")
    b.add_argument("--methods", default=",".join(MAP_METHODS), help="comma-separated, of "
                   f"{', '.join(METHODS)} (default: %(default)s)")
    b.add_argument("--size", type=_positive_int, default=512, help="film width and height (default 512)")
    b.add_argument("--repeat", type=_positive_int, default=3, help="timed runs per method; the median is shown")
    b.add_argument("--json", metavar="FILE", help="also write the results as JSON")
    b.add_argument("--models", nargs="+", metavar="MODEL",
                   help="instead: whole renders of model files with and without their trims (the cost of trimming)")
    b.add_argument("--full", action="store_true", help="also show whole renders by stage (shadows, mirrors) and rays per second")

    _preview_arguments(sub.add_parser("preview", help="interactive window: orbit, pan, zoom; refines to the exact image"))
    from bsrt.cli.batch import add_commands as _batch_commands

    _batch_commands(sub, _positive_int)
    for command in ("render", "map", "info", "preview", "batch", "animate"):  # every command that loads models
        _cache_option(sub.choices[command])
    return parser


INPUT_HELP = f"scene file (.toml) or model file ({extensions_text()})"
METHODS_HELP = "methods (--method):\n" + "\n".join(f"  {m.name:9} {m.help}" for m in METHODS.values())


def _preview_arguments(parser) -> None:
    """The options of ``bsrt preview``."""
    from bsrt.preview.bindings import KEYS_HELP
    from bsrt.preview.script import SCRIPT_HELP

    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.description = "An interactive window: a fast GL view while the camera moves, then the exact image."
    parser.epilog = KEYS_HELP + "\n" + SCRIPT_HELP
    parser.add_argument("scene", help=INPUT_HELP)
    parser.add_argument("--width", type=int, default=800, help="window width in screen coordinates (default 800)")
    parser.add_argument("--height", type=int, default=600, help="window height (default 600)")
    add_flags(parser, "preview")
    _camera_options(parser)
    parser.add_argument("--frames", type=int, help="quit after N frames")
    parser.add_argument("--screenshot", metavar="OUT.png", help="with --frames: write the last frame")
    parser.add_argument("--events", metavar="SCRIPT", help="drive the window: e.g. \"orbit 30 0; wait; save out.png; quit\"")
    parser.add_argument("--script", metavar="FILE", help="the same commands from a file")
    parser.add_argument("--frame-log", metavar="FILE.json", help="write per-frame timestamps and states as JSON")
    parser.add_argument("--max-fps", type=float, default=60.0, help="frame rate cap (default 60; 0: none)")


def _format_option(parser) -> None:
    parser.add_argument("--format", default="auto", choices=format_choices(),
                        help="model file format (default: auto, by extension; occt: STEP, BREP or IGES through "
                             "OpenCASCADE)")


def _cache_option(parser) -> None:
    parser.add_argument("--no-cache", dest="cache", action="store_false",
                        help="read model files without the converted-model cache (neither use nor write it)")


def _vector(text: str):
    try:
        values = [float(x) for x in text.replace(",", " ").split()]
    except ValueError:
        values = []
    if len(values) != 3 or not all(map(math.isfinite, values)):
        raise argparse.ArgumentTypeError(f"expected three numbers like 1,2,3, got {text!r}")
    return values


def _camera_options(parser) -> None:
    _format_option(parser)
    parser.add_argument("--camera-eye", type=_vector, metavar="X,Y,Z", help="camera position (overrides)")
    parser.add_argument("--camera-look-at", type=_vector, metavar="X,Y,Z", help="point the camera looks at")
    parser.add_argument("--camera-up", type=_vector, metavar="X,Y,Z", help="up direction (models default to +z)")
    parser.add_argument("--fov", type=float, help="vertical field of view in degrees, 0 < fov < 180")


def _load_input(args, progress=None):
    """The Scene for ``args.scene`` (bsrt/scene/loading.py), its import warnings on stderr once.
    progress: the render's progress, shown the "load" stage."""
    from bsrt.scene.loading import CameraOverrides, load_input

    scene = load_input(args.scene, args.format, width=getattr(args, "width", None),
                       height=getattr(args, "height", None), camera=CameraOverrides.from_args(args),
                       cache=args.cache, progress=progress)
    if progress:
        progress.clear()  # the warnings below get clean lines
    for note in scene.notes:
        print(f"bsrt: warning: {note}", file=sys.stderr)
    return scene


def _check_output(path: str, suffix: str) -> Path:
    """An output path the run can write (checked before any work): the right
    suffix, an existing folder, not a folder itself."""
    out = Path(path)
    if out.suffix.lower() != suffix:
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
            os.path.exists(a) and os.path.exists(b) and os.path.samefile(a, b))

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
    from bsrt.rendering.image import npz_writer, png_writer
    from bsrt.outputs import Outputs
    from bsrt.rendering.pipeline import render
    from bsrt.rendering.options import RenderOptions

    out = _check_output(args.output, ".png")
    aov = _check_output(args.aov, ".npz") if args.aov else None
    progress = _progress(args)
    try:
        scene = _load_input(args, progress)
    except BaseException:
        if progress:
            progress.clear()
        raise
    _refuse_overwriting([out] + ([aov] if aov else []), scene)
    options = RenderOptions.resolve(scene, **flag_values(args, "render"))
    _say_if_compiling()
    try:
        with interrupts.at_safe_points(), Outputs() as outputs:
            if progress:
                progress("setup", 0.0)  # at once: the setup (kernels, hierarchy) comes before the first stage
            result = render(scene, options, progress=progress)
            clock = time.perf_counter()
            outputs.write(out, png_writer(result.pixels))
            if aov:
                outputs.write(aov, npz_writer(result.aovs()))
            result.stats["seconds"]["write"] = time.perf_counter() - clock
            if args.stats:
                _print_stdout(json.dumps(result.stats, indent=2))
            outputs.commit()
    except BaseException:
        if progress:
            progress.clear()  # the error message gets a clean line
        raise
    if progress:
        progress.finish(f"rendered {out}{f' (AOVs: {aov})' if aov else ''} {options.width}x{options.height}, "
                        f"{options.spp} spp, {options.method}, {progress.elapsed():.1f} s")
    return 0


def _cmd_map(args) -> int:
    from bsrt.rendering.image import png_writer
    from bsrt.outputs import Outputs
    from bsrt.rendering.prelim import render_map
    from bsrt.rendering.pipeline import Geometry
    from bsrt.settings import with_settings

    out = _check_output(args.output, ".png")
    scene = _load_input(args)
    _refuse_overwriting([out], scene)
    scene = with_settings(scene, flag_values(args, "map"))
    with interrupts.at_safe_points(), Outputs() as outputs:  # as render: signals wait for a safe point
        prelim = render_map(Geometry(scene).patches, scene.camera, scene.film.width, scene.film.height,
                            scene.render.map)
        outputs.write(out, png_writer(prelim.picture))
        outputs.commit()
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
        print(f"{path}: scene, {len(scene.surfaces)} surfaces ({trimmed} trimmed, {loops} loops), degrees {degrees}, "
              f"{rational} rational, "
              f"{len(scene.lights)} lights, {len(scene.materials)} materials, film {scene.film.width}x{scene.film.height}")
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
    from bsrt.rendering import gl
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
    chosen = os.environ.get("BSRT_EGL_DEVICE", os.environ.get("GLCONTEXT_DEVICE_INDEX"))
    print(f"device chosen:   {chosen if chosen is not None else 'first that works'} (set GLCONTEXT_DEVICE_INDEX=N to pick)")
    from bsrt.kernels import compile as kernels

    cached = kernels.is_cached()
    from bsrt.rendering.warm_up import warm_up

    seconds = warm_up()
    print(f"kernels:         {'loaded from the cache' if cached else 'compiled'} in {seconds:.1f} s "
          f"(cache: {kernels.cache_folder() or 'none'})")
    from bsrt.io.formats import READERS

    for reader in READERS.values():
        state = "ready" if reader.available() else f"needs pip install 'bsrt[{reader.extra}]'"
        print(f"reader {reader.name + ':':7} {' '.join(reader.extensions):38} {state}")
    print("OK: bsrt can render headless")
    return 0


def _say_if_compiling() -> None:
    """On a terminal, say that the first render on this machine compiles the kernels (once)."""
    from bsrt.kernels import compile as kernels

    if sys.stderr.isatty() and not kernels.is_cached():
        print("bsrt: compiling the ray-tracing kernels for this machine (once; about a minute)...", file=sys.stderr,
              flush=True)


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
    log = lambda text: print(text, flush=True)  # noqa: E731
    if args.models:
        results = bench.trim_cost(args.models, args.size, args.repeat, log=log)
    else:
        results = bench.run(args.scenes or bench.DEFAULT_SCENES, named, args.size, args.repeat, log=log)
        print()
        print(bench.format_tables(results))
        if args.full:
            print()
            print(bench.format_full(results))
    if args.json:
        from bsrt.rendering.image import write_text

        write_text(args.json, json.dumps(results, indent=2))
    return 0


def _cmd_preview(args) -> int:
    from bsrt import preview
    from bsrt.scene.loading import CameraOverrides, load_input
    from bsrt.settings import with_settings

    options = preview.WindowOptions(args.width, args.height, args.frames, args.screenshot, args.max_fps,
                                    args.frame_log, preview.script_commands(args.events, args.script)).checked()
    scene = load_input(args.scene, args.format, width=args.width, height=args.height,
                       camera=CameraOverrides.from_args(args), cache=args.cache)
    return preview.run(with_settings(scene, flag_values(args, "preview")), Path(args.scene), options)


def _cmd_batch(args) -> int:
    from bsrt.cli.batch import cmd_batch

    return cmd_batch(args)


def _cmd_animate(args) -> int:
    from bsrt.cli.batch import cmd_animate

    return cmd_animate(args)


COMMANDS = {"render": _cmd_render, "map": _cmd_map, "info": _cmd_info, "doctor": _cmd_doctor, "bench": _cmd_bench, "preview": _cmd_preview,
            "batch": _cmd_batch, "animate": _cmd_animate}


# Values that start with '-': `--camera-eye -1,-2,3`, `--camera-look-at
# -4281,19153,5738`. argparse takes every argument that starts with '-' for an
# option unless it matches its own negative-number pattern, which (up to Python
# 3.13) accepts '-5' and '-.5' but not '-1,-2,3' or '-1e3', so those failed with
# "expected one argument". That pattern is private and set per parser (each
# subcommand is a separate parser), and parse_args has no switch for it, but
# argparse's documented `--option=value` spelling hands any value over
# unchanged. So before parsing, a long option directly followed by an argument
# that starts with '-' and a digit ('-.' and a digit, '-inf', '-nan') is
# rewritten to that spelling. Such an argument can never be an option (no bsrt
# option looks like that), so this changes nothing else: it works in every
# subcommand, with abbreviated options too; the value still goes through the
# option's own type and checks (`--fov -5` is still "must be between 0 and 180",
# a malformed vector still "expected three numbers"); nothing after a '--'
# separator is touched.
_NEGATIVE_VALUE = re.compile(r"-(\.?\d|inf|nan)", re.IGNORECASE)


def _join_negative_values(argv: list[str]) -> list[str]:
    joined: list[str] = []
    for arg in argv:
        prev = joined[-1] if joined else ""
        if (prev.startswith("--") and prev != "--" and "=" not in prev and "--" not in joined
                and _NEGATIVE_VALUE.match(arg)):
            joined[-1] = f"{prev}={arg}"
        else:
            joined.append(arg)
    return joined


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else [str(a) for a in argv]
    args = _parser().parse_args(_join_negative_values(argv))
    try:
        return COMMANDS[args.command](args)
    except InputError as exc:
        print(f"bsrt: error: {exc}", file=sys.stderr)
        return 2
    except OutputError as exc:
        print(f"bsrt: error: {exc}", file=sys.stderr)
        return 1
    except RenderError as exc:
        print(f"bsrt: render failed: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        raise  # bsrt/__main__.py reports it and leaves at once
    except MemoryError:
        print("bsrt: render failed: out of memory (a smaller film, fewer samples per pixel or a simpler model "
              "needs less)", file=sys.stderr)
        return 1
    except Exception as exc:  # a bug: still one line, the traceback on request
        if os.environ.get("BSRT_DEBUG", "").strip().lower() in ("1", "true", "yes"):
            raise
        print(f"bsrt: internal error: {type(exc).__name__}: {exc} (set BSRT_DEBUG=1 for a traceback)", file=sys.stderr)
        return 1


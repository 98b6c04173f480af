"""Command line: ``bsrt render | map | doctor``.

Exit codes: 0 success, 2 bad usage or bad input (scene, model, options),
1 a render failure (e.g. no OpenGL context). Errors are one line on stderr,
never a traceback (set BSRT_DEBUG=1 to see one), and no output file is left
behind on failure.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from .errors import InputError, RenderError
from .scene import MAP_MODES, METHODS


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bsrt", description="Ray-trace B-spline surfaces directly.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    r = sub.add_parser("render", help="render a scene to a PNG image")
    r.add_argument("scene", help="scene file (.toml)")
    r.add_argument("-o", "--output", required=True, help="output image (.png)")
    r.add_argument("--width", type=_positive_int, help="film width in pixels (overrides [film])")
    r.add_argument("--height", type=_positive_int, help="film height in pixels (overrides [film])")
    r.add_argument("--method", choices=METHODS, help="root finder (overrides [render].method)")
    r.add_argument("--map", choices=MAP_MODES, dest="map_mode", help="preliminary map precision")
    r.add_argument("--aov", metavar="FILE.npz", help="also write per-pixel arrays (hit, t, surface, u, v, ...)")
    r.add_argument("--stats", action="store_true", help="print timings and counters as JSON on stdout")

    m = sub.add_parser("map", help="write the preliminary map as a picture (paper's Figure 1)")
    m.add_argument("scene", help="scene file (.toml)")
    m.add_argument("-o", "--output", required=True, help="output image (.png)")
    m.add_argument("--width", type=_positive_int)
    m.add_argument("--height", type=_positive_int)
    m.add_argument("--map", choices=MAP_MODES, dest="map_mode")

    sub.add_parser("doctor", help="check the OpenGL set-up (EGL devices, renderer)")
    return parser


def _check_output(path: str, suffix: str) -> Path:
    out = Path(path)
    if out.suffix.lower() != suffix:
        raise InputError(f"{path}: the output file name must end in {suffix}")
    if not out.parent.is_dir():
        raise InputError(f"{path}: the folder {str(out.parent)!r} does not exist")
    return out


def _progress():
    if not sys.stderr.isatty():
        return None
    start = time.perf_counter()

    def report(stage: str) -> None:
        print(f"\rbsrt: {stage}... ({time.perf_counter() - start:.1f} s)", end="", file=sys.stderr, flush=True)

    return report


def _cmd_render(args) -> int:
    from .image import write_npz, write_png
    from .render import render
    from .scene import load_scene

    out = _check_output(args.output, ".png")
    aov = _check_output(args.aov, ".npz") if args.aov else None
    scene = load_scene(args.scene)
    progress = _progress()
    result = render(scene, method=args.method, map_mode=args.map_mode, width=args.width, height=args.height, progress=progress)
    clock = time.perf_counter()
    written = []
    try:
        write_png(out, result.pixels)
        written.append(out)
        if aov:
            write_npz(aov, result.aovs())
            written.append(aov)
    except BaseException:
        for path in written:
            path.unlink(missing_ok=True)
        raise
    result.stats["seconds"]["write"] = time.perf_counter() - clock
    if progress:
        print(file=sys.stderr)
    if args.stats:
        print(json.dumps(result.stats, indent=2))
    return 0


def _cmd_map(args) -> int:
    from .image import write_png
    from .prelim import render_map
    from .render import Geometry
    from .scene import load_scene

    out = _check_output(args.output, ".png")
    scene = load_scene(args.scene)
    width, height = args.width or scene.film.width, args.height or scene.film.height
    prelim = render_map(Geometry(scene).patches, scene.camera, width, height, args.map_mode or scene.render.map)
    write_png(out, prelim.picture)
    return 0


def _cmd_doctor(args) -> int:
    from . import gl

    devices = gl.egl_devices()
    print(f"EGL devices: {len(devices)}")
    for i, name in enumerate(devices):
        print(f"  [{i}] {name}")
    if not devices:
        print("  none found: " + gl.FIX_HINT)
    try:
        ctx = gl.create_headless_context()
    except RenderError as exc:
        print(f"OpenGL: FAILED: {exc}")
        return 1
    print(f"OpenGL renderer: {ctx.info['GL_RENDERER']}")
    print(f"OpenGL version:  {ctx.info['GL_VERSION']}")
    print(f"OpenGL vendor:   {ctx.info['GL_VENDOR']}")
    chosen = os.environ.get("BSRT_EGL_DEVICE", os.environ.get("GLCONTEXT_DEVICE_INDEX"))
    print(f"device chosen:   {chosen if chosen is not None else 'first that works'} (set GLCONTEXT_DEVICE_INDEX=N to pick)")
    print("OK: bsrt can render headless")
    ctx.release()
    return 0


COMMANDS = {"render": _cmd_render, "map": _cmd_map, "doctor": _cmd_doctor}


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except InputError as exc:
        print(f"bsrt: error: {exc}", file=sys.stderr)
        return 2
    except RenderError as exc:
        print(f"bsrt: render failed: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("bsrt: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        print("bsrt: render failed: out of memory (try a smaller --width/--height)", file=sys.stderr)
        return 1
    except Exception as exc:  # a bug: still one line, the traceback on request
        if os.environ.get("BSRT_DEBUG"):
            raise
        print(f"bsrt: internal error: {type(exc).__name__}: {exc} (set BSRT_DEBUG=1 for a traceback)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())

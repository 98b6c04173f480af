"""The command line's parser: every subcommand and its options (the settings' flags come from
the settings registry, the formats and methods from theirs), and argv's negative values."""

from __future__ import annotations

import argparse
import math
import re

from bsrt import __version__
from bsrt.io.formats import extensions_text, format_choices
from bsrt.methods import MAP_METHODS, METHODS
from bsrt.settings import VIEW_NAMES, add_flags


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

    def format_help(self):
        if callable(self.epilog):  # an epilog whose text needs heavy imports is made only when shown
            self.epilog = self.epilog()
        return super().format_help()


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="bsrt", description="Ray-trace B-spline surfaces directly.")
    parser.add_argument("--version", action="version", version=f"bsrt {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    r = sub.add_parser(
        "render",
        help="render a scene or a model file to a PNG image",
        epilog=METHODS_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    r.add_argument("scene", help=INPUT_HELP)
    r.add_argument(
        "-o",
        "--output",
        help="output image: .png (8 or 16 bits, RGB or RGBA), .jpg/.jpeg or .webp, by its extension "
        "(default: the input's name with .png, in the current folder)",
    )
    add_flags(r, "render")
    _camera_options(r)
    r.add_argument("--aov", metavar="FILE.npz", help="also write per-pixel arrays (hit, t, surface, u, v, ...)")
    r.add_argument("--stats", action="store_true", help="print timings and counters as JSON on stdout")
    r.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="progress on stderr: a bar with time left, then a summary line (default: only on a "
        "terminal, not in CI; --progress elsewhere writes plain lines)",
    )

    m = sub.add_parser("map", help="write the preliminary map as a picture (paper's Figure 1)")
    m.add_argument("scene", help=INPUT_HELP)
    m.add_argument("-o", "--output", required=True, help="output image (.png)")
    add_flags(m, "map")
    _camera_options(m)

    sc = sub.add_parser(
        "scene",
        help="write a model file's automatic scene as a small, editable scene file that imports it",
        description="Write the scene `bsrt render MODEL` would render (film, camera, lights, material; the "
        "flags below change it) as a short scene file with one [[import]] of the model: rendering it gives "
        "the same picture, and its camera and lights are there to edit.",
    )
    sc.add_argument("model", help=f"model file ({extensions_text()})")
    sc.add_argument(
        "-o", "--output", help="the scene file to write (.toml; default: the model's name with .toml, here)"
    )
    add_flags(sc, "render")
    _camera_options(sc)

    i = sub.add_parser("info", help="what a model or scene file holds")
    i.add_argument("file", help=INPUT_HELP)
    _format_option(i)

    d = sub.add_parser("doctor", help="check the set-up: OpenGL (EGL devices, renderer), kernels, model readers")
    d.add_argument(
        "--compile",
        action="store_true",
        help="also compile the kernels into the cache now (once per machine; the first render does it otherwise)",
    )

    b = sub.add_parser("bench", help="time the methods on the paper's scenes (Tables 1 and 2)")
    b.add_argument("--scenes", nargs="+", help="scene names under scenes/ or paths (default: column water-lily)")
    b.add_argument(
        "--methods",
        default=",".join(MAP_METHODS),
        help=f"comma-separated, of {', '.join(METHODS)} (default: %(default)s)",
    )
    b.add_argument(
        "--devices",
        help="comma-separated, of cpu, gpu: each method timed on each, side by side (METHOD@gpu), with the cores "
        "used (default: cpu, and gpu where the context is a hardware one with OpenGL 4.5, compute and float64, "
        "though --device auto takes the CPU there too)",
    )
    b.add_argument("--size", type=_positive_int, default=512, help="film width and height (default 512)")
    b.add_argument("--repeat", type=_positive_int, default=3, help="timed runs per method; the median is shown")
    b.add_argument("--json", metavar="FILE", help="also write the results as JSON")
    b.add_argument(
        "--models",
        nargs="+",
        metavar="MODEL",
        help="instead: whole renders of model files with and without their trims (the cost of trimming)",
    )
    b.add_argument(
        "--full", action="store_true", help="also show whole renders by stage (shadows, mirrors) and rays per second"
    )
    b.add_argument(
        "--embree",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="also trace the primary rays with Embree on tessellations of 8, 32 and 128 quads per patch edge "
        "and compare time and depth with the exact ones (default: on when the embreex package is installed)",
    )
    b.add_argument(
        "--memory",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="also measure the peak memory of CLI renders at 512x512 and 2048x2048 in new processes, and the "
        "bytes per added pixel (default: on)",
    )
    b.add_argument(
        "--startup",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="also time start-up (a 16x16 CLI render minus importing NumPy) and the first run (an empty kernel "
        "cache) in new processes (default: on)",
    )
    b.add_argument(
        "--preview",
        action="store_true",
        help="also the preview's latency: bsrt preview 800x600 (water-lily, or the first of --scenes), orbiting, "
        "until each exact image (needs DISPLAY)",
    )

    _preview_arguments(
        sub.add_parser("preview", help="interactive window: orbit, pan, zoom; refines to the exact image")
    )
    from bsrt.cli.batch import add_commands as _batch_commands

    _batch_commands(sub, _positive_int)
    from bsrt.cli.scan import add_command as _scan_command

    _scan_command(sub, _positive_int, INPUT_HELP, _camera_options)
    for command in ("render", "map", "scene", "info", "preview", "batch", "animate", "scan"):  # all loading models
        _cache_option(sub.choices[command])
    return parser


INPUT_HELP = f"scene file (.toml) or model file ({extensions_text()})"
METHODS_HELP = "methods (--method):\n" + "\n".join(f"  {m.name:9} {m.help}" for m in METHODS.values())


def _preview_arguments(parser) -> None:
    """The options of ``bsrt preview``."""
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.description = "An interactive window: a fast GL view while the camera moves, then the exact image."
    parser.epilog = _preview_epilog  # the keys and script commands: importing the preview costs glfw and more
    parser.add_argument("scene", help=INPUT_HELP)
    parser.add_argument("--width", type=int, default=800, help="window width in screen coordinates (default 800)")
    parser.add_argument("--height", type=int, default=600, help="window height (default 600)")
    add_flags(parser, "preview")
    _camera_options(parser)
    parser.add_argument("--frames", type=int, help="quit after N frames")
    parser.add_argument("--screenshot", metavar="OUT.png", help="with --frames: write the last frame")
    parser.add_argument(
        "--events", metavar="SCRIPT", help='drive the window: e.g. "orbit 30 0; wait; save out.png; quit"'
    )
    parser.add_argument("--script", metavar="FILE", help="the same commands from a file")
    parser.add_argument("--frame-log", metavar="FILE.json", help="write per-frame timestamps and states as JSON")
    parser.add_argument("--max-fps", type=float, default=60.0, help="frame rate cap (default 60; 0: none)")


def _preview_epilog() -> str:
    from bsrt.preview.bindings import KEYS_HELP
    from bsrt.preview.script import SCRIPT_HELP

    return KEYS_HELP + "\n" + SCRIPT_HELP


def _format_option(parser) -> None:
    parser.add_argument(
        "--format",
        default="auto",
        choices=format_choices(),
        help="model file format (default: auto, by extension; occt: STEP, BREP or IGES through OpenCASCADE)",
    )


def _cache_option(parser) -> None:
    parser.add_argument(
        "--no-cache",
        dest="cache",
        action="store_false",
        help="without the caches of converted models and of prepared geometry (neither use nor write them)",
    )


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
    parser.add_argument(
        "--view",
        choices=VIEW_NAMES,
        help="a named view of the automatic camera, fitted to the model (or the scene's surfaces): "
        "the model fills 90%% of the frame, centred (default: a three-quarter view from above)",
    )


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
        if (
            prev.startswith("--")
            and prev != "--"
            and "=" not in prev
            and "--" not in joined
            and _NEGATIVE_VALUE.match(arg)
        ):
            joined[-1] = f"{prev}={arg}"
        else:
            joined.append(arg)
    return joined

"""``bsrt batch`` and ``bsrt animate``: their options, and the commands over bsrt.batches.api.

Exit codes: 0 every item rendered (or skipped, complete already), 1 any item
failed, 2 bad usage (no such input, no Dask, a bad scene for ``animate``).
"""

from __future__ import annotations

import argparse
import sys

from bsrt.batches.api import animate, batch, require_dask
from bsrt.io.formats import extensions_text
from bsrt.settings import add_flags, flag_values


def add_commands(sub, positive_int) -> None:
    """Add ``batch`` and ``animate`` to the CLI's subparsers."""

    b = sub.add_parser("batch", help="render many scenes or model files on a Dask cluster")
    b.add_argument(
        "inputs",
        nargs="+",
        metavar="INPUT",
        help=f"scene (.toml) or model files ({extensions_text()}), folders (searched recursively for "
        "them) or glob patterns",
    )

    def shared(p) -> None:
        p.add_argument("--out", required=True, metavar="DIR", help="output folder (created if missing)")
        add_flags(p, "render")
        where = p.add_mutually_exclusive_group()
        where.add_argument(
            "--workers", type=positive_int, metavar="N", help="local worker processes (default: one per core)"
        )
        where.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. tcp://host:8786")
        p.add_argument("--resume", action="store_true", help="skip items whose outputs exist and are complete")
        p.add_argument("--summary", metavar="FILE.json", help="write a JSON summary of every item")

    shared(b)
    b.add_argument("--aov", action="store_true", help="also write DIR/<name>.npz (per-pixel arrays)")

    a = sub.add_parser("animate", help="render the frames of an orbit or of camera keyframes on a Dask cluster")
    a.add_argument("input", metavar="SCENE_OR_MODEL", help=f"a scene (.toml) or model file ({extensions_text()})")
    shared(a)
    a.add_argument(
        "--frames",
        type=positive_int,
        metavar="N",
        help="number of frames (default with keyframes: the last keyframe's frame)",
    )
    a.add_argument(
        "--orbit",
        type=float,
        metavar="DEGREES",
        help="orbit the eye about look_at, around the camera's up axis, by DEGREES over the frames",
    )
    a.add_argument("--fps", type=float, default=24.0, help="frames per second of the animated file (default 24)")
    kind = a.add_mutually_exclusive_group()
    kind.add_argument(
        "--webp",
        action="store_const",
        const="webp",
        dest="animation",
        help="also write DIR/<name>.webp (animated, lossless)",
    )
    kind.add_argument(
        "--apng", action="store_const", const="apng", dest="animation", help="also write DIR/<name>.png (animated PNG)"
    )


def _reporter(progress):
    """Print each failure as one line on stderr (the bar cleared first)."""

    def report(item) -> None:
        if item.status == "failed":
            if progress:
                progress.clear()
            where = "" if item.message.startswith(item.input) else f"{item.input}: "
            print(f"bsrt: failed: {where}{item.message}", file=sys.stderr, flush=True)

    return report


def _run(command: str, call, local: bool = True) -> int:
    from bsrt.progress import wanted

    progress = wanted(sys.stderr, None)
    cold = local  # workers on this machine: the kernels are compiled once here, not by each at once

    def follow(stage, fraction, *detail) -> None:
        nonlocal cold
        if cold:  # the first report ("starting") comes once the inputs are checked, before any job
            from bsrt.cli.compiling import compile_if_cold

            cold = False
            compile_if_cold(progress, warm=False)
        if progress:
            progress(stage, fraction, *detail)

    if progress:
        progress("starting", 0.0)
    try:
        summary = call(progress=follow, report=_reporter(progress))
    except BaseException:
        if progress:
            progress.clear()
        raise
    line = f"{command}: {summary.line()}"
    if progress:
        progress.finish(line)
    else:
        print(f"bsrt: {line}", file=sys.stderr)
    return summary.exit_code


def _check_device(args: argparse.Namespace) -> None:
    """--device gpu where this machine's OpenGL cannot run the GPU solve: one
    InputError (exit 2) before any item starts, not a failure per item."""
    if flag_values(args, "render").get("device") == "gpu":
        from bsrt.rendering.gpu import check_gpu

        check_gpu()


def cmd_batch(args: argparse.Namespace) -> int:
    from bsrt.batches import engine as batching

    require_dask("batch")
    _check_device(args)
    paths = batching.discover(args.inputs)
    for note in batching.output_names(paths)[1]:
        print(f"bsrt: note: {note}", file=sys.stderr)
    return _run(
        "batch",
        lambda progress, report: batch(
            paths,
            args.out,
            aov=args.aov,
            **flag_values(args, "render"),
            workers=args.workers,
            scheduler=args.scheduler,
            resume=args.resume,
            summary=args.summary,
            progress=progress,
            report=report,
            cache=args.cache,
        ),
        local=not args.scheduler,
    )


def cmd_animate(args: argparse.Namespace) -> int:
    require_dask("animate")
    _check_device(args)
    return _run(
        "animate",
        lambda progress, report: animate(
            args.input,
            args.out,
            frames=args.frames,
            orbit=args.orbit,
            fps=args.fps,
            animation=args.animation,
            **flag_values(args, "render"),
            workers=args.workers,
            scheduler=args.scheduler,
            resume=args.resume,
            summary=args.summary,
            progress=progress,
            report=report,
            cache=args.cache,
        ),
        local=not args.scheduler,
    )

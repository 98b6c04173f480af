"""``bsrt scan MODEL -o cloud.ply|.npz``: a sensor's exact point cloud (docs/ray-queries.md).

The sensor stands where ``bsrt render`` puts the camera (``--camera-eye``,
``--camera-look-at``, ``--camera-up``, ``--fov`` move it): a spinning LIDAR
(default) spinning about up, azimuth 0 toward the look-at point, its beams
spread over the camera's field of view about the look direction's
elevation; or a pinhole depth camera (``--sensor pinhole``, width x height).
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from bsrt.errors import InputError

SUFFIXES = (".ply", ".npz")


def _angles(text: str) -> list[float]:
    try:
        values = [float(x) for x in text.replace(",", " ").split()]
    except ValueError:
        values = []
    if not values or not all(np.isfinite(values)):
        raise argparse.ArgumentTypeError(f"expected numbers like -10,0,10, got {text!r}")
    return values


def add_command(sub, positive_int, input_help: str, camera_options) -> None:
    """The ``scan`` subcommand's parser (called by cli/parser.py)."""
    from bsrt.settings import add_flags

    s = sub.add_parser("scan", help="a LIDAR or depth camera's exact point cloud of a model (.ply or .npz)")
    s.add_argument("scene", help=input_help)
    s.add_argument("-o", "--output", required=True, help="point cloud: .ply (binary: points, normals, face) or .npz")
    s.add_argument("--sensor", choices=("lidar", "pinhole"), default="lidar", help="the sensor (default lidar)")
    s.add_argument("--width", type=positive_int, default=320, help="pinhole: image width (default 320)")
    s.add_argument("--height", type=positive_int, default=240, help="pinhole: image height (default 240)")
    s.add_argument("--horizontal-fov", type=float, default=360.0, help="lidar: degrees swept about up (default 360)")
    s.add_argument(
        "--horizontal-resolution", type=float, default=0.2, help="lidar: degrees between columns (default 0.2)"
    )
    s.add_argument("--channels", type=positive_int, default=64, help="lidar: beams (default 64)")
    s.add_argument(
        "--vertical-fov",
        type=_angles,
        metavar="LO,HI",
        help="lidar: lowest and highest beam, degrees above the horizontal (default: --fov about the look direction)",
    )
    s.add_argument("--elevations", type=_angles, metavar="E1,E2,...", help="lidar: the beams' elevations instead")
    add_flags(s, "scan")
    camera_options(s)


def cmd_scan(args) -> int:
    """Trace the sensor's rays, write the cloud (all or nothing), a summary line on stderr."""
    from pathlib import Path

    from bsrt import sensors
    from bsrt.cli.commands import _check_output, _load_input, _refuse_overwriting
    from bsrt.outputs import write_file
    from bsrt.queries import intersect

    suffix = Path(args.output).suffix.lower()
    if suffix not in SUFFIXES:
        raise InputError(f"{args.output}: the output file name must end in .ply or .npz")
    out = _check_output(args.output, suffix)
    scene = _load_input(args)
    _refuse_overwriting([out], scene)
    cam = scene.camera
    if args.sensor == "pinhole":
        rays = sensors.pinhole(cam.eye, cam.look_at, up=cam.up, fov=cam.fov, width=args.width, height=args.height)
    else:
        look = np.asarray(cam.look_at, float) - np.asarray(cam.eye, float)
        up = np.asarray(cam.up, float) / np.linalg.norm(cam.up)
        pitch = float(np.degrees(np.arcsin(np.clip(look @ up / np.linalg.norm(look), -1.0, 1.0))))
        vfov = args.vertical_fov or [max(-90.0, pitch - cam.fov / 2), min(90.0, pitch + cam.fov / 2)]
        if len(vfov) != 2:
            raise InputError(f"--vertical-fov: expected two angles LO,HI, got {len(vfov)}")
        rays = sensors.lidar(
            cam.eye,
            up=cam.up,
            forward=look,
            horizontal_fov=args.horizontal_fov,
            horizontal_resolution=args.horizontal_resolution,
            vertical_fov=tuple(vfov),
            channels=args.channels,
            elevations=args.elevations,
        )
    clock = time.perf_counter()
    tolerance = args.tolerance if args.tolerance is not None else scene.render.tolerance  # the flag, else the scene's
    result = intersect(scene, rays.origins[:1], rays.directions, tolerance=tolerance)
    took = time.perf_counter() - clock
    if suffix == ".ply":
        write_file(out, lambda f: sensors.write_ply(f, result))
    else:
        write_file(out, lambda f: sensors.write_npz(f, result, rays))
    print(
        f"bsrt: scanned {len(rays)} rays ({args.sensor} {rays.shape[0]}x{rays.shape[1]}), "
        f"{int(result.hit.sum())} points -> {out} ({took:.2f} s)",
        file=sys.stderr,
    )
    return 0

"""Ray patterns of sensors, for :func:`bsrt.intersect` (``bsrt.sensors``; docs/ray-queries.md).

* :func:`lidar`: a spinning LIDAR: ``channels`` beams at fixed elevations
  (evenly over a vertical field of view, or given), swept about the sensor's
  up axis over a horizontal field of view in steps of a resolution.
* :func:`pinhole`: a pinhole depth camera (the rays of ``bsrt render``'s
  camera, one per pixel centre).

Both return :class:`SensorRays`; :meth:`SensorRays.range_image` turns a
nearest-hit result into an image (rows, columns) of ranges (NaN: no return).
Point-cloud files: :func:`write_ply` (binary) and :func:`write_npz`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bsrt.errors import InputError


@dataclass(frozen=True, eq=False)
class SensorRays:
    """origins: (N, 3) float64 (every row the sensor's position). directions: (N, 3) float64,
    unit. shape: (rows, columns) with rows * columns = N, row-major (lidar: channels from the
    highest elevation down x azimuth steps; pinhole: image rows from the top x columns). forward:
    (3,) unit, the sensor's axis (the camera's view direction; the lidar's azimuth 0). kind:
    "lidar" or "pinhole"."""

    origins: np.ndarray
    directions: np.ndarray
    shape: tuple[int, int]
    forward: np.ndarray
    kind: str

    def __len__(self) -> int:
        return int(self.directions.shape[0])

    def range_image(self, result) -> np.ndarray:
        """(rows, columns) float64: the nearest hit's t per ray (NaN where none) of a "nearest"
        :class:`bsrt.Intersections` for these rays."""
        return np.where(result.hit, result.t, np.nan).reshape(self.shape)

    def depth_image(self, result) -> np.ndarray:
        """(rows, columns) float64: distance along ``forward`` (a depth camera's z), NaN where none."""
        return (self.range_image(result).ravel() * (self.directions @ self.forward)).reshape(self.shape)


def _vector(name: str, value) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64) if np.asarray(value).dtype.kind in "fiu" else None
    if a is None or a.shape != (3,) or not np.isfinite(a).all():
        raise InputError(f"{name}: expected three finite numbers, got {value!r}")
    return a


def _frame(forward, up):
    """(forward x up, up, forward), unit: forward kept and up made perpendicular to it."""
    f = forward / np.linalg.norm(forward)
    u = up - (up @ f) * f
    if not np.linalg.norm(u) > 1e-9 * np.linalg.norm(up):
        raise InputError("up: must not be zero or parallel to the sensor's forward direction")
    u = u / np.linalg.norm(u)
    return np.cross(f, u), u, f


def _angle(name: str, value, lo: float, hi: float, lo_open: bool = True) -> float:
    from bsrt.validate import real

    return real(name, value, lo, hi, lo_open=lo_open)


def lidar(
    position,
    *,
    up=(0.0, 0.0, 1.0),
    forward=(1.0, 0.0, 0.0),
    horizontal_fov: float = 360.0,
    horizontal_resolution: float = 0.2,
    vertical_fov: tuple[float, float] = (-15.0, 15.0),
    channels: int = 16,
    elevations=None,
) -> SensorRays:
    """A spinning LIDAR at ``position`` (3,), spinning about ``up`` (3,).

    Azimuth 0 is ``forward`` (3,) made perpendicular to up; azimuths run
    counter-clockwise seen from above, centred on 0, over horizontal_fov
    degrees (0 < fov <= 360; 360: a full turn without repeating the first
    column) in steps of horizontal_resolution degrees. Beams: ``channels``
    elevations (degrees above the plane perpendicular to up) evenly from
    vertical_fov[1] down to vertical_fov[0], or ``elevations`` (K,) as given
    (each in [-90, 90]). Rays: (channels x columns), row 0 the highest beam.
    """
    origin = _vector("position", position)
    left, fwd, upv = _frame(_vector("up", up), _vector("forward", forward))  # up kept, forward made perpendicular
    hfov = _angle("horizontal_fov", horizontal_fov, 0.0, 360.0)
    step = _angle("horizontal_resolution", horizontal_resolution, 0.0, 360.0)
    columns = max(1, int(round(hfov / step)) + (0 if hfov >= 360.0 else 1))
    if columns > 1 << 24:
        raise InputError(f"horizontal_resolution: {step:g} degrees gives {columns} columns, more than {1 << 24}")
    if elevations is None:
        lo, hi = (_angle(f"vertical_fov[{i}]", v, -90.0, 90.0, False) for i, v in enumerate(vertical_fov))
        if lo > hi:
            raise InputError(f"vertical_fov: expected (lowest, highest) degrees, got ({lo:g}, {hi:g})")
        from bsrt.validate import whole

        count = whole("channels", channels, 1, 1 << 16)
        elev = np.linspace(hi, lo, count) if count > 1 else np.array([0.5 * (lo + hi)])
    else:
        elev = np.asarray(elevations, dtype=np.float64).ravel()
        if not elev.size or not np.isfinite(elev).all() or np.abs(elev).max() > 90.0:
            raise InputError("elevations: expected one or more angles in [-90, 90] degrees")
    if hfov >= 360.0:
        az = -180.0 + step * np.arange(columns)
    else:
        az = np.linspace(-0.5 * hfov, 0.5 * hfov, columns)
    a, e = np.radians(az)[None, :], np.radians(elev)[:, None]
    c = np.cos(e)
    d = (c * np.cos(a))[..., None] * fwd + (c * np.sin(a))[..., None] * left + np.sin(e)[..., None] * upv
    d = d.reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1)[:, None]
    return SensorRays(np.broadcast_to(origin, d.shape), d, (elev.size, columns), fwd, "lidar")


def pinhole(eye, look_at, *, up=(0.0, 0.0, 1.0), fov: float = 40.0, width: int = 320, height: int = 240):
    """A pinhole depth camera at ``eye`` (3,) looking at ``look_at`` (3,): one ray per pixel
    centre of a width x height image, fov degrees vertically (as ``bsrt render``'s camera)."""
    from bsrt.scene.camera import Camera, pixel_rays
    from bsrt.validate import whole

    e, look, u = _vector("eye", eye), _vector("look_at", look_at), _vector("up", up)
    if not np.linalg.norm(look - e) > 0:
        raise InputError("look_at: must differ from eye")
    _frame(look - e, u)
    fov = _angle("fov", fov, 0.0, 180.0)
    if fov >= 180.0:
        raise InputError(f"fov: must be below 180 degrees, got {fov:g}")
    w, h = whole("width", width, 1, 1 << 15), whole("height", height, 1, 1 << 15)
    camera = Camera(e, look, u, fov, "y")
    d = pixel_rays(camera, w, h)
    return SensorRays(np.broadcast_to(e, d.shape), d, (h, w), camera.basis()[2], "pinhole")


def write_ply(f, result) -> None:
    """A binary little-endian PLY of the hits of a nearest-hit ``result`` into the binary file f:
    per point x, y, z (double), nx, ny, nz (float, outward), face (int: the surface index)."""
    keep = np.flatnonzero(result.hit)
    rows = np.zeros(
        keep.size,
        dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4"), ("face", "<i4")],
    )
    for k, name in enumerate("xyz"):
        rows[name] = result.point[keep, k]
        rows["n" + name] = result.normal[keep, k]
    rows["face"] = result.surface[keep]
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment bsrt scan: exact ray hits; face = surface index\n"
        f"element vertex {keep.size}\nproperty double x\nproperty double y\nproperty double z\n"
        "property float nx\nproperty float ny\nproperty float nz\nproperty int face\nend_header\n"
    )
    f.write(header.encode("ascii"))
    f.write(rows.tobytes())


def write_npz(f, result, rays: SensorRays | None = None) -> None:
    """Every array of ``result`` (and of the rays: origins, directions, range (rows, columns) and
    for a pinhole depth (rows, columns)) into the binary file f as a compressed .npz (bsrt/npz.py);
    names: (S,) str."""
    from bsrt import npz

    arrays = {
        name: getattr(result, name)
        for name in ("hit", "t", "point", "normal", "front_facing", "u", "v", "surface", "residual")
    }
    arrays["names"] = np.array(result.names, dtype=str)
    if rays is not None:
        arrays["origins"] = np.ascontiguousarray(rays.origins)
        arrays["directions"] = rays.directions
        arrays["range"] = rays.range_image(result)
        if rays.kind == "pinhole":
            arrays["depth"] = rays.depth_image(result)
    npz.write(f, arrays)

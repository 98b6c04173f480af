"""The automatic camera and the studio lights: what a model file alone gets, and what a scene
gets where it leaves out its ``[camera]`` (scenes with ``[[import]]``) or every ``[[light]]``.

* ``surface_points``: points on what the surfaces show (grids over each domain, trimmed
  surfaces by their kept points and trim curves);
* ``fit_camera``: the camera looking along a named view that fits those points into
  ``FILL`` (90 %) of the frame, centred, for any aspect ratio (exactly for a sphere: its
  silhouette's diameter is 90 % of the frame's smaller side);
* ``studio_lights``: key, fill, rim and a soft ambient light, placed relative to the camera and
  scaled to the model (each point light's intensity is ``brightness * distance**2``: as bright
  as ``brightness`` at the model's centre, whatever the model's size).
"""

from __future__ import annotations

import numpy as np

from bsrt.errors import InputError
from bsrt.scene.camera import Camera
from bsrt.scene.model import Light
from bsrt.settings import VIEW_NAMES, VIEWS

__all__ = ["VIEWS", "VIEW_NAMES", "fit_camera", "studio_lights", "surface_points", "view_direction"]

FILL = 0.9  # the fraction of the frame (each side) the automatic camera gives the model
DEFAULT_FOV = 35.0  # degrees, vertical
GRID = 64  # samples per direction of a surface's domain
MAX_POINTS = 1 << 18  # fewer grid samples per surface on models of many surfaces (at least 9 x 9)
HULL_DIRECTIONS = 8  # extreme points that outline a 2-D point set, to drop the points inside


def surface_points(surfaces) -> np.ndarray:
    """(N, 3) float64 points on what the surfaces show: a grid over each domain (GRID x GRID, fewer
    when the model has many surfaces), trimmed surfaces by their kept points and points of their
    trim curves. Their box and extent are the model's, to the grid's spacing."""
    from bsrt.geometry.bspline import evaluate, grid_points
    from bsrt.geometry.trim_table import build_trim_table, loop_points
    from bsrt.kernels.trim import kept_many

    n = int(max(9, min(GRID, np.sqrt(MAX_POINTS / max(len(surfaces), 1)))))
    grids = [(np.linspace(*s.domain_u, n), np.linspace(*s.domain_v, n)) for s in surfaces]
    parts = [grid_points(s, gu, gv).reshape(-1, 3) for s, (gu, gv) in zip(surfaces, grids) if not s.is_trimmed]
    trimmed = [(s, g) for s, g in zip(surfaces, grids) if s.is_trimmed]
    if trimmed:
        table = build_trim_table([s for s, _ in trimmed])
        u = np.concatenate([np.repeat(gu, n) for _, (gu, gv) in trimmed])
        v = np.concatenate([np.tile(gv, n) for _, (gu, gv) in trimmed])
        keep = kept_many(table, np.repeat(np.arange(len(trimmed)), n * n), u, v).reshape(len(trimmed), n * n)
        owner, lu, lv = loop_points(table)
        order = np.argsort(owner, kind="stable")
        starts = np.searchsorted(owner[order], np.arange(len(trimmed) + 1))
        for m, (surf, (gu, gv)) in enumerate(trimmed):
            parts.append(grid_points(surf, gu, gv).reshape(-1, 3)[keep[m]])
            at = order[starts[m] : starts[m + 1]]
            (u0, u1), (v0, v1) = surf.domain_u, surf.domain_v
            parts.append(evaluate(surf, np.clip(lu[at], u0, u1), np.clip(lv[at], v0, v1))[0])
    return np.concatenate(parts)


def view_frame(up) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(X, Y, Z) unit (3,) vectors, right-handed, Z along ``up``: the world's axes when up is +z."""
    z = np.asarray(up, dtype=np.float64)
    if np.linalg.norm(z) == 0:
        raise InputError("--camera-up: must not be the zero vector")
    z = z / np.linalg.norm(z)
    x = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = x - z * (x @ z)
    x /= np.linalg.norm(x)
    return x, np.cross(z, x), z


def view_direction(view: str, up) -> tuple[np.ndarray, np.ndarray]:
    """(unit direction from the model to the eye, the camera's up), both (3,), of a named view."""
    if view not in VIEWS:
        raise InputError(f"--view: expected one of {', '.join(VIEW_NAMES)}, got {view!r}")
    frame = np.array(view_frame(up))  # rows X, Y, Z
    to_eye, cam_up = (np.asarray(a) @ frame for a in VIEWS[view])
    return to_eye / np.linalg.norm(to_eye), cam_up


def fit_camera(
    points: np.ndarray,
    width: int,
    height: int,
    view: str = "default",
    up=(0.0, 0.0, 1.0),
    fov: float = DEFAULT_FOV,
    turntable: bool = False,
) -> Camera:
    """The camera looking along ``view`` whose picture holds ``points`` (N, 3) within FILL of
    each side of the frame, centred: the points' projections span [-FILL, FILL] on the
    limiting axis, their projected box centred on both.

    With the view direction f fixed, a point at (x, y, z) (camera right, up, depth from the
    look-at point) projects to x / (z + D) for an eye at distance D; so the smallest D that
    keeps every |x - s| <= k (z + D) (k = FILL tan of the half field of view on that axis) is
    max(|x - s| / k - z), and s (the look-at point's sideways shift) centres the projected box
    (a few fixed-point steps). For a sphere of radius R this is D = R sqrt(1 + k^2) / k: its
    silhouette's diameter is FILL of the frame's smaller side.
    turntable: no sideways shift, and the points taken at every 10 degrees about the up axis
    through their box's centre, so an orbit about look_at stays centred and in the frame.
    """
    to_eye, cam_up = view_direction(view, up)
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre = (lo + hi) / 2.0
    rel = points - centre
    if turntable:
        from bsrt.scene.camera import rotation_matrix

        axis = np.asarray(up, dtype=np.float64)
        rel = np.concatenate([rel @ rotation_matrix(axis, a).T for a in range(0, 360, 10)])
    f = -to_eye
    r = np.cross(f, cam_up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    x, y, z = rel @ r, rel @ u, rel @ f
    keep = np.union1d(hull_vertices(z, x), hull_vertices(z, y))  # every max below is at one of them
    x, y, z = x[keep], y[keep], z[keep]
    aspect = width / height
    ty = np.tan(np.radians(fov) / 2.0)
    kx, ky = FILL * ty * aspect, FILL * ty
    sx = sy = 0.0
    size = max(float(np.ptp(x)), float(np.ptp(y)), float(np.ptp(z)), 1e-300)
    for _ in range(30):
        d = max(float(np.max(np.abs(x - sx) / kx - z)), float(np.max(np.abs(y - sy) / ky - z)), 1e-9 * size)
        if turntable:
            break
        px, py = (x - sx) / (z + d), (y - sy) / (z + d)
        step_x, step_y = (px.max() + px.min()) / 2.0 * d, (py.max() + py.min()) / 2.0 * d
        sx, sy = sx + step_x, sy + step_y
        if abs(step_x) + abs(step_y) < 1e-12 * size:
            break
    d = max(float(np.max(np.abs(x - sx) / kx - z)), float(np.max(np.abs(y - sy) / ky - z)), 1e-9 * size)
    look = centre + sx * r + sy * u
    return Camera(look - d * f, look, np.asarray(cam_up, dtype=np.float64), float(fov), "y")


def hull_vertices(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Indices (sorted, int64) of points (a, b), (N,) each, that include every vertex of their
    convex hull: the points that can maximise a linear function of (a, b), or (b - s) / (a + d)
    (the tangent of the angle under which a point of the plane, with every point in front of it,
    sees them: a projection's extent). Points inside or on the polygon of the extreme points
    along a few directions, other than its corners, are dropped first (Akl and Toussaint's
    filter, twice: HULL_DIRECTIONS, then 8 times as many on what is left), and the rest go
    through Andrew's monotone chain."""
    rest = np.arange(a.size)
    for count in (HULL_DIRECTIONS, 8 * HULL_DIRECTIONS):
        if rest.size <= count:
            break
        x, y = a[rest], b[rest]
        angles = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
        corners = np.unique(np.argmax(np.cos(angles)[:, None] * x + np.sin(angles)[:, None] * y, axis=1))
        if corners.size < 3:  # on a line: nothing is inside
            break
        ring = corners[np.argsort(np.arctan2(y[corners] - y[corners].mean(), x[corners] - x[corners].mean()))]
        inside = np.ones(rest.size, dtype=bool)
        for i, j in zip(ring, np.roll(ring, -1)):  # counter-clockwise
            inside &= (x[j] - x[i]) * (y - y[i]) - (y[j] - y[i]) * (x - x[i]) >= 0.0
        inside[ring] = False  # on the polygon's edges only its corners can be hull vertices
        rest = rest[~inside]
    rest = rest[np.lexsort((b[rest], a[rest]))]
    chain: list[int] = []
    for sweep in (rest, rest[::-1]):  # lower hull left to right, then upper hull back
        start = len(chain)
        for k in sweep.tolist():
            while len(chain) - start >= 2:
                i, j = chain[-2], chain[-1]
                if (a[j] - a[i]) * (b[k] - b[i]) - (b[j] - b[i]) * (a[k] - a[i]) > 0.0:
                    break
                chain.pop()
            chain.append(k)
    return np.unique(np.asarray(chain, dtype=np.int64))


def studio_lights(points_or_box, camera: Camera) -> tuple[Light, ...]:
    """The default studio rig for a model seen by ``camera``: a warm key light above and to the
    side of the camera, a cooler fill from the other side, a rim light from behind and above, and
    a soft ambient light. points_or_box: (N, 3) points on the model (or its two box corners);
    the point lights stand 3 model radii from its centre, each as bright at the centre as its
    brightness (intensity = brightness * distance**2)."""
    pts = np.asarray(points_or_box, dtype=np.float64)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-9)
    right, up, forward = camera.basis()
    to_eye = -forward

    def point(direction, brightness, color):
        d = np.asarray(direction, dtype=np.float64)
        position = centre + d / np.linalg.norm(d) * 3.0 * radius
        distance2 = float(np.sum((position - centre) ** 2))
        return Light("point", color=color, intensity=brightness * distance2, position=tuple(float(c) for c in position))

    return (
        Light("ambient", color=(1.0, 1.0, 1.0), intensity=0.15),
        point(to_eye - 0.9 * right + 0.9 * up, 0.85, (1.0, 0.96, 0.9)),  # key: left of the camera, above
        point(to_eye + 1.2 * right + 0.1 * up, 0.35, (0.85, 0.9, 1.0)),  # fill: right, low, cooler
        point(-to_eye + 0.3 * right + 1.2 * up, 0.5, (1.0, 1.0, 1.0)),  # rim: behind, above
    )

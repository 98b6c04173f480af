"""Write the bundled scene files (scene format version 1).

Run from the repository root:

    python scenes/generate.py            # (re)write scenes/*.toml
    python scenes/generate.py --check    # also validate them and print stats

The output is deterministic (no randomness, no clock): re-running the script
reproduces the committed files. Only the standard library and NumPy are needed
to write the files; ``--check`` also imports ``bsrt``.

Every surface is a non-rational (polynomial) B-spline. Circles cannot be
represented exactly without weights, so closed round objects are built from
quarter surfaces whose angular direction is a least-squares cubic B-spline fit
to a 90 degree arc (2 knot spans, radial error within 5e-4 of the radius, far
below a pixel at the bundled cameras). The four quarters are exact 90 degree
rotations of one another, so neighbouring surfaces share their boundary control
points bit for bit and close without gaps.

Scenes:

column.toml      the project's "Column" (cf. Sisojevs & Glazs): an Attic base
                 (plinth, two tori, scotia), an entasis shaft and a Doric
                 capital (astragal, echinus, abacus); 9 profile pieces x 4
                 quarters = 36 bicubic surfaces, closed at both ends by poles.
water-lily.toml  the "Water-lily": three rings of cupped petals, a seed pod and
                 a ring of stamens, and four lily pads lying on z = 0.
bench-64.toml    one bicubic surface with 8 x 8 knot spans (64 Bezier patches),
                 the speed benchmark.
quad.toml        one bilinear flat square seen head-on, 64 x 64: smoke tests.
"""

from __future__ import annotations

import argparse
import math
import sys
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DEGREE = 3


# ---------------------------------------------------------------------------
# B-spline helpers (degree 3 curves, clamped knot vectors)


def clamped_knots(params) -> list[float]:
    """Clamped cubic knot vector on [0, 1] with the given interior knots."""
    return [0.0] * (DEGREE + 1) + [float(k) for k in params] + [1.0] * (DEGREE + 1)


def uniform_knots(n: int) -> list[float]:
    """Clamped uniform cubic knot vector on [0, 1] for n control points."""
    spans = n - DEGREE
    return clamped_knots(i / spans for i in range(1, spans))


def averaged_knots(poly) -> list[float]:
    """Clamped, generally non-uniform cubic knots for a control polygon.

    Parameters by cumulative chord length of the polygon, then knots by
    de Boor's averaging, so the parameter speed roughly follows the geometry.
    """
    poly = np.asarray(poly, dtype=np.float64)
    n = len(poly)
    chord = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    t = np.concatenate([[0.0], np.cumsum(chord)]) / chord.sum()
    return clamped_knots(round(float(np.mean(t[j : j + DEGREE])), 9) for j in range(1, n - DEGREE))


def basis_matrix(knots, n: int, ts) -> np.ndarray:
    """(len(ts), n) matrix of the degree-3 B-spline basis functions at ts."""
    knots = np.asarray(knots, dtype=np.float64)
    out = np.zeros((len(ts), n))
    for row, t in enumerate(ts):
        span = min(max(int(np.searchsorted(knots, t, side="right")) - 1, DEGREE), n - 1)
        vals = [1.0]
        for d in range(1, DEGREE + 1):
            new = [0.0] * (d + 1)
            for r in range(d):
                i = span - d + 1 + r
                lo, hi = knots[i], knots[i + d]
                w = (t - lo) / (hi - lo) if hi > lo else 0.0
                new[r] += (1.0 - w) * vals[r]
                new[r + 1] += w * vals[r]
            vals = new
        out[row, span - DEGREE : span + 1] = vals
    return out


def unit(phi: float) -> tuple[float, float]:
    """(cos phi, sin phi), with exact zeros at multiples of 90 degrees."""
    return tuple(0.0 if abs(x) < 1e-15 else x for x in (math.cos(phi), math.sin(phi)))


def fit_arc(phi0: float, phi1: float, n: int) -> np.ndarray:
    """(n, 2) control points of a clamped uniform cubic fitting a unit arc.

    The arc runs counter-clockwise from angle phi0 to phi1 (radians). The end
    points lie exactly on the circle, P1 and P[n-2] lie on the end tangents at
    one shared distance a, so arcs that meet end to end join with matching
    first derivatives. a and the free inner points minimise the squared
    distance to the circle at 400 parameter values: a linear least-squares fit
    to points of constant angular speed, then refitted a few times to the
    nearest circle points of the current curve (the foot-point method).
    """
    c0, c1 = unit(phi0), unit(phi1)
    p0, pn = np.array(c0), np.array(c1)
    t0, t1 = np.array([-c0[1], c0[0]]), np.array([-c1[1], c1[0]])
    ts = np.linspace(0.0, 1.0, 400)
    basis = basis_matrix(uniform_knots(n), n, ts)
    # The curve is fixed + a_mat @ (a, x2, y2, ..., x[n-3], y[n-3]), stacked as x then y.
    fixed = np.outer(basis[:, 0] + basis[:, 1], p0) + np.outer(basis[:, -1] + basis[:, -2], pn)
    along = np.outer(basis[:, 1], t0) - np.outer(basis[:, -2], t1)  # d curve / d a
    cols = [np.concatenate([along[:, 0], along[:, 1]])]
    inner = n - 4
    for k in range(inner):
        b = basis[:, 2 + k]
        cols.append(np.concatenate([b, np.zeros_like(b)]))
        cols.append(np.concatenate([np.zeros_like(b), b]))
    a_mat = np.stack(cols, axis=1)
    phis = phi0 + (phi1 - phi0) * ts
    target = np.stack([np.cos(phis), np.sin(phis)], axis=1)
    for _ in range(30):
        rhs = np.concatenate([target[:, 0] - fixed[:, 0], target[:, 1] - fixed[:, 1]])
        sol = np.linalg.lstsq(a_mat, rhs, rcond=None)[0]
        curve = fixed + (a_mat @ sol).reshape(2, -1).T
        target = curve / np.linalg.norm(curve, axis=1)[:, None]
    pts = np.empty((n, 2))
    pts[0], pts[-1] = c0, c1
    pts[1], pts[-2] = p0 + sol[0] * t0, pn - sol[0] * t1
    pts[2:-2] = sol[1:].reshape(inner, 2)
    return pts


def rot90(points: np.ndarray, k: int) -> np.ndarray:
    """Rotate (..., 3) points by k * 90 degrees about z, exactly (swaps only)."""
    out = np.array(points, dtype=np.float64)
    for _ in range(k % 4):
        out = np.stack([-out[..., 1], out[..., 0], out[..., 2]], axis=-1)
    return out


def material_table(name, color, specular, shininess, reflectance=0.0) -> dict:
    """A [[material]] table."""
    return {"name": name, "color": color, "specular": specular, "shininess": shininess, "reflectance": reflectance}


def ground(name, material, half, z) -> dict:
    """A flat square [-half, half]^2 at height z as a bicubic B-spline (4 x 4 points)."""
    g = np.linspace(-half, half, 4)
    pts = [[[x, y, z] for y in g] for x in g]
    knots = [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0]
    return surface(name, material, knots, knots, pts)


def surface(name, material, knots_u, knots_v, points, degree=(DEGREE, DEGREE)) -> dict:
    pts = np.asarray(points, dtype=np.float64)
    assert pts.ndim == 3 and pts.shape[2] == 3, (name, pts.shape)
    assert len(knots_u) == pts.shape[0] + degree[0] + 1, name
    assert len(knots_v) == pts.shape[1] + degree[1] + 1, name
    return {
        "name": name,
        "material": material,
        "degree": list(degree),
        "knots_u": list(knots_u),
        "knots_v": list(knots_v),
        "points": pts,
    }


def revolve(name, material, profile, n_arc=5, rim=None) -> list[dict]:
    """Four quarter surfaces of revolution of a profile curve in the (r, z) plane.

    u runs around the axis (counter-clockwise seen from above) through n_arc
    control points per quarter, v along the profile (chord-length averaged
    knots), so S_u x S_v points out of a profile that runs bottom to top. A
    profile point with r = 0 makes a pole. rim(phi) -> (dr, dz), if given,
    displaces the last profile row; it must have a period of 90 degrees so that
    the quarters, exact rotations of each other, still meet without gaps.
    """
    arc = fit_arc(0.0, math.pi / 2, n_arc)
    pts = []
    for cx, cy in arc:
        row = [[r * cx, r * cy, z] for (r, z) in profile]
        if rim is not None:
            dr, dz = rim(math.atan2(cy, cx))
            r, z = profile[-1]
            row[-1] = [(r + dr) * cx, (r + dr) * cy, z + dz]
        pts.append(row)
    knots_v = averaged_knots(profile)
    return [surface(f"{name}-q{k}", material, uniform_knots(n_arc), knots_v, rot90(pts, k)) for k in range(4)]


# ---------------------------------------------------------------------------
# Column


def arc_points(centre, radius, deg0, deg1, n):
    """Control polygon of an arc of a circle in the profile plane (degrees)."""
    unit = fit_arc(math.radians(deg0), math.radians(deg1), n)
    return [(centre[0] + radius * x, centre[1] + radius * y) for (x, y) in unit]


def column_profile() -> list[tuple[str, str, list]]:
    """(piece name, material, control polygon in (r, z)) from bottom to top.

    Consecutive pieces share their end points exactly; the first piece starts
    and the last ends on the axis (r = 0), closing the solid with a pole.
    """
    base, shaft = "marble-dark", "marble"
    torus_c, torus_r = (1.20, 0.80), 0.27
    plinth_top = 0.55
    phi_low = math.degrees(math.asin((plinth_top - torus_c[1]) / torus_r))
    lower_torus = arc_points(torus_c, torus_r, phi_low, 105.0, 7)
    upper_torus = arc_points((1.04, 1.42), 0.17, -75.0, 100.0, 6)
    astragal = arc_points((0.80, 8.66), 0.09, -90.0, 90.0, 6)
    pieces = [
        ("bottom", base, [(0.0, 0.0), (0.35, 0.0), (0.75, 0.0), (1.15, 0.0), (1.43, 0.0)]),
        (
            "plinth",
            base,
            [
                (1.43, 0.0),
                (1.55, 0.0),
                (1.55, 0.1),
                (1.55, 0.28),
                (1.55, 0.45),
                (1.55, plinth_top),
                (1.42, plinth_top),
                lower_torus[0],
            ],
        ),
        ("lower-torus", base, lower_torus),
        (
            "scotia",
            base,
            [lower_torus[-1], (1.08, 1.075), (1.00, 1.10), (0.96, 1.16), (0.98, 1.23), (1.03, 1.255), upper_torus[0]],
        ),
        ("upper-torus", base, upper_torus),
        (
            "shaft",
            shaft,
            [
                upper_torus[-1],
                (0.95, 1.60),
                (0.92, 1.66),
                (0.92, 2.2),
                (0.93, 3.6),
                (0.91, 5.2),
                (0.86, 6.8),
                (0.80, 8.1),
                (0.785, 8.45),
                (0.79, 8.56),
                astragal[0],
            ],
        ),
        ("astragal", base, astragal),
        (
            "echinus",
            base,
            [astragal[-1], (0.84, 8.76), (0.98, 8.80), (1.15, 8.87), (1.28, 8.98), (1.33, 9.08), (1.33, 9.16)],
        ),
        (
            "abacus",
            base,
            [
                (1.33, 9.16),
                (1.44, 9.16),
                (1.46, 9.16),
                (1.46, 9.26),
                (1.46, 9.46),
                (1.46, 9.56),
                (1.44, 9.56),
                (1.30, 9.56),
                (0.95, 9.56),
                (0.55, 9.56),
                (0.2, 9.56),
                (0.0, 9.56),
            ],
        ),
    ]
    for (_, _, a), (_, _, b) in zip(pieces, pieces[1:]):
        assert a[-1] == b[0], (a[-1], b[0])
    return pieces


def column_scene() -> dict:
    surfaces = []
    for name, material, poly in column_profile():
        surfaces += revolve(name, material, poly)
    surfaces.append(ground("floor", "floor", 9.0, 0.0))
    return {
        "comment": "Column: Attic base, entasis shaft, Doric capital (9 profile pieces x 4 quarters) on a polished floor.",
        "film": {"width": 512, "height": 512, "background": [0.02, 0.02, 0.03]},
        "camera": {"eye": [13.0, -17.0, 10.0], "look_at": [0.0, 0.0, 4.75], "up": [0.0, 0.0, 1.0], "fov": 32.0},
        "render": {"method": "newton"},
        "materials": [
            material_table("marble", [0.93, 0.87, 0.78], 0.35, 60.0),
            material_table("marble-dark", [0.82, 0.74, 0.64], 0.3, 40.0),
            material_table("floor", [0.30, 0.31, 0.34], 0.5, 80.0, reflectance=0.3),
        ],
        "lights": [
            {"kind": "ambient", "color": [1.0, 1.0, 1.0], "intensity": 0.15},
            {"kind": "point", "position": [14.0, -9.0, 16.0], "color": [1.0, 0.96, 0.9], "intensity": 400.0},
            {"kind": "directional", "direction": [1.0, 1.2, -0.6], "color": [0.75, 0.82, 1.0], "intensity": 0.35},
        ],
        "surfaces": surfaces,
    }


# ---------------------------------------------------------------------------
# Water-lily


def petal(name, material, phi, length, base_r, base_z, elev0, elev1, half_width, cup) -> dict:
    """One petal: u along the petal (base to pointed tip), v across it.

    The mid line starts at radius base_r and height base_z and bends upward,
    its elevation growing from elev0 to elev1 degrees; the cross-section is
    cupped (edges raised by cup * local half-width); the tip row collapses to
    a point. The petal is then turned by phi degrees about z.
    """
    rows = [0.0, 0.15, 0.35, 0.55, 0.75, 0.9, 1.0]
    widths = [0.22, 0.62, 0.92, 1.0, 0.82, 0.45, 0.0]
    across = [-1.0, -0.55, 0.0, 0.55, 1.0]
    e0, e1 = math.radians(elev0), math.radians(elev1)
    c, s = math.cos(math.radians(phi)), math.sin(math.radians(phi))
    pts = []
    for t, w in zip(rows, widths):
        # Mid line: integral of the unit direction (cos e, sin e), e linear in t.
        k = e1 - e0
        if abs(k) < 1e-12:
            x, z = t * math.cos(e0), t * math.sin(e0)
        else:
            x = (math.sin(e0 + k * t) - math.sin(e0)) / k
            z = (math.cos(e0) - math.cos(e0 + k * t)) / k
        x, z = base_r + length * x, base_z + length * z
        e = e0 + k * t
        nx, nz = -math.sin(e), math.cos(e)  # in-plane normal of the mid line (upper side)
        row = []
        for a in across:
            hw = half_width * w
            lx, ly = x + cup * hw * a * a * nx, hw * a
            lz = z + cup * hw * a * a * nz
            row.append([c * lx - s * ly, s * lx + c * ly, lz])
        pts.append(row)
    return surface(name, material, averaged_knots([p[2] for p in pts]), uniform_knots(len(across)), pts)


def lily_pad(name, material, centre, radius, notch_deg, height, waves, phase) -> dict:
    """A lily pad: u runs around from one side of the notch to the other, v from
    the centre (a pole) to the rim; gentle waves grow toward the rim."""
    gap = 9.0
    n_ang, radii = 15, [0.0, 0.2, 0.45, 0.72, 1.0]
    arc = fit_arc(math.radians(notch_deg + gap), math.radians(notch_deg + 360.0 - gap), n_ang)
    pts = []
    for cx, cy in arc:
        phi = math.atan2(cy, cx)
        row = []
        for rho in radii:
            dz = 0.035 * rho**2 * math.sin(waves * phi + phase) + 0.03 * rho**4
            row.append([centre[0] + radius * rho * cx, centre[1] + radius * rho * cy, height + dz])
        pts.append(row)
    return surface(name, material, uniform_knots(n_ang), averaged_knots([[r, 0.0] for r in radii]), pts)


def water_lily_scene() -> dict:
    surfaces = []
    rings = [  # count, phase, length, base_r, base_z, elev0, elev1, half_width, cup
        (8, 0.0, 1.30, 0.16, 0.06, 6.0, 28.0, 0.30, 0.35),
        (8, 22.5, 1.12, 0.14, 0.09, 24.0, 52.0, 0.27, 0.45),
        (6, 15.0, 0.88, 0.12, 0.12, 42.0, 68.0, 0.23, 0.5),
    ]
    for ring, (count, phase, length, base_r, base_z, e0, e1, hw, cup) in enumerate(rings):
        for m in range(count):
            wobble = 4.0 * math.sin(2.3 * m + ring)  # break the perfect symmetry a little
            surfaces.append(
                petal(
                    f"petal-{ring + 1}-{m + 1}",
                    "petal",
                    phase + 360.0 * m / count + wobble,
                    length * (1.0 + 0.04 * math.cos(1.7 * m)),
                    base_r,
                    base_z,
                    e0 + 0.5 * wobble,
                    e1,
                    hw,
                    cup,
                )
            )
    # Seed pod: a flattened dome closed by a pole at the top and a pole at the bottom.
    surfaces += revolve(
        "pod",
        "centre",
        [(0.0, 0.10), (0.10, 0.10), (0.17, 0.12), (0.19, 0.22), (0.17, 0.33), (0.10, 0.37), (0.0, 0.38)],
    )
    # Stamens: a flaring open ring with a crown of 12 points around its rim.
    surfaces += revolve(
        "stamens",
        "centre",
        [(0.18, 0.10), (0.20, 0.22), (0.24, 0.36), (0.30, 0.47), (0.35, 0.55)],
        n_arc=15,
        rim=lambda phi: (0.05 * math.cos(12 * phi), 0.07 * math.cos(12 * phi)),
    )
    flower_scale = 1.3  # the flower was modelled 2.8 units across
    for s in surfaces:
        s["points"] = s["points"] * flower_scale
    pads = [  # centre, radius, notch direction, height, waves, phase
        ((1.95, 1.6), 1.3, 200.0, 0.0, 5, 0.3),
        ((-1.95, 1.7), 1.35, 290.0, 0.01, 6, 1.1),
        ((-1.95, -1.45), 1.15, 20.0, 0.02, 5, 2.0),
        ((1.65, -1.85), 1.2, 120.0, 0.005, 4, 0.7),
    ]
    for k, (centre, radius, notch, h, waves, phase) in enumerate(pads):
        surfaces.append(lily_pad(f"pad-{k + 1}", "leaf", centre, radius, notch, h, waves, phase))
    surfaces.append(ground("water", "water", 9.0, -0.04))
    return {
        "comment": "Water-lily: 22 petals in three rings, seed pod, stamens, 4 lily pads on reflective water.",
        "film": {"width": 512, "height": 512, "background": [0.01, 0.03, 0.05]},
        "camera": {"eye": [5.3, -9.3, 9.4], "look_at": [0.0, -0.3, 0.1], "up": [0.0, 0.0, 1.0], "fov": 30.0},
        "render": {"method": "newton"},
        "materials": [
            material_table("petal", [0.96, 0.82, 0.87], 0.25, 30.0),
            material_table("centre", [0.95, 0.74, 0.16], 0.2, 20.0),
            material_table("leaf", [0.16, 0.42, 0.13], 0.4, 50.0),
            material_table("water", [0.02, 0.06, 0.08], 0.6, 120.0, reflectance=0.45),
        ],
        "lights": [
            {"kind": "ambient", "color": [1.0, 1.0, 1.0], "intensity": 0.15},
            {"kind": "point", "position": [6.0, -5.0, 10.0], "color": [1.0, 0.97, 0.92], "intensity": 160.0},
            {"kind": "directional", "direction": [1.0, 1.0, -1.0], "color": [0.8, 0.85, 1.0], "intensity": 0.35},
        ],
        "surfaces": surfaces,
    }


# ---------------------------------------------------------------------------
# Benchmark surface and smoke-test quad


def bench_scene() -> dict:
    n = 11  # 8 knot spans per direction: 64 Bezier patches
    knots = uniform_knots(n)
    greville = [sum(knots[i + 1 : i + DEGREE + 1]) / DEGREE for i in range(n)]
    pts = []
    for gu in greville:
        x = -2.0 + 4.0 * gu
        row = []
        for gv in greville:
            y = -2.0 + 4.0 * gv
            z = 0.4 * math.sin(1.5 * x + 0.4) * math.cos(1.3 * y) + 0.16 * math.sin(2.4 * (x + y) + 1.0)
            row.append([x, y, z])
        pts.append(row)
    return {
        "comment": "Benchmark: one bicubic surface with 8 x 8 knot spans (64 patches), 11 x 11 points.",
        "film": {"width": 512, "height": 512, "background": [0.02, 0.02, 0.03]},
        "camera": {"eye": [0.0, -1.2, 6.2], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 0.0, 1.0], "fov": 36.0},
        "render": {"method": "newton"},
        "materials": [
            material_table("clay", [0.78, 0.55, 0.42], 0.3, 40.0),
        ],
        "lights": [
            {"kind": "ambient", "color": [1.0, 1.0, 1.0], "intensity": 0.15},
            {"kind": "point", "position": [5.0, -3.0, 7.0], "color": [1.0, 0.97, 0.92], "intensity": 90.0},
            {"kind": "directional", "direction": [-1.0, 1.0, -1.0], "color": [0.8, 0.85, 1.0], "intensity": 0.3},
        ],
        "surfaces": [surface("height-field", "clay", knots, knots, pts)],
    }


def quad_scene() -> dict:
    pts = [[[-1.0, 0.0, -1.0], [-1.0, 0.0, 1.0]], [[1.0, 0.0, -1.0], [1.0, 0.0, 1.0]]]
    return {
        "comment": "Smoke test: one bilinear 2 x 2 square in the plane y = 0, seen head-on.",
        "film": {"width": 64, "height": 64, "background": [0.05, 0.05, 0.08]},
        "camera": {"eye": [0.0, -4.0, 0.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 0.0, 1.0], "fov": 40.0},
        "render": {"method": "newton"},
        "materials": [
            material_table("white", [0.9, 0.9, 0.9], 0.1, 10.0),
        ],
        "lights": [
            {"kind": "ambient", "color": [1.0, 1.0, 1.0], "intensity": 0.15},
            {"kind": "point", "position": [1.0, -4.0, 2.0], "color": [1.0, 1.0, 1.0], "intensity": 20.0},
            {"kind": "directional", "direction": [0.5, 1.0, -0.5], "color": [1.0, 1.0, 1.0], "intensity": 0.3},
        ],
        "surfaces": [surface("square", "white", [0.0, 0.0, 1.0, 1.0], [0.0, 0.0, 1.0, 1.0], pts, degree=(1, 1))],
    }


SCENES = {
    "column.toml": column_scene,
    "water-lily.toml": water_lily_scene,
    "bench-64.toml": bench_scene,
    "quad.toml": quad_scene,
}


# ---------------------------------------------------------------------------
# TOML writer


def fnum(x) -> str:
    """A float as TOML: 12 significant digits, always with a '.' or exponent."""
    x = float(x) + 0.0  # no negative zero
    if not math.isfinite(x):
        raise ValueError(f"non-finite number {x!r}")
    s = f"{x:.12g}"
    if "e" in s:
        mant, exp = s.split("e")
        s = (mant if "." in mant else mant + ".0") + "e" + exp
    elif "." not in s:
        s += ".0"
    return s


def fvec(values) -> str:
    return "[" + ", ".join(fnum(v) for v in values) + "]"


def value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return fnum(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return fvec(v)


def table(name: str, entries: dict, array: bool = False) -> list[str]:
    lines = [f"[[{name}]]" if array else f"[{name}]"]
    lines += [f"{key} = {value(v)}" for key, v in entries.items()]
    return lines + [""]


def to_toml(scene: dict, filename: str) -> str:
    lines = [
        f"# {filename}: {scene['comment']}",
        "# Generated by scenes/generate.py; edit that script, not this file.",
        "",
    ]
    lines += table("film", scene["film"])
    lines += table("camera", scene["camera"])
    lines += table("render", scene["render"])
    for m in scene["materials"]:
        lines += table("material", m, array=True)
    for light in scene["lights"]:
        lines += table("light", light, array=True)
    for s in scene["surfaces"]:
        lines += [
            "[[surface]]",
            f"name = {value(s['name'])}",
            f"material = {value(s['material'])}",
            f"degree = [{s['degree'][0]}, {s['degree'][1]}]",
            f"knots_u = {fvec(s['knots_u'])}",
            f"knots_v = {fvec(s['knots_v'])}",
            "points = [",
        ]
        for row in s["points"]:
            lines.append("  [" + ", ".join(fvec(p) for p in row) + "],")
        lines += ["]", ""]
    return "\n".join(lines)


# ---------------------------------------------------------------------------
# --check: validate the written files and print statistics


def camera_ndc(camera: dict, width: int, height: int, points: np.ndarray) -> np.ndarray:
    """Points -> (x / tx, y / ty) screen coordinates, in [-1, 1] when inside the frame
    (SCENE_FORMAT.md, "Camera and pixels"); rows with nonpositive depth get inf."""
    eye, look = np.array(camera["eye"], float), np.array(camera["look_at"], float)
    f = (look - eye) / np.linalg.norm(look - eye)
    r = np.cross(f, np.array(camera["up"], float))
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    aspect = width / height
    ty = math.tan(math.radians(camera["fov"]) / 2)
    if camera.get("fov_axis", "y") == "x":
        ty /= aspect
    tx = ty * aspect
    d = points - eye
    depth = d @ f
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.stack([(d @ r) / depth / tx, (d @ u) / depth / ty], axis=1)
    out[depth <= 0] = np.inf
    return out


def boundary_edges(surf, evaluate, samples: int = 41):
    """The four boundary curves of a surface, each (samples, 3)."""
    (u0, u1), (v0, v1) = surf.domain_u, surf.domain_v
    t = np.linspace(0.0, 1.0, samples)
    us, vs = u0 + (u1 - u0) * t, v0 + (v1 - v0) * t
    edges = []
    for u in (u0, u1):
        edges.append(evaluate(surf, np.full(samples, u), vs)[0])
    for v in (v0, v1):
        edges.append(evaluate(surf, us, np.full(samples, v))[0])
    return edges


def check(path: Path) -> bool:
    from bsrt.geometry.bspline import evaluate, make_surface

    with open(path, "rb") as fh:
        doc = tomllib.load(fh)
    surfs = [make_surface(s["degree"], s["knots_u"], s["knots_v"], s["points"]) for s in doc["surface"]]
    materials = {m["name"] for m in doc["material"]}
    ok = all(s["material"] in materials for s in doc["surface"])
    allpts = np.concatenate([s.points.reshape(-1, 3) for s in surfs])
    lo, hi = allpts.min(axis=0), allpts.max(axis=0)
    diag = float(np.linalg.norm(hi - lo))
    finite = True
    for s in surfs:
        (u0, u1), (v0, v1) = s.domain_u, s.domain_v
        uu, vv = np.meshgrid(np.linspace(u0, u1, 33), np.linspace(v0, v1, 33), indexing="ij")
        S, Su, Sv = evaluate(s, uu.ravel(), vv.ravel())
        finite &= bool(np.all(np.isfinite(S)) and np.all(np.isfinite(Su)) and np.all(np.isfinite(Sv)))
    # Seams: boundary curves of different surfaces whose ends and middle coincide.
    tol = 1e-6 * diag
    edges = []  # (surface index, curve) for curves of nonzero length
    degenerate = 0
    for k, s in enumerate(surfs):
        for e in boundary_edges(s, evaluate):
            if np.ptp(e, axis=0).max() <= tol:
                degenerate += 1
            else:
                edges.append((k, e))
    matched = [False] * len(edges)
    gap = 0.0
    seams = 0
    for a in range(len(edges)):
        for b in range(a + 1, len(edges)):
            ea, eb = edges[a][1], edges[b][1]
            for cand in (eb, eb[::-1]):
                mid = len(ea) // 2
                if all(np.linalg.norm(ea[i] - cand[i]) <= 1e-3 * diag for i in (0, mid, -1)):
                    gap = max(gap, float(np.linalg.norm(ea - cand, axis=1).max()))
                    matched[a] = matched[b] = True
                    seams += 1
                    break
    open_edges = matched.count(False)
    film, cam = doc["film"], doc["camera"]
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    box = camera_ndc(cam, film["width"], film["height"], corners)
    ctrl = camera_ndc(cam, film["width"], film["height"], allpts)
    in_frame = bool(np.all(np.abs(box) < 1.0))
    degrees = sorted({tuple(s.degree) for s in surfs})
    print(f"{path.name}: {len(surfs)} surfaces, degrees {degrees}, materials ok {ok}, finite {finite}")
    print(f"  box {np.round(lo, 3).tolist()} .. {np.round(hi, 3).tolist()}, diagonal {diag:.4g}")
    print(f"  seams {seams}, max seam gap {gap:.3g}, open (unmatched) edges {open_edges}, collapsed edges {degenerate}")
    print(
        f"  control points on screen: x {ctrl[:, 0].min():+.3f} .. {ctrl[:, 0].max():+.3f}, "
        f"y {ctrl[:, 1].min():+.3f} .. {ctrl[:, 1].max():+.3f}"
    )
    print(
        f"  bounding box on screen: x {box[:, 0].min():+.3f} .. {box[:, 0].max():+.3f}, "
        f"y {box[:, 1].min():+.3f} .. {box[:, 1].max():+.3f}; inside the frame {in_frame}"
    )
    return ok and finite and in_frame and gap <= 1e-9 * diag


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="validate the written scenes and print stats")
    args = parser.parse_args(argv)
    for filename, build in SCENES.items():
        (HERE / filename).write_text(to_toml(build(), filename), encoding="utf-8")
    if args.check:
        results = [check(HERE / filename) for filename in SCENES]
        return 0 if all(results) else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

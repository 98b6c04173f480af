"""Surfaces from the objects Python users already hold: Splipy and geomdl.

Duck-typed: neither library is imported here; an object is recognised by
its attributes. Each library's conventions, checked against its own
evaluator in tests/test_api.py:

- Splipy (``splipy.Surface``): ``order(d)`` is degree + 1;
  ``knots(d, with_multiplicities=True)`` the full knot vector;
  ``controlpoints`` (n1, n2, dim [+ 1]) indexed [i along u, j along v]; a
  rational object stores (w x, w y, w z, w), weight last. A periodic basis
  (``bases[d].periodic = k >= 0``) keeps n functions but a knot vector of a
  basis with n + k + 1: its last k + 1 functions are its first ones again,
  so the control points are repeated to make an ordinary B-spline. A
  ``TrimmedSurface`` brings its ``boundaries`` (loops of 2-D curves) as
  trims.
- geomdl / NURBS-Python (``BSpline.Surface``, ``NURBS.Surface``):
  ``degree_u``, ``degree_v``, ``knotvector_u``, ``knotvector_v``,
  ``ctrlpts_size_u``, ``ctrlpts_size_v``; the flat control point list runs
  with v fastest (index i * nv + j); a rational surface's ``ctrlptsw`` are
  (w x, w y, w z, w). geomdl trim curves are not converted (an error, not
  a silent drop): give ``trims=`` instead.

2-D control points get z = 0.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .errors import InputError


def from_splipy(surface, **kwargs):
    """A :class:`bsrt.Surface` from a Splipy ``Surface`` or ``TrimmedSurface``.

    kwargs: the other Surface fields (material, color, name, transform,
    trims to replace a TrimmedSurface's loops).
    """
    from .api import Surface

    if not (hasattr(surface, "bases") and hasattr(surface, "controlpoints")):
        raise TypeError(f"expected a Splipy Surface (with bases and controlpoints), got {type(surface).__name__}")
    bases = list(surface.bases)
    cps = np.array(surface.controlpoints, dtype=np.float64)
    if len(bases) != 2 or cps.ndim != 3:
        raise InputError(f"splipy: expected a surface (2 parameter directions), got {len(bases)}")
    cps = _unroll_periodic(cps, [getattr(b, "periodic", -1) for b in bases])
    points, weights = _split(cps, bool(surface.rational), "splipy")
    degree = tuple(int(b.order) - 1 for b in bases)
    knots = [np.array(b.knots, dtype=np.float64) for b in bases]
    if "trims" not in kwargs and getattr(surface, "boundaries", None):
        kwargs["trims"] = [[_splipy_curve(c) for c in loop] for loop in surface.boundaries]
    return Surface(degree=degree, knots_u=knots[0], knots_v=knots[1], points=points, weights=weights, **kwargs)


def from_geomdl(surface, **kwargs):
    """A :class:`bsrt.Surface` from a geomdl ``BSpline.Surface`` or ``NURBS.Surface``.

    kwargs: the other Surface fields (material, color, name, transform, trims).
    """
    from .api import Surface

    needed = ("degree_u", "degree_v", "knotvector_u", "knotvector_v", "ctrlpts_size_u", "ctrlpts_size_v")
    if not all(hasattr(surface, k) for k in needed):
        raise TypeError(f"expected a geomdl BSpline.Surface or NURBS.Surface, got {type(surface).__name__}")
    if getattr(surface, "trims", None) and "trims" not in kwargs:
        raise InputError("geomdl: the surface has trim curves, which bsrt does not convert "
                         "(their sense follows geomdl's own rules); pass trims=[...] (loops of curves) instead")
    nu, nv = int(surface.ctrlpts_size_u), int(surface.ctrlpts_size_v)
    rational = bool(getattr(surface, "rational", False))
    flat = np.array(surface.ctrlptsw if rational else surface.ctrlpts, dtype=np.float64)
    if flat.ndim != 2 or flat.shape[0] != nu * nv:
        raise InputError(f"geomdl: expected {nu} x {nv} control points, got an array of shape {flat.shape}")
    points, weights = _split(flat.reshape(nu, nv, -1), rational, "geomdl")
    return Surface(
        degree=(int(surface.degree_u), int(surface.degree_v)),
        knots_u=np.array(surface.knotvector_u, dtype=np.float64),
        knots_v=np.array(surface.knotvector_v, dtype=np.float64),
        points=points,
        weights=weights,
        **kwargs,
    )


def surface_from_object(obj, **kwargs):
    """:meth:`bsrt.Surface.from_object`: dispatch on what ``obj`` looks like."""
    from .api import Surface
    from .bspline import BSplineSurface
    from .scene import SceneSurface

    if isinstance(obj, Surface):
        return replace(obj, **kwargs)
    if isinstance(obj, SceneSurface):
        kwargs.setdefault("name", obj.name)
        obj = obj.geometry
    if isinstance(obj, BSplineSurface):
        kwargs.setdefault("trims", obj.trims)
        return Surface(degree=obj.degree, knots_u=obj.knots_u, knots_v=obj.knots_v, points=obj.points,
                       weights=obj.weights, **kwargs)
    if hasattr(obj, "bases") and hasattr(obj, "controlpoints"):
        return from_splipy(obj, **kwargs)
    if hasattr(obj, "degree_u") and hasattr(obj, "knotvector_u"):
        return from_geomdl(obj, **kwargs)
    raise TypeError(f"cannot make a bsrt.Surface from {type(obj).__name__}: expected a Splipy Surface, a geomdl "
                    f"Surface, a bsrt BSplineSurface or SceneSurface")


def _split(cps: np.ndarray, rational: bool, source: str):
    """(..., dim [+ 1]) control points -> points (..., 3) and weights (...) or None."""
    if rational:
        weights = cps[..., -1]
        if not np.all(weights > 0):
            raise InputError(f"{source}: every weight must be > 0")
        cps = cps[..., :-1] / weights[..., None]
    else:
        weights = None
    dim = cps.shape[-1]
    if dim not in (2, 3):
        raise InputError(f"{source}: expected 2-D or 3-D control points, got {dim}-D")
    if dim == 2:
        cps = np.concatenate([cps, np.zeros(cps.shape[:-1] + (1,))], axis=-1)
    return cps, weights


def _unroll_periodic(cps: np.ndarray, periodic) -> np.ndarray:
    """Repeat the first k + 1 control points at the end of each periodic direction."""
    for axis, k in enumerate(periodic):
        if k is not None and k >= 0:
            cps = np.concatenate([cps, np.take(cps, range(k + 1), axis=axis)], axis=axis)
    return cps


def _splipy_curve(curve) -> dict:
    """A Splipy 2-D curve as a trim curve {degree, knots, points, weights}."""
    basis = curve.bases[0]
    cps = _unroll_periodic(np.array(curve.controlpoints, dtype=np.float64), [getattr(basis, "periodic", -1)])
    if curve.rational:
        weights = cps[:, -1]
        points = cps[:, :-1] / weights[:, None]
    else:
        weights, points = None, cps
    return {"degree": int(basis.order) - 1, "knots": np.array(basis.knots, dtype=np.float64), "points": points,
            "weights": weights}

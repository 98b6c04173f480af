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

2-D control points get z = 0. Each function returns the fields of a
:class:`bsrt.Surface` as a dict (degree, knots_u, knots_v, points, weights,
and trims where the object has them); :mod:`bsrt.api` builds the Surface.
"""

from __future__ import annotations

import numpy as np

from bsrt.errors import InputError


def splipy_fields(surface) -> dict:
    """The Surface fields of a Splipy ``Surface`` or ``TrimmedSurface`` (with its loops as trims)."""
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
    fields = dict(degree=degree, knots_u=knots[0], knots_v=knots[1], points=points, weights=weights)
    if getattr(surface, "boundaries", None):
        fields["trims"] = [[_splipy_curve(c) for c in loop] for loop in surface.boundaries]
    return fields


def geomdl_fields(surface, trims_given: bool = False) -> dict:
    """The Surface fields of a geomdl ``BSpline.Surface`` or ``NURBS.Surface``. Its own trim curves are
    refused unless ``trims_given`` (the caller passes trims of its own)."""
    needed = ("degree_u", "degree_v", "knotvector_u", "knotvector_v", "ctrlpts_size_u", "ctrlpts_size_v")
    if not all(hasattr(surface, k) for k in needed):
        raise TypeError(f"expected a geomdl BSpline.Surface or NURBS.Surface, got {type(surface).__name__}")
    if getattr(surface, "trims", None) and not trims_given:
        raise InputError(
            "geomdl: the surface has trim curves, which bsrt does not convert "
            "(their sense follows geomdl's own rules); pass trims=[...] (loops of curves) instead"
        )
    nu, nv = int(surface.ctrlpts_size_u), int(surface.ctrlpts_size_v)
    rational = bool(getattr(surface, "rational", False))
    flat = np.array(surface.ctrlptsw if rational else surface.ctrlpts, dtype=np.float64)
    if flat.ndim != 2 or flat.shape[0] != nu * nv:
        raise InputError(f"geomdl: expected {nu} x {nv} control points, got an array of shape {flat.shape}")
    points, weights = _split(flat.reshape(nu, nv, -1), rational, "geomdl")
    return dict(
        degree=(int(surface.degree_u), int(surface.degree_v)),
        knots_u=np.array(surface.knotvector_u, dtype=np.float64),
        knots_v=np.array(surface.knotvector_v, dtype=np.float64),
        points=points,
        weights=weights,
    )


def object_fields(obj, trims_given: bool = False) -> dict:
    """The Surface fields of what ``obj`` looks like: a bsrt BSplineSurface or SceneSurface (its name
    too), a Splipy or a geomdl surface; a TypeError for anything else."""
    from bsrt.geometry.bspline import BSplineSurface
    from bsrt.scene import SceneSurface

    if isinstance(obj, SceneSurface):
        return {"name": obj.name, **object_fields(obj.geometry)}
    if isinstance(obj, BSplineSurface):
        return dict(
            degree=obj.degree,
            knots_u=obj.knots_u,
            knots_v=obj.knots_v,
            points=obj.points,
            weights=obj.weights,
            trims=obj.trims,
        )
    if hasattr(obj, "bases") and hasattr(obj, "controlpoints"):
        return splipy_fields(obj)
    if hasattr(obj, "degree_u") and hasattr(obj, "knotvector_u"):
        return geomdl_fields(obj, trims_given)
    raise TypeError(
        f"cannot make a bsrt.Surface from {type(obj).__name__}: expected a Splipy Surface, a geomdl "
        f"Surface, a bsrt BSplineSurface or SceneSurface"
    )


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
    return {
        "degree": int(basis.order) - 1,
        "knots": np.array(basis.knots, dtype=np.float64),
        "points": points,
        "weights": weights,
    }

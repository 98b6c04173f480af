"""Per-ray root finding on the patch table, all rays at once (paper 2.2, 2.3).

A ray o + t d meets S(u, v) where S - o is parallel to d. With e1, e2 an
orthonormal pair perpendicular to d, the rotation with rows (e1, e2, d) moves
the ray onto the z axis, and a hit solves

    Qx(u, v) = e1 . (S(u, v) - o) = 0,   Qy(u, v) = e2 . (S(u, v) - o) = 0.

We apply that rotation to the evaluated point rather than to the control
points (the paper's wording): it is the same Qx, Qy, but costs two dot
products per ray instead of transforming every control point per ray. Then
sqrt(Qx^2 + Qy^2) is exactly the distance between the ray and S(u, v), which
is what the convergence tolerance bounds, and t = d . (S - o).

Three methods share one active-set loop (converged rays leave the arrays;
the rest stay sorted by patch so evaluation is a run of small BLAS products):

- ``newton``: Newton on (Qx, Qy), with a Levenberg-Marquardt term of 1e-12 of
  the Jacobian's scale so a singular Jacobian gives a finite step.
- ``gradient`` (paper eq. 7-9): u -= h dw/du, v -= h dw/dv on w = Qx^2 + Qy^2.
  Step-size rule: h is the exact minimiser of the Gauss-Newton model of w
  along the gradient (the Cauchy step), h = |g|^2 / (2 |J g|^2); when w does
  not decrease, the step is rejected and h halved.
- ``fast`` (paper 2.3): as ``gradient``, but after an accepted step the same
  gradient and h are reused, evaluating S only (no derivatives), while w keeps
  decreasing; the gradient is recomputed when it stops decreasing.

Parameters are clipped to the surface's domain after every step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .patches import PatchSet

METHODS = ("gradient", "fast", "newton")  # the map-seeded ones; scene.METHODS adds "martin"


def orthonormal_frames(directions: np.ndarray):
    """Two unit vectors perpendicular to each unit direction and to each other.

    directions: (N, 3) float64, unit length. Returns e1, e2, each (3, N)
    (component-major, like PatchSet.evaluate). Branch-free construction of
    Duff et al. 2017 ("Building an orthonormal basis, revisited").
    """
    x, y, z = directions[:, 0], directions[:, 1], directions[:, 2]
    sign = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    e1 = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x])
    e2 = np.stack([b, sign + y * y * a, -y])
    return e1, e2


@dataclass
class Rays:
    """A batch of N rays, component-major.

    origin, direction: (3, N) float64, direction of unit length.
    e1, e2: (3, N) float64, see orthonormal_frames.
    """

    origin: np.ndarray
    direction: np.ndarray
    e1: np.ndarray
    e2: np.ndarray

    @classmethod
    def from_arrays(cls, origins: np.ndarray, directions: np.ndarray) -> "Rays":
        """origins, directions: (N, 3) float64 (directions are normalised here)."""
        d = directions / np.linalg.norm(directions, axis=1, keepdims=True)
        e1, e2 = orthonormal_frames(d)
        o = np.ascontiguousarray(np.broadcast_to(origins, d.shape).T)
        return cls(o, np.ascontiguousarray(d.T), e1, e2)

    def __len__(self) -> int:
        return self.direction.shape[1]


@dataclass
class RootResult:
    """Outcome for M (ray, start) items.

    converged: (M,) bool, the ray-surface distance fell under the tolerance.
    u, v: (M,) float64 final parameters (inside the surface's domain).
    patch: (M,) int64 patch of the final (u, v).
    t: (M,) float64 distance along the ray of S(u, v).
    residual: (M,) float64 ray-surface distance at the final (u, v).
    iterations: (M,) int32 evaluations spent.
    """

    converged: np.ndarray
    u: np.ndarray
    v: np.ndarray
    patch: np.ndarray
    t: np.ndarray
    residual: np.ndarray
    iterations: np.ndarray


def find_roots(
    patches: PatchSet,
    rays: Rays,
    ray: np.ndarray,
    surface: np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    method: str = "newton",
    tolerance: float = 1e-9,
    max_iterations: int = 64,
    stop_on_growth: bool = False,
) -> RootResult:
    """Solve Qx = Qy = 0 for M items, each a ray and a starting (surface, u, v).

    ray: (M,) int index into ``rays`` (a ray may appear in several items);
    surface: (M,) int; u, v: (M,) float64 starting parameters.
    tolerance: absolute ray-surface distance (scene units) that counts as
    converged. stop_on_growth: give up on an item as soon as a Newton step
    increases the residual (Martin et al.'s rule, for starts that may be far).
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}")
    m = ray.shape[0]
    out = RootResult(
        converged=np.zeros(m, dtype=bool),
        u=np.array(u, dtype=np.float64),
        v=np.array(v, dtype=np.float64),
        patch=np.zeros(m, dtype=np.int64),
        t=np.full(m, np.nan),
        residual=np.full(m, np.nan),
        iterations=np.zeros(m, dtype=np.int32),
    )
    if m == 0:
        return out
    surface = np.asarray(surface, dtype=np.int64)
    uu, vv = patches.clamp(surface, out.u, out.v)
    patch = patches.locate(surface, uu, vv)
    order = np.argsort(patch, kind="stable")
    st = _State(patches, rays, order, ray[order], surface[order], uu[order], vv[order], patch[order])
    tol2 = tolerance * tolerance
    it = 0
    while st.idx.size:
        it += 1
        if method == "fast":
            with_derivs = st.fresh.copy()
            S, Su, Sv = _evaluate_mixed(patches, st)
        else:
            S, Su, Sv = patches.evaluate(st.patch, st.u, st.v)
        qx = _dot(st.e1, S) - st.c1
        qy = _dot(st.e2, S) - st.c2
        w = qx * qx + qy * qy
        done = w <= tol2
        if method == "newton":
            failed = ~done & (w > st.w) if stop_on_growth else np.zeros_like(done)
        else:
            # A rejected step: w did not decrease. Go back to the last
            # accepted point; gradient halves h, fast recomputes the gradient.
            worse = ~done & ~st.probe & (w >= st.w)
            failed = np.zeros_like(done)
            if np.any(worse):
                st.u[worse] -= st.step_u[worse]
                st.v[worse] -= st.step_v[worse]
                w = np.where(worse, st.w, w)
                if method == "gradient":
                    st.step_u[worse] *= 0.5
                    st.step_v[worse] *= 0.5
                else:
                    st.step_u[worse] = 0.0
                    st.step_v[worse] = 0.0
                    st.fresh[worse] = True
        if it > 1:  # clipped at the domain's border with nowhere to go
            stuck = ~done & (st.step_u == 0.0) & (st.step_v == 0.0)
            failed |= stuck & ~st.fresh if method == "fast" else stuck
        finished = done | failed | (it >= max_iterations)
        out.iterations[st.idx] = it
        if np.any(finished):
            f = np.flatnonzero(finished)
            ids = st.idx[f]
            out.converged[ids] = done[f]
            out.u[ids], out.v[ids], out.patch[ids] = st.u[f], st.v[f], st.patch[f]
            out.t[ids] = _dot(rays.direction[:, st.ray[f]], S[:, f] - rays.origin[:, st.ray[f]])
            out.residual[ids] = np.sqrt(w[f])
            keep = np.flatnonzero(~finished)
            st = st.subset(keep)
            if not keep.size:
                break
            qx, qy, w, Su, Sv = qx[keep], qy[keep], w[keep], Su[:, keep], Sv[:, keep]
            if method != "newton":
                worse = worse[keep]
            if method == "fast":
                with_derivs = with_derivs[keep]
        a, b = _dot(st.e1, Su), _dot(st.e1, Sv)
        c, d = _dot(st.e2, Su), _dot(st.e2, Sv)
        if method == "newton":
            # (J^T J + mu I) delta = -J^T q, mu tiny: Newton unless J is singular.
            j00, j01, j11 = a * a + c * c, a * b + c * d, b * b + d * d
            mu = 1e-12 * (j00 + j11) + 1e-300
            g0, g1 = a * qx + c * qy, b * qx + d * qy
            det = (j00 + mu) * (j11 + mu) - j01 * j01
            st.step_u = ((j11 + mu) * g0 - j01 * g1) / -det
            st.step_v = ((j00 + mu) * g1 - j01 * g0) / -det
            st.w = w
        else:
            accepted = ~worse
            st.w = np.where(accepted, w, st.w)
            recompute = accepted if method == "gradient" else accepted & with_derivs
            st.probe = worse & (method == "fast")
            # Cauchy step on the Gauss-Newton model: h = |g|^2 / (2 |J g|^2).
            gu = 2.0 * (a * qx + c * qy)
            gv = 2.0 * (b * qx + d * qy)
            jg0, jg1 = a * gu + b * gv, c * gu + d * gv
            h = (gu * gu + gv * gv) / (2.0 * (jg0 * jg0 + jg1 * jg1) + 1e-300)
            st.step_u = np.where(recompute, -h * gu, st.step_u)
            st.step_v = np.where(recompute, -h * gv, st.step_v)
            st.fresh &= ~recompute
        st.advance(patches)
    return out


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Column-wise dot product of two (3, K) arrays -> (K,)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _evaluate_mixed(patches: PatchSet, st: "_State"):
    """S everywhere; S_u, S_v only where ``st.fresh`` (zeros elsewhere)."""
    n = st.idx.size
    S, Su, Sv = np.empty((3, n)), np.zeros((3, n)), np.zeros((3, n))
    r, k = np.flatnonzero(st.fresh), np.flatnonzero(~st.fresh)
    S[:, k] = patches.evaluate(st.patch[k], st.u[k], st.v[k], derivatives=False)
    S[:, r], Su[:, r], Sv[:, r] = patches.evaluate(st.patch[r], st.u[r], st.v[r])
    return S, Su, Sv


class _State:
    """The active items of find_roots, every array (K,) or (3, K), in patch order.

    idx: position in the caller's arrays; ray, surface, u, v, patch; e1, e2
    (3, K) and c1 = e1 . o, c2 = e2 . o of the item's ray; step_u, step_v the
    last step; w the last accepted Qx^2 + Qy^2; fresh: derivatives are needed
    at the next point (fast); probe: the next point was evaluated before.
    """

    fields = ("idx", "ray", "surface", "u", "v", "patch", "e1", "e2", "c1", "c2",
              "step_u", "step_v", "w", "fresh", "probe")

    def __init__(self, patches, rays, idx, ray, surface, u, v, patch):
        k = idx.size
        self.idx, self.ray, self.surface, self.u, self.v, self.patch = idx, ray, surface, u, v, patch
        self.e1, self.e2 = rays.e1[:, ray], rays.e2[:, ray]
        o = rays.origin[:, ray]
        self.c1, self.c2 = _dot(self.e1, o), _dot(self.e2, o)
        self.step_u, self.step_v = np.zeros(k), np.zeros(k)
        self.w = np.full(k, np.inf)
        self.fresh = np.ones(k, dtype=bool)
        self.probe = np.zeros(k, dtype=bool)

    def subset(self, sel) -> "_State":
        new = _State.__new__(_State)
        for name in self.fields:
            value = getattr(self, name)
            setattr(new, name, value[:, sel] if value.ndim == 2 else value[sel])
        return new

    def advance(self, patches: PatchSet) -> None:
        """Take the step; items that leave their patch are clipped and relocated."""
        u, v = self.u + self.step_u, self.v + self.step_v
        b = patches.bounds[self.patch]
        out = np.flatnonzero((u < b[:, 0]) | (u > b[:, 1]) | (v < b[:, 2]) | (v > b[:, 3]))
        if out.size:
            u[out], v[out] = patches.clamp(self.surface[out], u[out], v[out])
            self.patch[out] = patches.locate(self.surface[out], u[out], v[out])
        self.step_u, self.step_v = u - self.u, v - self.v
        self.u, self.v = u, v
        if out.size and np.any(self.patch[1:] < self.patch[:-1]):
            order = np.argsort(self.patch, kind="stable")
            for name in self.fields:
                value = getattr(self, name)
                setattr(self, name, value[:, order] if value.ndim == 2 else value[order])

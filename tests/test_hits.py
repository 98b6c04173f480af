"""hits.keep_nearest, the one "nearest wins" rule, against a plain loop over the candidates."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bsrt.rendering.hits import Hits, keep_nearest


def _records(rng, n: int, hit_rate: float, t_choices: np.ndarray) -> Hits:
    """n records, hits where a draw is below hit_rate, t from t_choices (few values: ties)."""
    hit = rng.random(n) < hit_rate
    t = np.where(hit, rng.choice(t_choices, n), np.nan)
    ident = np.arange(n)
    return Hits(
        hit=hit,
        t=t,
        surface=np.where(hit, ident % 7, -1),
        patch=np.where(hit, ident, -1),
        u=np.where(hit, ident * 0.5, np.nan),
        v=np.where(hit, ident * 0.25, np.nan),
        iterations=np.zeros(n, dtype=np.int32),
        residual=np.where(hit, ident * 1e-12, np.nan),
    )


def _by_loop(hits: Hits, ray: np.ndarray, candidates: Hits) -> tuple[Hits, set]:
    """keep_nearest's rule, one candidate at a time in their order: a hit replaces the ray's record
    when the ray has none or the candidate is strictly nearer (the first of equal ones stays)."""
    out = hits.take(slice(None))
    out = Hits(*(getattr(out, f).copy() for f in Hits.FIELDS))
    changed = set()
    for k in range(len(candidates)):
        r = ray[k]
        if candidates.hit[k] and (not out.hit[r] or candidates.t[k] < out.t[r]):
            for f in ("hit", "t", "surface", "patch", "u", "v", "residual"):
                getattr(out, f)[r] = getattr(candidates, f)[k]
            changed.add(int(r))
    return out, changed


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    rays=st.integers(1, 30),
    per_ray=st.integers(0, 5),
    grouped=st.booleans(),
)
def test_keep_nearest_keeps_the_first_nearest_candidate_of_each_ray(seed, rays, per_ray, grouped):
    """Candidates grouped by ray (as the repair passes them: no sort) or shuffled, with ties in t
    among them and with the rays' own records: the same records as the loop, and the rays whose
    record changed."""
    rng = np.random.default_rng(seed)
    hits = _records(rng, rays, 0.5, np.array([1.0, 2.0, 3.0]))
    k = rays * per_ray
    ray = np.sort(rng.integers(0, rays, k)) if grouped else rng.integers(0, rays, k)
    candidates = _records(rng, k, 0.7, np.array([1.0, 1.5, 2.0, 3.0]))
    expected, changed = _by_loop(hits, ray, candidates)
    got = keep_nearest(hits, ray, candidates)
    assert set(got.tolist()) == changed and got.size == len(changed)
    for f in Hits.FIELDS:
        np.testing.assert_array_equal(getattr(hits, f), getattr(expected, f), err_msg=f)

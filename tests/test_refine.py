"""The preview's refinement state machine (bsrt/preview/refine.py), with no
window, no GL and no solver: the clock is passed in."""

from __future__ import annotations

import numpy as np

from bsrt.preview.refine import LEVELS, Refinement, level_size, map_bands

FB = (800, 600)


def _pixels(level, r):
    w, h = r.size(level, FB)
    return np.full((h, w, 3), level, dtype=np.uint8)


def _run_level(r, now):
    """Ask for the next level and submit it (no map bands: "martin")."""
    level = r.next_level(now)
    if level is not None:
        r.submitted()
    return level


def test_levels_coarse_to_fine_after_the_camera_settles():
    r = Refinement(levels=(4, 2, 1), settle=0.15)
    r.restart(now=10.0)
    assert r.next_level(10.1) is None  # still moving
    assert r.state(10.1) == "moving"
    assert [_run_level(r, t) for t in (10.2, 10.21, 10.22, 10.23)] == [0, 1, 2, None]
    assert [r.size(k, FB) for k in range(3)] == [(200, 150), (400, 300), (800, 600)]
    assert r.state(10.3) == "refining"
    # a held mouse button counts as moving however long it is held
    assert r.moving(100.0, held=True)


def test_level_size_rounds_up():
    assert level_size((801, 601), 4) == (201, 151)
    assert level_size((3, 2), 4) == (1, 1)


def test_results_shown_in_order_and_completion_reported():
    r = Refinement(levels=(4, 2, 1))
    g = r.restart(now=0.0, settle=False)
    for _ in range(3):
        r.submitted()
    assert r.accept(g, 1, _pixels(1, r), seconds=0.5) == "shown"
    assert r.progress_text() == "refining 2/3 (1/2 shown)"
    assert r.accept(g, 0, _pixels(0, r)) == "older"  # a coarser level after a finer one is not shown
    assert r.shown == 1 and r.solve_seconds == 0.5
    assert not r.complete and r.state(1.0) == "refining"
    exact = _pixels(2, r)
    assert r.accept(g, 2, exact) == "exact"
    assert r.complete and r.exact is exact and r.state(1.0) == "exact"


def test_a_result_for_a_stale_camera_is_dropped():
    r = Refinement(levels=(4, 1))
    old = r.restart(now=0.0, settle=False)
    r.submitted()
    new = r.restart(now=1.0)  # the camera moved
    assert new == old + 1
    assert r.accept(old, 1, _pixels(1, r)) == "stale"
    assert r.accept(old, 0, None, error="newton failed") == "stale"
    assert not r.complete and r.shown == -1 and r.failed is None


def test_a_camera_move_restarts_at_the_coarsest_level():
    r = Refinement(levels=(4, 2, 1), settle=0.15)
    g = r.restart(now=0.0)
    assert [_run_level(r, t) for t in (1.0, 1.0)] == [0, 1]
    assert r.accept(g, 0, _pixels(0, r)) == "shown"
    r.restart(now=2.0)  # moved while level 1 was being solved, level 2 not submitted yet
    assert r.shown == -1 and r.exact is None
    assert _run_level(r, 2.1) is None  # not settled yet
    assert [_run_level(r, t) for t in (2.2, 2.2, 2.2, 2.2)] == [0, 1, 2, None]


def test_cancelling_forgets_queued_map_bands_and_failures():
    r = Refinement(levels=(1,), band_pixels=100_000)
    r.restart(now=0.0, settle=False)
    rows, count = r.next_band(800, 600)
    assert (rows, count) == ((0, 120), 5)
    assert r.add_band("top band", count) is None
    assert r.next_band(800, 600)[0] == (120, 240)
    r.fail("map: out of memory")
    assert r.next_level(5.0) is None and r.state(5.0) == "failed"
    r.restart(now=1.0, settle=False)  # cancelled: a new generation starts clean
    assert r.failed is None and r.parts == []
    assert r.next_band(800, 600)[0] == (0, 120)
    assert r.next_level(1.0) == 0


def test_bands_top_to_bottom_then_stitched():
    from dataclasses import fields

    from bsrt.rendering.prelim import PrelimMap

    def part(first, stop):
        return PrelimMap(
            *(np.full((stop - first, 4) + ((3,) if f.name == "picture" else ()), first) for f in fields(PrelimMap))
        )

    r = Refinement(levels=(1,), band_pixels=10)
    r.restart(now=0.0, settle=False)
    got = None
    order = []
    while got is None:
        rows, count = r.next_band(4, 10)
        order.append(rows)
        got = r.add_band(part(*rows), count)
    assert order == map_bands(4, 10, 10) == [(0, 2), (2, 5), (5, 8), (8, 10)]
    assert got.surface[:, 0].tolist() == [0, 0, 2, 2, 2, 5, 5, 5, 8, 8]
    assert r.parts == []


def test_a_dead_solver_fails_every_later_generation():
    r = Refinement(levels=LEVELS)
    r.restart(now=0.0, settle=False)
    r.solver_died("the solver process died (exit code -9)")
    r.restart(now=1.0, settle=False)
    assert r.state(2.0) == "failed" and r.next_level(2.0) is None
    assert r.failed == "the solver process died (exit code -9)"


def test_default_levels_end_with_the_exact_image():
    assert LEVELS[-1] == 1 and list(LEVELS) == sorted(LEVELS, reverse=True)

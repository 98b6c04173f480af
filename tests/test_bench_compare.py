"""bench's Embree comparison and memory row, on the bundled plane (closed forms): a bilinear
2 x 2 square in y = 0 seen head-on from 4 units away. Speed is never asserted here."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import embreex  # noqa: F401  (the real library: the test extra installs it; never a skip)
import numpy as np
import pytest

from bsrt.errors import InputError
from bsrt.rendering import bench, bench_embree, bench_memory

QUAD = Path(__file__).resolve().parents[1] / "scenes" / "quad.toml"


@pytest.mark.gl
def test_embree_on_a_tessellated_plane_gives_the_exact_depths_to_float32():
    results = bench.run([str(QUAD)], ["newton"], size=64, repeat=1, log=lambda _: None, embree=(1, 3))
    rows = results["scenes"]["quad"]["embree"]
    assert list(rows) == ["1", "3"]
    for n, row in rows.items():
        assert row["triangles"] == 2 * int(n) ** 2  # one patch: n x n quads, two triangles each
        # a plane is its own tessellation: the same pixels hit (none at the square's border are
        # on a pixel centre), depths equal to float32's rounding of t ~ 4 (diagonal 2 sqrt 2)
        assert row["missed"] == 0 and row["extra"] == 0
        assert row["depth_error_max"] < 4.5 * 2.0**-23 * 4 / (2 * math.sqrt(2))
        assert row["trace_seconds"] > 0 and row["ratio"] > 0
    text = bench_embree.format_rows(results)
    assert "quad" in text and text.count("\n") == 3


def test_the_embree_comparison_is_off_with_no_embree():
    from bsrt.cli.commands import _embree_segments

    assert _embree_segments(False) == ()
    assert _embree_segments(None) == bench_embree.DEFAULT_SEGMENTS  # embreex is installed here
    assert _embree_segments(True) == bench_embree.DEFAULT_SEGMENTS


@pytest.mark.gl
def test_memory_rows_measure_two_new_processes():
    memory = bench_memory.per_pixel(lambda out: bench.render_argv(str(QUAD), out), bench.child_env(), sizes=(16, 128))
    peaks = memory["peak_mb"]
    assert set(peaks) == {"16", "128"} and 20 < peaks["16"] <= peaks["128"] < 4096
    assert math.isfinite(memory["bytes_per_pixel"])
    assert "bytes per added pixel" in bench_memory.format_row(memory)


def test_a_failing_child_is_one_input_error():
    with pytest.raises(InputError, match="failed"):
        bench_memory.peak_rss([sys.executable, "-c", "raise SystemExit(3)"], bench.child_env())


def test_a_childs_peak_does_not_count_the_memory_of_the_process_measuring_it():
    """Linux records, at a child's exec, the high-water mark of the address space it was started
    from: measured from this process directly, a child that allocates nothing would show this
    process's 400 MB (bench runs after Embree's scenes: 2.4 GB each)."""
    held = np.ones(400 * 2**20 // 8)  # 400 MB resident here
    small = bench_memory.peak_rss([sys.executable, "-c", "pass"], bench.child_env())
    big = bench_memory.peak_rss(
        [sys.executable, "-c", "import numpy as np; a = np.ones(2**28 // 8)"], bench.child_env()
    )
    assert held[-1] == 1.0
    assert small < 100 * 2**20
    assert 256 * 2**20 < big < 256 * 2**20 + small + 50 * 2**20  # its own 256 MB array

"""Signals at random moments of a render with an image and AOVs: one line,
exit 128 + signal, and the outputs all or nothing (SIGKILL: at most the
documented temporary name ``.bsrt-<pid>-<hex>.tmp``)."""

from __future__ import annotations

import os
import random
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.gl  # every test here needs it (tests/conftest.py checks)

ROOT = Path(__file__).resolve().parents[1]
COMMAND = [
    sys.executable,
    "-m",
    "bsrt",
    "render",
    str(ROOT / "scenes" / "column.toml"),
    "-o",
    "out.png",
    "--aov",
    "out.npz",
    "--width",
    "160",
    "--height",
    "160",
]
TEMPORARY = re.compile(r"\.bsrt-\d+-[0-9a-f]{8}\.tmp")
RENDERS = 20


def _seconds_uninterrupted(command: list[str], folder: Path) -> float:
    """How long one uninterrupted run of ``command`` takes here (the caches warmed first), so that
    the signals' random moments fall within a run however fast this machine is."""
    subprocess.run(command, cwd=folder, check=True, capture_output=True, timeout=600)  # warm the caches
    seconds = []
    for _ in range(2):  # the shorter: a moment of load while timing must not put the signals after the runs
        clock = time.perf_counter()
        subprocess.run(command, cwd=folder, check=True, capture_output=True, timeout=600)
        seconds.append(time.perf_counter() - clock)
    return min(seconds)


@pytest.fixture(scope="module")
def whole_run_seconds(tmp_path_factory):
    """How long one uninterrupted render takes here (kernels already compiled by then)."""
    return _seconds_uninterrupted(COMMAND, tmp_path_factory.mktemp("whole"))


# Python reaches bsrt's first line (which installs the handlers) 25-30 ms after it starts here;
# a signal before that takes its default action. Allowed this early only, on a slow machine.
BEFORE_THE_HANDLERS = 0.15


def _before_the_handlers(code: int, err: str, left: list, signum: int, delay: float) -> bool:
    """The process was ended by the signal itself, before bsrt ran: nothing said, nothing left."""
    if code != -signum:
        return False
    assert delay < BEFORE_THE_HANDLERS and err == "" and left == [], f"{signum.name} after {delay:.3f} s: {err!r}"
    return True


def _moments(rng: random.Random, count: int, whole: float) -> list[float]:
    """count random moments over a run of ``whole`` seconds and a little past it, one in each of count
    equal strata of [0.05, 1.05 whole], in a shuffled order: every part of the run is covered
    whatever the seed (drawn uniformly, the 5 moments of one seed fell twice in the first 70 ms and
    twice past the end, and a run as fast as the timing left none inside it)."""
    edges = [0.05 + (whole * 1.05 - 0.05) * k / count for k in range(count + 1)]
    moments = [rng.uniform(lo, hi) for lo, hi in zip(edges[:-1], edges[1:])]
    rng.shuffle(moments)
    return moments


def _run_and_signal(folder: Path, signum: int, delay: float):
    proc = subprocess.Popen(COMMAND, cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=600)
    return proc.returncode, err, sorted(os.listdir(folder))


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP])
def test_a_signal_at_any_moment_leaves_all_outputs_or_none(tmp_path, whole_run_seconds, signum):
    rng = random.Random(signum)
    interrupted = 0
    count = RENDERS if signum == signal.SIGTERM else RENDERS // 4
    for i, delay in enumerate(_moments(rng, count, whole_run_seconds)):
        folder = tmp_path / str(i)
        folder.mkdir()
        code, err, left = _run_and_signal(folder, signum, delay)
        where = f"signal {signum.name} after {delay:.3f} s"
        if code == 0:  # the render was over before the signal came
            assert left == ["out.npz", "out.png"], where
            continue
        if _before_the_handlers(code, err, left, signum, delay):
            continue
        interrupted += 1
        assert code == 128 + signum, f"{where}: exit {code}, {err!r}"
        assert err.splitlines() == [f"bsrt: interrupted ({signum.name})"], where
        assert left == [], f"{where}: left {left}"  # a signal after the commit ends the run as finished
    assert interrupted >= 2  # on a loaded machine more runs finish before their signal


def test_sigkill_at_any_moment_leaves_no_lone_output(tmp_path, whole_run_seconds):
    rng = random.Random(9)
    for i, delay in enumerate(_moments(rng, RENDERS, whole_run_seconds)):
        folder = tmp_path / str(i)
        folder.mkdir()
        code, err, left = _run_and_signal(folder, signal.SIGKILL, delay)
        outputs = [name for name in left if not TEMPORARY.fullmatch(name)]
        assert outputs in ([], ["out.npz", "out.png"]), f"SIGKILL after {delay:.3f} s: left {left}"
        assert len(left) - len(outputs) <= 2


def test_a_signal_during_bsrt_map_leaves_the_map_or_nothing(tmp_path):
    """bsrt map writes through the same staged outputs and safe points as render."""
    command = [
        sys.executable,
        "-m",
        "bsrt",
        "map",
        str(ROOT / "scenes" / "water-lily.toml"),
        "-o",
        "map.png",
        "--width",
        "1024",
        "--height",
        "1024",
    ]
    whole = _seconds_uninterrupted(command, tmp_path)
    (tmp_path / "map.png").unlink()
    rng = random.Random(5)
    interrupted = 0
    for i, delay in enumerate(_moments(rng, 8, whole)):
        folder = tmp_path / str(i)
        folder.mkdir()
        proc = subprocess.Popen(command, cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(delay)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=600)
        left = sorted(os.listdir(folder))
        if proc.returncode == 0:
            assert left == ["map.png"]
            continue
        if _before_the_handlers(proc.returncode, err, left, signal.SIGTERM, delay):
            continue
        interrupted += 1
        assert proc.returncode == 143, f"after {delay:.3f} s: exit {proc.returncode}, {err!r}"
        assert err.splitlines() == ["bsrt: interrupted (SIGTERM)"] and left == [], f"after {delay:.3f} s: {left}"
    assert interrupted >= 2  # on a loaded machine more runs finish before their signal

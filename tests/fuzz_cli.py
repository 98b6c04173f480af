"""Fuzz `bsrt render` from the outside: mutate the bundled scenes and model
files, render each at 64 x 64 in a child process (timeout, address-space
limit, peak RSS from wait4) and check bsrt's promises on every case:

- the exit code is 0, 1 or 2, and 0 means a 64 x 64 PNG was written;
- a non-zero exit prints exactly one line on stderr besides "bsrt: warning:"
  lines, and that line starts with "bsrt: "; exit 2 (bad input) names the file;
- no "Traceback", no "internal error", no NumPy "Warning:" on stderr;
- nothing is left in the (otherwise empty) output folder after a failure;
- no case is killed by its timeout (a hang) or by a signal.

Usage: python tests/fuzz_cli.py --cases 2000 --seed 1 [--jobs 2]
[--timeout 120] [--memory-gb 8] [--keep DIR] [--time-budget SECONDS] [--json FILE]

Each case is reproducible from (seed, case number); broken cases are kept
(input file, stderr) under --keep. The summary (cases, exits by code,
tracebacks, internal errors, hangs, files left, max peak RSS, slowest case)
is printed at the end; the exit code is 1 if any promise was broken.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # this checkout's bsrt (dumps_toml), as the children use
MODEL_SUFFIXES = (".bez", ".bpt", ".g2", ".igs", ".iges", ".nurbs", ".obj")
SIZE = 64

# Runs in the child: set the address-space limit, then become the bsrt command.
_LAUNCH = (
    "import os, resource, sys; n = int(sys.argv[1]); resource.setrlimit(resource.RLIMIT_AS, (n, n)); "
    "os.execv(sys.executable, [sys.executable] + sys.argv[2:])"
)


def sources(root: Path = ROOT) -> list[Path]:
    """The bundled scenes and the model files of the test data (STEP left out: that is OpenCASCADE's reader)."""
    scenes = sorted((root / "scenes").glob("*.toml"))
    models = sorted(p for p in (root / "tests" / "data").rglob("*") if p.suffix.lower() in MODEL_SUFFIXES)
    return scenes + models


# ---------------------------------------------------------------------------
# Mutations: each takes (rng, bytes) and returns (bytes, description)

EXTREMES = [
    "1e308",
    "-1e308",
    "1e400",
    "-1e400",
    "5e-324",
    "1e-320",
    "0",
    "-0",
    "0.0",
    "-1",
    "99999999999999999999999999999",
    "-99999999999999999999999999999",
    "9223372036854775808",
    "nan",
    "inf",
    "-inf",
    "１",
    "٣",
    "1.7976931348623157e308",
    "1e15",
    "1e16",
    "2e-16",
    "true",
    "abc",
    "",
]
_NUMBER = re.compile(rb"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][+-]?\d+)?")


def byte_flips(rng, data):
    data = bytearray(data)
    n = rng.randint(1, 8)
    for _ in range(n):
        if data:
            i = rng.randrange(len(data))
            data[i] ^= 1 << rng.randrange(8)
    return bytes(data), f"flip {n} bits"


def truncation(rng, data):
    cut = rng.randrange(len(data) + 1) if data else 0
    return data[:cut], f"truncate at byte {cut} of {len(data)}"


def line_deletion(rng, data):
    lines = data.split(b"\n")
    k = rng.randrange(len(lines))
    n = rng.randint(1, 5)
    return b"\n".join(lines[:k] + lines[k + n :]), f"delete lines {k + 1}..{k + n}"


def line_duplication(rng, data):
    lines = data.split(b"\n")
    k = rng.randrange(len(lines))
    n = rng.randint(1, 3)
    return b"\n".join(lines[: k + 1] + [lines[k]] * n + lines[k + 1 :]), f"repeat line {k + 1} {n} times"


def huge_numbers(rng, data):
    spans = [m.span() for m in _NUMBER.finditer(data)]
    if not spans:
        return byte_flips(rng, data)
    picks = sorted(rng.sample(spans, min(len(spans), rng.choice([1, 1, 2, 5]))), reverse=True)
    out, done = bytearray(data), []
    for a, b in picks:
        value = rng.choice(EXTREMES)
        out[a:b] = value.encode()
        done.append(value)
    return bytes(out), f"numbers -> {', '.join(repr(v) for v in done)}"


def bom(rng, data):
    return b"\xef\xbb\xbf" + data, "byte-order mark added"


TEXT_MUTATIONS = [byte_flips, truncation, line_deletion, line_duplication, huge_numbers, huge_numbers, bom]


def _nodes(value, path=()):
    """(path, value) of every node below the document's top (keys and list indices)."""
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, child in items:
        yield path + (key,), child
        yield from _nodes(child, path + (key,))


def _swap_value(rng):
    return rng.choice(
        [
            True,
            False,
            "x",
            "１",
            "",
            0,
            -1,
            1,
            10**30,
            -(10**30),
            2**63,
            1e308,
            -1e308,
            5e-324,
            float("nan"),
            float("inf"),
            float("-inf"),
            1.5,
            [],
            [1, 2],
            [[True, "a"]],
            {},
            {"a": 1},
            "1e3",
            [0.0] * rng.choice([1, 3, 4, 1000]),
            _nested(rng.choice([5, 60, 900, 50_000])),
        ]
    )


def _nested(depth):
    """A placeholder that _toml_text writes as ``depth`` nested arrays (no recursion here)."""
    return f"__NESTED_{depth}__"


def toml_mutation(rng, data):
    """A type swap, deletion, duplication or scaling inside the parsed TOML document."""
    try:
        doc = tomllib.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError):
        return huge_numbers(rng, data)
    nodes = list(_nodes(doc))
    path, value = rng.choice(nodes)
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    kind = rng.choice(["swap", "swap", "delete", "duplicate", "scale"])
    if kind == "delete":
        del parent[path[-1]]
        what = "deleted"
    elif kind == "duplicate" and isinstance(parent, list):
        parent.insert(path[-1], value)
        what = "duplicated"
    elif kind == "scale" and isinstance(value, (int, float)) and not isinstance(value, bool):
        factor = 10.0 ** rng.randint(-330, 330)
        parent[path[-1]] = value * factor if value else factor
        what = f"scaled by {factor:g}"
    else:
        parent[path[-1]] = new = _swap_value(rng)
        what = f"-> {_short(new)}"
    return _toml_text(doc), f"TOML {'.'.join(map(str, path))} {what}"


def _short(value):
    text = repr(value)
    return text if len(text) < 40 else text[:37] + "..."


def _toml_text(doc: dict) -> bytes:
    from bsrt.api import dumps_toml

    flat = {k: v for k, v in doc.items() if not _is_table(v)}  # bare keys before the first table header
    flat.update({k: v for k, v in doc.items() if _is_table(v)})
    text = dumps_toml(flat)
    text = re.sub(r'"__NESTED_(\d+)__"', lambda m: "[" * int(m[1]) + "1.0" + "]" * int(m[1]), text)
    return text.encode("utf-8")


def _is_table(value) -> bool:
    return isinstance(value, dict) or (
        isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)
    )


def mutate(rng: random.Random, source: Path) -> tuple[bytes, str]:
    data = source.read_bytes()
    if source.suffix == ".toml" and rng.random() < 0.6:
        return toml_mutation(rng, data)
    return rng.choice(TEXT_MUTATIONS)(rng, data)


# ---------------------------------------------------------------------------
# Running one case


@dataclass
class Case:
    number: int
    source: str
    mutation: str
    code: int | None = None
    seconds: float = 0.0
    peak_mb: float = 0.0
    stderr: str = ""
    problems: list[str] = field(default_factory=list)


def run_case(number: int, seed: int, files: list[Path], work: Path, timeout: float, memory: int) -> Case:
    rng = random.Random(f"{seed}:{number}")
    source = rng.choice(files)
    data, mutation = mutate(rng, source)
    folder = work / f"case-{number}"
    out = folder / "out"
    out.mkdir(parents=True)
    target = folder / source.name
    target.write_bytes(data)
    case = Case(number, str(source.relative_to(ROOT)), mutation)
    env = dict(os.environ, PYTHONPATH=str(ROOT), BSRT_DEBUG="")
    command = [
        sys.executable,
        "-c",
        _LAUNCH,
        str(memory),
        "-m",
        "bsrt",
        "render",
        str(target),
        "-o",
        str(out / "image.png"),
        "--width",
        str(SIZE),
        "--height",
        str(SIZE),
        "--no-progress",
    ]
    err_path = folder / "stderr.txt"
    clock = time.perf_counter()
    with open(err_path, "wb") as err:
        child = subprocess.Popen(
            command, stdout=subprocess.DEVNULL, stderr=err, env=env, cwd=folder, start_new_session=True
        )
        fired = threading.Event()
        timer = threading.Timer(timeout, _kill, (child.pid, fired))
        timer.start()
        _, status, usage = os.wait4(child.pid, 0)
        timer.cancel()
        child.returncode = 0  # reaped here (wait4), not by Popen
    case.seconds = time.perf_counter() - clock
    case.peak_mb = usage.ru_maxrss / 1024.0
    case.code = os.waitstatus_to_exitcode(status)
    case.stderr = err_path.read_text("utf-8", "replace")
    case.problems = promises_broken(case, out, fired.is_set(), target.name)
    return case


def _kill(pid: int, fired: threading.Event) -> None:
    fired.set()
    try:
        os.killpg(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def promises_broken(case: Case, out: Path, timed_out: bool, name: str) -> list[str]:
    """The promises the case broke (empty: it kept them all); ``name``: the input file's name,
    which a bad-input message (exit 2) must contain."""
    problems = []
    lines = case.stderr.splitlines()
    messages = [line for line in lines if not line.startswith("bsrt: warning:")]
    left = sorted(p.name for p in out.iterdir())
    if timed_out:
        problems.append("hang")
    elif case.code not in (0, 1, 2):
        problems.append(f"exit code {case.code}")
    if "Traceback" in case.stderr:
        problems.append("traceback")
    if "internal error" in case.stderr:
        problems.append("internal error")
    if re.search(r"\w+Warning:", case.stderr):
        problems.append("Python warning on stderr")
    if case.code == 0:
        if left != ["image.png"] or not _is_png(out / "image.png"):
            problems.append(f"exit 0 without a {SIZE}x{SIZE} PNG (found {left})")
        if messages:
            problems.append("exit 0 with a non-warning stderr line")
    else:
        if len(messages) != 1 or not messages[0].startswith("bsrt: "):
            problems.append(f"{len(messages)} stderr lines")
        if left:
            problems.append(f"files left: {left}")
        if case.code == 2 and messages and name not in messages[-1]:
            problems.append("message does not name the file")
    return problems


def _is_png(path: Path) -> bool:
    head = path.read_bytes()[:24]
    return (
        head[:8] == b"\x89PNG\r\n\x1a\n"
        and int.from_bytes(head[16:20], "big") == SIZE
        and int.from_bytes(head[20:24], "big") == SIZE
    )


# ---------------------------------------------------------------------------
# The run and its summary


def run(
    cases: int,
    seed: int,
    jobs: int = 1,
    timeout: float = 120.0,
    memory_gb: float = 8.0,
    keep: Path | None = None,
    time_budget: float | None = None,
    log=print,
) -> dict:
    """Run the cases; returns the summary (see ``summary``). Broken cases are copied to ``keep``."""
    files = sources()
    memory = int(memory_gb * 2**30)
    started = time.perf_counter()
    done: list[Case] = []
    with tempfile.TemporaryDirectory(prefix="bsrt-fuzz-") as tmp:
        work = Path(tmp)

        def one(number):
            if time_budget is not None and time.perf_counter() - started > time_budget:
                return None
            case = run_case(number, seed, files, work, timeout, memory)
            if case.problems and keep is not None:
                keep.mkdir(parents=True, exist_ok=True)
                shutil.copytree(work / f"case-{number}", keep / f"case-{number}", dirs_exist_ok=True)
            shutil.rmtree(work / f"case-{number}", ignore_errors=True)
            if case.problems:
                log(
                    f"case {number}: {case.source}: {case.mutation}: {', '.join(case.problems)}: "
                    f"{case.stderr.strip()[-300:]!r}"
                )
            return case

        with ThreadPoolExecutor(max_workers=jobs) as pool:
            for case in pool.map(one, range(cases)):
                if case is not None:
                    done.append(case)
                    if len(done) % 100 == 0:
                        log(f"... {len(done)} cases, {time.perf_counter() - started:.0f} s")
    return summary(done, seed, time.perf_counter() - started)


def summary(cases: list[Case], seed: int, seconds: float) -> dict:
    def count(problem):
        return sum(any(p.startswith(problem) for p in c.problems) for c in cases)

    codes: dict[str, int] = {}
    for c in cases:
        codes[str(c.code)] = codes.get(str(c.code), 0) + 1
    biggest = max(cases, key=lambda c: c.peak_mb, default=None)
    slowest = max(cases, key=lambda c: c.seconds, default=None)
    broken = [c for c in cases if c.problems]
    return {
        "cases": len(cases),
        "seed": seed,
        "seconds": round(seconds, 1),
        "exits": dict(sorted(codes.items())),
        "tracebacks": count("traceback"),
        "internal_errors": count("internal error"),
        "hangs": count("hang"),
        "files_left": count("files left"),
        "stderr_not_one_line": count("stderr lines") + count("exit 0 with"),
        "python_warnings": count("Python warning"),
        "bad_exit_codes": count("exit code"),
        "exit0_without_image": count("exit 0 without"),
        "unnamed_file": count("message does not"),
        "max_peak_rss_mb": round(biggest.peak_mb, 1) if biggest else 0,
        "max_peak_rss_case": _label(biggest),
        "slowest_seconds": round(slowest.seconds, 2) if slowest else 0,
        "slowest_case": _label(slowest),
        "broken": [asdict(c) for c in broken],
    }


def _label(case: Case | None) -> str:
    return "" if case is None else f"{case.number}: {case.source}: {case.mutation}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=1, help="cases run at once (default 1)")
    parser.add_argument("--timeout", type=float, default=120.0, help="seconds per case before it counts as a hang")
    parser.add_argument("--memory-gb", type=float, default=8.0, help="address-space limit of each case (RLIMIT_AS)")
    parser.add_argument("--keep", type=Path, help="copy broken cases (input, stderr) into this folder")
    parser.add_argument("--time-budget", type=float, help="start no case after this many seconds")
    parser.add_argument("--json", type=Path, help="also write the summary as JSON")
    args = parser.parse_args(argv)
    result = run(args.cases, args.seed, args.jobs, args.timeout, args.memory_gb, args.keep, args.time_budget)
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))
    shown = {k: v for k, v in result.items() if k != "broken"}
    print(json.dumps(shown, indent=2))
    print(f"broken cases: {len(result['broken'])}")
    return 1 if result["broken"] else 0


if __name__ == "__main__":
    sys.exit(main())

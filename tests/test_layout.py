"""The layout's rules (docs/design.md, "Modules"), checked on the source: no import circles, a
lower floor never imports a higher one, every module under 500 lines. Imports inside functions count
(they run too); those under ``if TYPE_CHECKING:`` do not."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "bsrt"

# Floors from the bottom: a module may import its own floor's modules and any lower floor's.
# The top-level package (bsrt/__init__.py) is lazy: it names the API and imports nothing at import.
FLOORS = (
    ("errors", "interrupts", "files", "progress", "allocator"),
    ("kernels",),  # numba loops over flat arrays
    ("methods", "geometry"),
    ("validate",),
    ("settings", "outputs", "npz"),
    ("io",),  # the model readers
    ("scene",),
    ("adapters", "parts", "sensors"),
    ("rendering",),
    ("api",),
    ("queries", "batches", "preview", "doc_tables"),
    ("cli",),  # the only code that knows argv
    ("__main__",),
)
FLOOR = {name: level for level, names in enumerate(FLOORS) for name in names}
MAX_LINES = 499  # modules stay under 500 lines


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = ["bsrt", *path.relative_to(PACKAGE).with_suffix("").parts]
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The bsrt modules ``name`` imports anywhere but under ``if TYPE_CHECKING:``."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found = set()

    def walk(node):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                continue
            if isinstance(child, ast.ImportFrom):
                base = package[: len(package) - child.level + 1] if child.level else []
                target = ".".join(base + (child.module.split(".") if child.module else []))
                for alias in child.names:
                    for candidate in (f"{target}.{alias.name}", target):
                        if candidate in modules:
                            found.add(candidate)
                            break
            elif isinstance(child, ast.Import):
                found.update(a.name for a in child.names if a.name in modules)
            walk(child)

    walk(ast.parse(path.read_text()))
    found.discard(name)
    return found


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def _floor(module: str) -> int | None:
    parts = module.split(".")
    return FLOOR.get(parts[1]) if len(parts) > 1 else None  # None: the lazy top-level package


def test_every_module_has_a_floor():
    assert [m for m in _modules() if m != "bsrt" and _floor(m) is None] == []


def test_no_import_runs_up_the_floors():
    upward = [
        f"{a} -> {b}"
        for a, targets in _graph().items()
        for b in targets
        if _floor(a) is not None and _floor(b) is not None and _floor(b) > _floor(a)
    ]
    assert upward == []


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on_stack, circles, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return circles


def test_no_import_circles():
    assert _circles(_graph()) == []


def test_the_rules_catch_an_upward_import_and_a_circle(tmp_path, monkeypatch):
    """The checks can fail: a kernel importing the CLI, and two modules importing each other."""
    fake = tmp_path / "bsrt"
    (fake / "kernels").mkdir(parents=True)
    (fake / "cli").mkdir()
    (fake / "__init__.py").write_text("")
    (fake / "kernels" / "__init__.py").write_text("")
    (fake / "cli" / "__init__.py").write_text("")
    (fake / "kernels" / "a.py").write_text("def f():\n    from bsrt.cli import b\n")
    (fake / "cli" / "b.py").write_text("from bsrt.kernels import a\n")
    monkeypatch.setitem(globals(), "PACKAGE", fake)
    graph = _graph()
    assert graph["bsrt.kernels.a"] == {"bsrt.cli.b"}  # an import inside a function counts
    assert _floor("bsrt.cli.b") > _floor("bsrt.kernels.a")
    assert _circles(graph) == [["bsrt.cli.b", "bsrt.kernels.a"]]


def test_every_module_under_500_lines():
    long = {m: n for m, p in _modules().items() if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert long == {}

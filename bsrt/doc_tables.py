"""The documentation's tables, generated from the registries.

Each docs page holds its generated tables between
``<!-- BEGIN GENERATED: name -->`` and ``<!-- END GENERATED: name -->``;
``python -m bsrt.doc_tables docs/*.md`` rewrites them in place, and
tests/test_registries.py fails when a page is stale.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path


def _methods() -> str:
    from bsrt.methods import DEFAULT_METHOD, METHODS

    rows = ["| method | seeded by the map | what it does |", "|---|---|---|"]
    for m in METHODS.values():
        default = " (default)" if m.name == DEFAULT_METHOD else ""
        rows.append(f"| `{m.name}`{default} | {'yes' if m.seeded else 'no'} | {m.help} |")
    return "\n".join(rows)


def _settings() -> str:
    from bsrt.settings import markdown_table

    return markdown_table()


def _formats() -> str:
    from bsrt.io.formats import markdown_table

    return markdown_table()


TABLES = {"settings": _settings, "formats": _formats, "methods": _methods}
_BLOCK = re.compile(r"(<!-- BEGIN GENERATED: (\w+) -->\n)(.*?)(<!-- END GENERATED: \2 -->)", re.S)


def regenerate(text: str) -> str:
    """``text`` with every generated block replaced by its table's current text."""
    return _BLOCK.sub(lambda m: m.group(1) + TABLES[m.group(2)]() + "\n" + m.group(4), text)


def blocks(text: str) -> list[str]:
    """The names of the generated blocks in ``text``."""
    return [m.group(2) for m in _BLOCK.finditer(text)]


def main(paths: list[str]) -> int:
    for path in map(Path, paths):
        text = path.read_text(encoding="utf-8")
        new = regenerate(text)
        if new != text:
            path.write_text(new, encoding="utf-8")
            print(f"updated {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

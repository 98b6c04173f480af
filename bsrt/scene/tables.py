"""Typed access to one TOML table: every error names the file, the table and the key."""

from __future__ import annotations

import math

from bsrt import validate
from bsrt.errors import InputError


class _Table:
    """Typed access to one TOML table; every error names file, table and key."""

    def __init__(self, where: str, data, name: str):
        if not isinstance(data, dict):
            raise InputError(f"{where}: {name}: expected a table")
        self.where, self.data, self.name, self.used = where, data, name, set()

    def fail(self, key: str, message: str):
        raise InputError(f"{self.where}: {self.name}.{key}: {message}")

    def has(self, key: str) -> bool:
        return key in self.data

    def raw(self, key: str, default=None, required: bool = False):
        self.used.add(key)
        if key not in self.data:
            if required:
                self.fail(key, "missing (required)")
            return default
        return self.data[key]

    def number(
        self,
        key: str,
        default=None,
        lo=None,
        hi=None,
        lo_open=False,
        hi_open=False,
        required=False,
        limit=validate.MAX_COORDINATE,
    ):
        value = self.raw(key, default, required)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(key, f"expected a number, got {_show(value)}")
        value = float(value) if isinstance(value, float) or abs(value) < 1e300 else math.inf
        if not math.isfinite(value):
            self.fail(key, f"expected a finite number, got {_show(value)}")
        if lo is not None and (value < lo or (lo_open and value == lo)):
            self.fail(key, f"must be {'>' if lo_open else '>='} {lo:g}, got {value:g}")
        if hi is not None and (value > hi or (hi_open and value == hi)):
            self.fail(key, f"must be {'<' if hi_open else '<='} {hi:g}, got {value:g}")
        if limit is not None and abs(value) > limit:
            self.fail(key, f"must lie within +-{limit:g} (see Limits in docs/scene-format.md), got {value:g}")
        return value

    def integer(self, key: str, default=None, lo=None, required=False, hi=None):
        value = self.raw(key, default, required)
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(key, f"expected a whole number, got {_show(value)}")
        if lo is not None and value < lo:
            self.fail(key, f"must be >= {lo}, got {value}")
        if hi is not None and value > hi:
            self.fail(key, f"must be at most {hi} (see Limits in docs/scene-format.md), got {_show(value)}")
        return value

    def string(self, key: str, default=None, choices=None, required=False):
        value = self.raw(key, default, required)
        if value is None:
            return None
        if not isinstance(value, str):
            self.fail(key, f"expected a string, got {_show(value)}")
        if choices and value not in choices:
            self.fail(key, f"expected one of {', '.join(repr(c) for c in choices)}, got {value!r}")
        return value

    def vector(self, key: str, default=None, length=3, required=False, lo=None, limit=validate.MAX_COORDINATE):
        value = self.raw(key, default, required)
        if value is None:
            return None
        if (
            not isinstance(value, (list, tuple))
            or len(value) != length
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in value)
        ):
            self.fail(key, f"expected {length} numbers, got {_show(value)}")
        if not all(math.isfinite(x) for x in value):
            self.fail(key, "values must be finite numbers")
        if lo is not None and any(x < lo for x in value):
            self.fail(key, f"values must be >= {lo:g}")
        if limit is not None and any(abs(x) > limit for x in value):
            self.fail(key, f"values must lie within +-{limit:g} (see Limits in docs/scene-format.md)")
        return tuple(float(x) for x in value)

    def finish(self):
        unknown = [k for k in self.data if k not in self.used]
        if unknown:
            self.fail(unknown[0], "unknown key")


def _show(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."

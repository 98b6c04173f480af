"""Writing results: sRGB-encoded 8-bit PNG and AOV archives, atomically.

Files are written to a temporary name in the target folder and renamed into
place, so a failure never leaves a half-written output behind.
"""

from __future__ import annotations

import os
import secrets
from pathlib import Path

import numpy as np
from PIL import Image


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Linear RGB in [0, 1] (any shape) -> 8-bit sRGB (IEC 61966-2-1 curve), clipped."""
    c = np.clip(np.nan_to_num(linear, nan=0.0), 0.0, 1.0)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    return np.rint(s * 255.0).astype(np.uint8)


def _atomic_write(path: Path, write) -> None:
    path = Path(path)
    # Created with mode 0o666 less the umask, like any new file (mkstemp's 0o600 would stick).
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_png(path, pixels: np.ndarray) -> None:
    """pixels: (H, W, 3) uint8 -> PNG at path."""
    _atomic_write(path, lambda tmp: Image.fromarray(pixels, "RGB").save(tmp, format="PNG"))


def write_text(path, text: str) -> None:
    """UTF-8 text (e.g. JSON results) at path."""
    _atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def write_npz(path, arrays: dict) -> None:
    """Arrays -> compressed .npz at path (the name is kept exactly)."""

    def write(tmp):
        with open(tmp, "wb") as f:
            np.savez_compressed(f, **arrays)

    _atomic_write(path, write)

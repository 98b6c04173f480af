"""Writing results: sRGB-encoded 8-bit PNG and AOV archives, atomically.

Each file is written all or nothing (bsrt/outputs.py): a failure never
leaves a half-written output behind.
"""

from __future__ import annotations

import numpy as np
from PIL import Image

from bsrt.errors import InputError
from bsrt.outputs import write_file

#: extension -> (Pillow's format name, its options): what RenderResult.save writes
IMAGE_FORMATS = {
    ".png": ("PNG", {}),
    ".jpg": ("JPEG", {"quality": 95}),
    ".jpeg": ("JPEG", {"quality": 95}),
    ".webp": ("WEBP", {"lossless": True}),
}


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Linear RGB in [0, 1] (any shape) -> 8-bit sRGB (IEC 61966-2-1 curve), clipped."""
    c = np.clip(np.nan_to_num(linear, nan=0.0), 0.0, 1.0)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    return np.rint(s * 255.0).astype(np.uint8)


def png_writer(pixels: np.ndarray):
    """pixels: (H, W, 3) uint8 -> a function writing them as PNG to a binary file."""
    return lambda f: Image.fromarray(pixels, "RGB").save(f, format="PNG")


def npz_writer(arrays: dict):
    """Named arrays -> a function writing a compressed .npz to a binary file."""
    return lambda f: np.savez_compressed(f, **arrays)


def write_png(path, pixels: np.ndarray) -> None:
    """pixels: (H, W, 3) uint8 -> PNG at path, all or nothing."""
    write_file(path, png_writer(pixels))


def write_image(path, pixels: np.ndarray) -> None:
    """pixels: (H, W, 3) uint8 -> the format the extension of ``path`` names (IMAGE_FORMATS), all or
    nothing; an InputError for any other extension."""
    from pathlib import Path

    ext = Path(path).suffix.lower()
    if ext not in IMAGE_FORMATS:
        raise InputError(
            f"{path}: cannot tell the image format from {ext or 'no extension'!r}; use one of "
            f"{', '.join(IMAGE_FORMATS)}"
        )
    name, options = IMAGE_FORMATS[ext]
    write_file(path, lambda f: Image.fromarray(pixels, "RGB").save(f, format=name, **options))


def write_text(path, text: str) -> None:
    """UTF-8 text (e.g. JSON results) at path, all or nothing."""
    write_file(path, lambda f: f.write(text.encode("utf-8")))


def write_npz(path, arrays: dict) -> None:
    """Arrays -> compressed .npz at path (the name is kept exactly), all or nothing."""
    write_file(path, npz_writer(arrays))

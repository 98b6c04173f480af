"""Writing results: sRGB-encoded PNG (8 or 16 bits, RGB or RGBA), JPEG and WebP, atomically (the AOV
archives: bsrt/npz.py).

Each file is written all or nothing (bsrt/outputs.py): a failure never
leaves a half-written output behind.
"""

from __future__ import annotations

import numpy as np
from PIL import Image

from bsrt.errors import InputError
from bsrt.kernels.threads import run_chunks
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


def srgb_decode(pixels: np.ndarray) -> np.ndarray:
    """8-bit sRGB (any shape, uint8) -> linear RGB float64 in [0, 1] (the curve's inverse), looked
    up in the table of its 256 values."""
    return DECODED[pixels]


def _decode(levels: np.ndarray) -> np.ndarray:
    s = levels.astype(np.float64) / 255.0
    return np.where(s <= 0.04045, s / 12.92, np.power((s + 0.055) / 1.055, 2.4))


DECODED = _decode(np.arange(256, dtype=np.uint8))  # (256,) srgb_decode's values


def srgb_encode16(linear: np.ndarray) -> np.ndarray:
    """Linear RGB in [0, 1] (any shape) -> 16-bit sRGB, clipped."""
    c = np.clip(np.nan_to_num(linear, nan=0.0), 0.0, 1.0)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    return np.rint(s * 65535.0).astype(np.uint16)


ENCODE_ROWS = 16  # picture rows encoded at once at least (a task of run_chunks)


def encode_picture(linear: np.ndarray, coverage: np.ndarray, background, transparent: bool, bits: int) -> np.ndarray:
    """The picture to write. linear: (H, W, 3) float64, the pixels' mean colour (background
    samples included); coverage: (H, W) float64 in [0, 1], the fraction of samples that hit.

    Opaque: (H, W, 3) sRGB. Transparent: (H, W, 4), alpha = coverage, and the colour the
    surfaces alone give (straight alpha: linear = a * colour + (1 - a) * background, solved for
    colour; 0 where a = 0). uint8 for bits = 8, uint16 for 16. Encoded in bands of rows on every
    core (NumPy's loops release the GIL; a band's temporaries are small enough to be reused
    rather than mapped afresh: a 2048 x 2048 picture took 0.7-1.9 s of one core in one piece)."""
    h, w = linear.shape[:2]
    out = np.empty((h, w, 4 if transparent else 3), dtype=np.uint8 if bits == 8 else np.uint16)
    background = np.asarray(background, dtype=np.float64)
    run_chunks(_encode_rows, h, linear, coverage, background, transparent, bits, out, min_chunk=ENCODE_ROWS)
    return out


def _encode_rows(start, stop, linear, coverage, background, transparent, bits, out) -> None:
    """encode_picture's rows start..stop-1 into out."""
    encode = srgb_encode if bits == 8 else srgb_encode16
    if not transparent:
        out[start:stop] = encode(linear[start:stop])
        return
    a = coverage[start:stop, :, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        colour = np.where(a > 0, (linear[start:stop] - (1.0 - a) * background) / a, 0.0)
    scale = 255.0 if bits == 8 else 65535.0
    out[start:stop, :, :3] = encode(colour)
    out[start:stop, :, 3] = np.rint(np.clip(coverage[start:stop], 0.0, 1.0) * scale)


def png_writer(pixels: np.ndarray):
    """pixels: (H, W, 3|4) uint8 or uint16 -> a function writing them as PNG (RGB or RGBA,
    8 or 16 bits a channel) to a binary file."""
    if pixels.dtype == np.uint16:
        return lambda f: f.write(png16_bytes(pixels))
    return lambda f: Image.fromarray(pixels, "RGB" if pixels.shape[2] == 3 else "RGBA").save(f, format="PNG")


def png16_bytes(pixels: np.ndarray) -> bytes:
    """pixels: (H, W, 3|4) uint16 -> a 16-bit RGB or RGBA PNG file's bytes (Pillow writes
    16 bits only for grey pictures: the chunks are written here, PNG specification section 11)."""
    import struct
    import zlib

    h, w, channels = pixels.shape

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", w, h, 16, 2 if channels == 3 else 6, 0, 0, 0)
    rows = np.zeros((h, 1 + w * channels * 2), dtype=np.uint8)  # filter byte 0 (none), then big-endian samples
    rows[:, 1:] = pixels.astype(">u2").reshape(h, -1).view(np.uint8)
    srgb = chunk(b"sRGB", b"\x00")
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + srgb
        + chunk(b"IDAT", zlib.compress(rows.tobytes(), 6))
        + chunk(b"IEND", b"")
    )


def write_png(path, pixels: np.ndarray) -> None:
    """pixels: (H, W, 3) uint8 -> PNG at path, all or nothing."""
    write_file(path, png_writer(pixels))


def check_image_path(path, transparent: bool = False, bits: int = 8, label: str = "") -> str:
    """The image format (an IMAGE_FORMATS key) the extension of ``path`` names, checked against what
    the picture needs; else an InputError (label: how the caller names the setting, e.g. "--")."""
    from pathlib import Path

    ext = Path(path).suffix.lower()
    if ext not in IMAGE_FORMATS:
        raise InputError(
            f"{path}: cannot tell the image format from {ext or 'no extension'!r}; use one of "
            f"{', '.join(IMAGE_FORMATS)}"
        )
    key = lambda name: "--" + name.replace("_", "-") if label == "--" else label + name  # noqa: E731
    if transparent and IMAGE_FORMATS[ext][0] == "JPEG":
        raise InputError(f"{path}: {key('transparent')}: JPEG has no transparency; write .png or .webp")
    if bits != 8 and ext != ".png":
        raise InputError(f"{path}: {key('bit_depth')} {bits}: only PNG holds 16 bits a channel; write .png")
    return ext


def image_writer(path, pixels: np.ndarray):
    """pixels: (H, W, 3|4) uint8 (or uint16 for PNG) -> a function writing them, in the format
    the extension of ``path`` names, to a binary file (check_image_path first)."""
    ext = check_image_path(path, pixels.shape[2] == 4, 16 if pixels.dtype == np.uint16 else 8)
    if ext == ".png":
        return png_writer(pixels)
    name, options = IMAGE_FORMATS[ext]
    return lambda f: Image.fromarray(pixels, "RGB" if pixels.shape[2] == 3 else "RGBA").save(f, format=name, **options)


def write_image(path, pixels: np.ndarray) -> None:
    """pixels: (H, W, 3|4) uint8 (or uint16 for PNG) -> the format the extension of ``path`` names
    (IMAGE_FORMATS), all or nothing; an InputError for any other extension."""
    writer = image_writer(path, pixels)
    write_file(path, writer)


def write_text(path, text: str) -> None:
    """UTF-8 text (e.g. JSON results) at path, all or nothing."""
    write_file(path, lambda f: f.write(text.encode("utf-8")))

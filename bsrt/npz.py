"""Compressed ``.npz`` archives (what ``numpy.load`` reads), deflated on every core.

``numpy.savez_compressed`` and ``zipfile`` deflate a member in one thread, and
zlib deflates float64 arrays at about 70 MB/s (level 1, one core of this
project's machines): a 2048x2048 film's AOVs (373 MB) took 6 s of one core
after a 3.5 s render, a 4096x4096 film's (1.5 GB) most of a 55 s render on
16 cores. Here each member's bytes (its ``.npy`` header, then the array's)
are cut into pieces of PIECE bytes, and each piece is deflated on its own
on a thread pool (zlib releases the GIL): a raw deflate stream that ends
with a sync flush, or with the stream's end for the member's last piece.
Concatenated, the pieces make one valid deflate stream (no back-reference
crosses a piece; it costs well under 1 % in size). Each piece's CRC-32 is
taken with it and the member's is combined from them (crc32_combine). The
pieces are written in order as they come, at most WINDOW_PER_THREAD x
threads of them in flight (memory bounded whatever the arrays' size).

zipfile has no way to take data already deflated, so the archive's records
are written here, ZIP64 throughout as zipfile itself writes to a stream
(PKWARE's APPNOTE 6.3, sections 4.3 and 4.5.3): per member a local header
(sizes in its ZIP64 field, CRC and sizes in a data descriptor after the
data, bit 3), then the central directory, the ZIP64 end record and its
locator, the end record. The output depends only on the arrays (names
encoded as UTF-8, every time stamp 1980-01-01 00:00), not on the threads.

A waiting signal is taken (bsrt.interrupts.safe_point) while the writer
waits for a piece and before each member: the run ends within a piece's
time, the pieces not yet started are dropped and those running are waited
for (a fraction of a second).
"""

from __future__ import annotations

import functools
import struct
import zlib
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout

import numpy as np

from bsrt import interrupts
from bsrt.kernels.threads import POLL_SECONDS, workers

LEVEL = 1  # zlib level: 6 (numpy's) takes 1.5x as long for 2 % fewer bytes
PIECE = 1 << 22  # bytes deflated as one piece: 60 ms of one core
WINDOW_PER_THREAD = 2  # pieces in flight per thread

_LOCAL, _DESCRIPTOR, _CENTRAL = 0x04034B50, 0x08074B50, 0x02014B50
_END64, _LOCATOR64, _END = 0x06064B50, 0x07064B50, 0x06054B50
_VERSION = 45  # ZIP64
_DEFLATED = 8
_DATE = (0 << 9) | (1 << 5) | 1  # 1980-01-01 (MS-DOS date), time 00:00
_UTF8_NAME = 0x800
_MASK32, _MASK16 = 0xFFFFFFFF, 0xFFFF
_POLY = 0xEDB88320  # CRC-32's polynomial, bits reversed


def writer(arrays):
    """Named arrays (a mapping name -> array-like, read in order) -> a function writing them to a
    binary file as a compressed .npz: one ``NAME.npy`` member per array."""
    return lambda f: write(f, arrays)


def write(f, arrays) -> None:
    """Write ``arrays`` (name -> array-like) to the binary file f (from its current position,
    written forward only) as a compressed .npz."""
    out = _Counted(f)
    members = []  # (name bytes, flags, crc, deflated size, size, offset)
    with ThreadPoolExecutor(max_workers=workers(), thread_name_prefix="bsrt-npz") as pool:
        try:
            for name, value in arrays.items():
                interrupts.safe_point()
                members.append(_member(out, pool, f"{name}.npy", np.asanyarray(value)))
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)  # those running end within a piece
            raise
    directory = out.position
    for name, flags, crc, deflated, size, offset in members:
        extra = struct.pack("<HHQQQ", 1, 24, size, deflated, offset)
        out.write(
            struct.pack(
                "<IHHHHHHIIIHHHHHII",
                _CENTRAL,
                (3 << 8) | _VERSION,
                _VERSION,
                flags,
                _DEFLATED,
                0,
                _DATE,
                crc,
                _MASK32,
                _MASK32,
                len(name),
                len(extra),
                0,
                0,
                0,
                0o644 << 16,
                _MASK32,
            )
            + name
            + extra
        )
    end64, count, length = out.position, len(members), out.position - directory
    out.write(struct.pack("<IQHHIIQQQQ", _END64, 44, _VERSION, _VERSION, 0, 0, count, count, length, directory))
    out.write(struct.pack("<IIQI", _LOCATOR64, 0, end64, 1))
    # the end record's fields saturate where a value does not fit (the ZIP64 record holds it)
    entries = min(count, _MASK16)
    out.write(struct.pack("<IHHHHIIH", _END, 0, 0, entries, entries, min(length, _MASK32), min(directory, _MASK32), 0))


def _member(out, pool, name: str, array: np.ndarray) -> tuple:
    """Write one member (local header, deflated pieces, data descriptor); its central directory
    entry's values: (name bytes, flags, crc, deflated size, size, offset)."""
    encoded = name.encode("utf-8")
    flags = 0x08 | (0 if encoded.isascii() else _UTF8_NAME)
    offset = out.position
    out.write(
        struct.pack("<IHHHHHIIIHH", _LOCAL, _VERSION, flags, _DEFLATED, 0, _DATE, 0, _MASK32, _MASK32, len(encoded), 20)
        + encoded
        + struct.pack("<HHQQ", 1, 16, 0, 0)
    )
    # the bytes numpy.save writes: Fortran order kept (the header says so), else C order
    fortran = array.flags.f_contiguous and not array.flags.c_contiguous
    a = array if fortran or array.flags.c_contiguous else array.copy(order="C")
    header = _npy_header(a)
    raw = (a.T if fortran else a).reshape(-1).view(np.uint8)
    pieces = [memoryview(header)] + [raw[s : s + PIECE] for s in range(0, raw.size, PIECE)]
    crc, size, deflated = 0, 0, 0
    window = WINDOW_PER_THREAD * workers()
    running = deque()
    for k, piece in enumerate(pieces):
        running.append(pool.submit(_deflate, piece, k == len(pieces) - 1))
        while len(running) >= window or (k == len(pieces) - 1 and running):
            data, piece_crc, length = _result(running.popleft())
            out.write(data)
            crc, size, deflated = crc32_combine(crc, piece_crc, length), size + length, deflated + len(data)
    out.write(struct.pack("<IIQQ", _DESCRIPTOR, crc, deflated, size))
    return encoded, flags, crc, deflated, size, offset


def _npy_header(a: np.ndarray) -> bytes:
    """The .npy format's header of ``a`` (what numpy.save writes before the data)."""
    import io

    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, np.lib.format.header_data_from_array_1_0(a))
    return buffer.getvalue()


def _deflate(piece, last: bool) -> tuple[bytes, int, int]:
    """(raw deflate of piece ending with a sync flush, or the stream's end when last; its CRC-32;
    its length in bytes)."""
    compressor = zlib.compressobj(LEVEL, zlib.DEFLATED, -15)
    data = compressor.compress(piece) + compressor.flush(zlib.Z_FINISH if last else zlib.Z_SYNC_FLUSH)
    return data, zlib.crc32(piece), len(piece)


def _result(future):
    """The future's result, taking a waiting signal every POLL_SECONDS meanwhile."""
    while True:
        interrupts.safe_point()
        try:
            return future.result(timeout=POLL_SECONDS)
        except FutureTimeout:
            continue


class _Counted:
    """A binary file written forward, counting the bytes from where it started."""

    def __init__(self, f):
        self.f, self.position = f, 0

    def write(self, data) -> None:
        self.f.write(data)
        self.position += len(data)


def _multiply(a: int, b: int) -> int:
    """a x b modulo CRC-32's polynomial (32-bit polynomials over GF(2), bits reversed: x^0 is the
    top bit)."""
    product, bit = 0, 1 << 31
    while a:
        if a & bit:
            product ^= b
            a ^= bit
        bit >>= 1
        b = (b >> 1) ^ _POLY if b & 1 else b >> 1
    return product


@functools.lru_cache(maxsize=16)
def _x_to_8n(n: int) -> int:
    """x^(8 n) modulo CRC-32's polynomial (bits reversed), by squaring."""
    result, power = 1 << 31, 1 << 23  # x^0; x^8
    while n:
        if n & 1:
            result = _multiply(power, result)
        power, n = _multiply(power, power), n >> 1
    return result


def crc32_combine(first: int, second: int, length: int) -> int:
    """The CRC-32 of A followed by B from first = crc32(A), second = crc32(B) and length = len(B):
    first's remainder moved past B's 8 x length bits, plus B's."""
    return _multiply(_x_to_8n(length), first) ^ second

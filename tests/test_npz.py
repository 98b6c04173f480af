"""The .npz archives deflated on every core (bsrt/npz.py): what numpy.load and zipfile read,
the same bytes whatever the threads, CRC-32s combined as zlib computes them whole."""

from __future__ import annotations

import io
import zipfile
import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bsrt import npz


def _arrays():
    rng = np.random.default_rng(4)
    return {
        "hit": rng.random((37, 41)) > 0.5,
        "surface": rng.integers(-1, 9, (37, 41)).astype(np.int32),
        "position": rng.random((37, 41, 3)),
        "fortran": np.asfortranarray(rng.random((5, 7))),
        "strided": rng.random((6, 8))[::2, ::3],
        "big_endian": np.arange(12, dtype=">f8").reshape(3, 4),
        "none": np.zeros((0, 3)),
        "names": np.array(["teacup", "spout"]),
        "héllo": np.float64(2.5),  # a 0-d array and a name outside ASCII
    }


def _written(arrays, offset: bytes = b"") -> bytes:
    buffer = io.BytesIO()
    buffer.write(offset)
    npz.write(buffer, arrays)
    return buffer.getvalue()[len(offset) :]


@pytest.mark.parametrize("piece", [1000, 1 << 22])
def test_numpy_load_gives_every_array_back_exactly(monkeypatch, piece):
    """One NAME.npy member per array, in order; numpy.load returns each with its dtype, shape and
    values (Fortran order and byte order kept as numpy.save keeps them), in pieces of 1000 bytes
    (position: 36 pieces) or one."""
    monkeypatch.setattr(npz, "PIECE", piece)
    arrays = _arrays()
    data = _written(arrays)
    with np.load(io.BytesIO(data)) as got:
        assert got.files == list(arrays)
        for name, want in arrays.items():
            assert got[name].dtype == want.dtype and got[name].shape == want.shape, name
            np.testing.assert_array_equal(got[name], want, err_msg=name)
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        assert archive.testzip() is None  # every member's CRC-32 and sizes
        infos = archive.infolist()
        assert [i.filename for i in infos] == [f"{name}.npy" for name in arrays]
        assert all(i.compress_type == zipfile.ZIP_DEFLATED and i.date_time == (1980, 1, 1, 0, 0, 0) for i in infos)
        for info, (name, want) in zip(infos, arrays.items()):
            saved = io.BytesIO()
            np.save(saved, want)
            assert archive.read(info) == saved.getvalue(), name  # the bytes numpy.save writes


def test_the_members_are_deflated_in_pieces_of_their_own(monkeypatch):
    """With PIECE = 1000 the position member's deflate stream is its pieces' streams one after
    the other: each ends with a sync flush (the empty stored block 00 00 ff ff) but the last."""
    monkeypatch.setattr(npz, "PIECE", 1000)
    arrays = {"position": np.random.default_rng(1).random((40, 50))}
    data = _written(arrays)
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        info = archive.infolist()[0]
    start = info.header_offset + 30 + len(info.filename) + 20  # the local header, its ZIP64 field
    stream = data[start : start + info.compress_size]
    assert stream.count(b"\x00\x00\xff\xff") >= 16  # the header's piece and 16 pieces of 1000 bytes, the last not
    raw = zlib.decompressobj(-15)
    assert raw.decompress(stream) == io.BytesIO(_npy(arrays["position"])).getvalue() and raw.eof


def _npy(array) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def test_the_bytes_do_not_depend_on_the_threads_or_on_where_the_file_starts(monkeypatch):
    """One thread or many, from the file's start or after other bytes: the same archive."""
    monkeypatch.setattr(npz, "PIECE", 1000)
    arrays = _arrays()
    many = _written(arrays)
    assert _written(arrays, offset=b"x" * 77) == many
    monkeypatch.setattr(npz, "workers", lambda: 1)
    assert _written(arrays) == many


def test_the_archive_of_no_arrays_is_an_empty_zip():
    with zipfile.ZipFile(io.BytesIO(_written({}))) as archive:
        assert archive.infolist() == []


def test_a_signal_drops_the_pieces_not_started(monkeypatch):
    """A signal taken while the writer waits for a piece (interrupts.safe_point raising, as a
    signal does) ends the write there: the exception comes out, no further member is written, and
    of the 400 pieces queued (one thread, each piece 5 ms) only those already started run."""
    import time

    monkeypatch.setattr(npz, "PIECE", 1000)
    monkeypatch.setattr(npz, "WINDOW_PER_THREAD", 400)
    monkeypatch.setattr(npz, "workers", lambda: 1)
    started = []
    deflate = npz._deflate

    def slow(piece, last):
        started.append(len(piece))
        time.sleep(0.005)
        return deflate(piece, last)

    waits = []

    def signal_on_the_fifth_wait():
        waits.append(1)
        if len(waits) == 5:
            raise KeyboardInterrupt

    monkeypatch.setattr(npz, "_deflate", slow)
    monkeypatch.setattr(npz.interrupts, "safe_point", signal_on_the_fifth_wait)
    buffer = io.BytesIO()
    with pytest.raises(KeyboardInterrupt):
        npz.write(buffer, {"a": np.zeros(100_000), "b": np.zeros(100_000)})
    assert len(started) < 50  # of a's 801 pieces, 400 in the queue when the signal came
    assert b"b.npy" not in buffer.getvalue()


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300), st.binary(max_size=300))
def test_crc32_combine_is_the_crc_of_the_two_parts_together(first, second):
    assert npz.crc32_combine(zlib.crc32(first), zlib.crc32(second), len(second)) == zlib.crc32(first + second)


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 1 << 40), st.integers(0, 1 << 40))
def test_the_shift_of_a_crc_adds_up_past_32_bit_lengths(a, b):
    """x^(8 a) x^(8 b) = x^(8 (a + b)) modulo CRC-32's polynomial: the shift crc32_combine applies
    for a ZIP64 member's lengths, checked where zlib cannot be asked (terabytes)."""
    assert npz._multiply(npz._x_to_8n(a), npz._x_to_8n(b)) == npz._x_to_8n(a + b)


def test_crc32_combine_of_a_long_run_of_zeros():
    """The CRC-32 of 2^34 zero bytes built by doubling from one byte and from a mebibyte (zlib's)."""
    crc, length = zlib.crc32(b"\x00"), 1
    while length < 1 << 34:
        crc, length = npz.crc32_combine(crc, crc, length), 2 * length
    whole, length = zlib.crc32(bytes(1 << 20)), 1 << 20
    while length < 1 << 34:
        whole, length = npz.crc32_combine(whole, whole, length), 2 * length
    assert crc == whole

"""The decoding process's pipe: objects and their arrays through it as they were, arrays writable."""

from __future__ import annotations

import contextlib
import os
import pickle
import threading
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from sniffer.step_pipe import receive_item, send_item

pytestmark = pytest.mark.skipif(not hasattr(os, "readv"), reason="the decoding process exists on POSIX only")


@dataclass
class _Step:
    name: str
    data: bytes
    columns: dict[str, np.ndarray]
    parts: list[np.ndarray]


@pytest.fixture
def pipe() -> Iterator[tuple[int, int]]:
    read, write = os.pipe()
    yield read, write
    for fd in (read, write):
        with contextlib.suppress(OSError):  # closed by the test
            os.close(fd)


def _through(pipe: tuple[int, int], *items: object) -> list[object]:
    """``items`` sent by a thread while this one receives them (more than the pipe holds)."""
    read, write = pipe
    sender = threading.Thread(target=lambda: [send_item(write, item) for item in items])
    sender.start()
    received = [receive_item(read) for _ in items]
    sender.join()
    return received


def _equal(a: object, b: object) -> bool:
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape and bool(
            np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"))
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return type(a) is type(b) and len(a) == len(b) and all(map(_equal, a, b))  # type: ignore[arg-type]
    if isinstance(a, _Step):
        fields = ("name", "data", "columns", "parts")
        return isinstance(b, _Step) and all(_equal(getattr(a, f), getattr(b, f)) for f in fields)
    return a == b


def test_a_step_of_columns_comes_through_whole_and_its_arrays_writable(pipe: tuple[int, int]) -> None:
    rng = np.random.default_rng(1)
    big = rng.integers(0, 1 << 62, 600_000, dtype=np.int64)  # 4.8 MB: more than the pipe holds
    step = _Step("batch", bytes(range(256)) * 100,
                 {"t": big, "role": rng.integers(0, 6, 1000).astype(np.uint8), "empty": np.zeros(0, np.int16),
                  "every_other": big[::2], "matrix_f": np.asfortranarray(rng.random((30, 7))),
                  "objects": np.array(["a", None, 3], object)},
                 [np.arange(5), np.float64(2.5) * np.ones(3)])
    (received,) = _through(pipe, step)
    assert _equal(step, received)
    assert isinstance(received, _Step)
    for column in (*received.columns.values(), *received.parts):
        assert column.flags.writeable
        if column.size:
            column[0] = column[-1]  # written in place, as the parent may


def test_many_items_come_in_order(pipe: tuple[int, int]) -> None:
    items = [{"n": n, "a": np.full(n * 1000, n, np.int32)} for n in range(40)] + [None, "end", (1, b"x")]
    assert all(_equal(a, b) for a, b in zip(items, _through(pipe, *items), strict=True))


@settings(max_examples=60, deadline=None)
@given(st.lists(hnp.arrays(hnp.scalar_dtypes(), hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=40)),
                max_size=6))
def test_any_arrays_come_through_as_pickle_gives_them(arrays: list[np.ndarray]) -> None:
    read, write = os.pipe()
    try:
        (received,) = _through((read, write), arrays)
    finally:
        os.close(read)
        os.close(write)
    # As pickle gives them in one piece (which turns a 0-d array of the other byte order native).
    expected = pickle.loads(pickle.dumps(arrays, protocol=5))
    assert isinstance(received, list) and len(received) == len(expected)
    for got, want in zip(received, expected, strict=True):
        assert got.dtype == want.dtype and got.shape == want.shape
        assert got.tobytes() == want.tobytes()


def test_a_pipe_ended_within_an_item_is_end_of_file(pipe: tuple[int, int]) -> None:
    read, write = pipe
    side_read, side_write = os.pipe()
    send_item(side_write, {"a": np.arange(1000)})
    os.close(side_write)
    whole = b""
    while chunk := os.read(side_read, 1 << 16):
        whole += chunk
    os.close(side_read)
    for cut in (0, 4, 8 + 8, len(whole) // 2, len(whole) - 1):
        r, w = os.pipe()
        os.write(w, whole[:cut])
        os.close(w)
        with pytest.raises(EOFError):
            receive_item(r)
        os.close(r)
    os.write(write, whole)
    assert _equal(receive_item(read), {"a": np.arange(1000)})


def test_an_item_that_does_not_pickle_writes_nothing(pipe: tuple[int, int]) -> None:
    read, write = pipe
    with pytest.raises((pickle.PicklingError, TypeError, AttributeError)):
        send_item(write, {"a": np.arange(3), "f": lambda: None})
    send_item(write, "next")
    assert receive_item(read) == "next"  # nothing of the failed one came before it


def test_sending_to_a_closed_reader_is_an_os_error(pipe: tuple[int, int]) -> None:
    read, write = pipe
    os.close(read)
    with pytest.raises(OSError):
        send_item(write, np.arange(10))

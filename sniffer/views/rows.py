"""Records built a batch at a time: columns of byte strings joined into rows in C.

A sink that writes a record per frame (a JSON line, an MCAP message) spends most of its time
putting small pieces together. Here each field is a column: one constant piece for every row, or
a list with one piece per row. :func:`join_rows` interleaves the columns with one list slice
assignment each and joins them with one ``bytes.join``: the Python work is per column, not per
row. The numbers' texts come from one ``repr`` per column (:func:`number_texts`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

#: A field of every row: the same bytes for all, or one piece per row.
Column = bytes | Sequence[bytes]
#: A column of integers of any width (slaves are int16, roles uint8, times int64).
Integers = npt.NDArray[np.integer[Any]]


@dataclass(frozen=True)
class Rows:
    """Rows laid end to end: row ``i`` is ``data[offsets[i] : offsets[i + 1]]``.

    ``data`` is writable so that a fixed-size slot at the start of each row (``reserved``
    bytes, see :func:`join_rows`) can be filled in afterwards, by numpy, for all rows at once.
    """

    data: bytearray
    offsets: npt.NDArray[np.int64]
    reserved: int = 0

    def __len__(self) -> int:
        return len(self.offsets) - 1

    def lengths(self) -> npt.NDArray[np.int64]:
        return np.diff(self.offsets)

    def row(self, index: int) -> bytes:
        """Row ``index`` without its reserved slot."""
        return bytes(self.data[int(self.offsets[index]) + self.reserved : int(self.offsets[index + 1])])

    def buffer(self) -> npt.NDArray[np.uint8]:
        """``data`` as a writable numpy view (no copy)."""
        return np.frombuffer(self.data, np.uint8)


def join_rows(columns: Sequence[Column], count: int, reserved: int = 0) -> Rows:
    """``count`` rows, row ``i`` being the ``i``-th piece of every column in order (a constant
    column gives its bytes to every row), after ``reserved`` zero bytes."""
    if count == 0:
        return Rows(bytearray(), np.zeros(1, np.int64), reserved)
    width = len(columns) + (1 if reserved else 0)
    pieces: list[bytes] = [b""] * (count * width)
    fixed = reserved
    if reserved:
        pieces[0::width] = [bytes(reserved)] * count
    lengths = np.zeros(count, np.int64)
    for place, column in enumerate(columns, start=width - len(columns)):
        if isinstance(column, bytes):
            pieces[place::width] = [column] * count
            fixed += len(column)
        else:
            if len(column) != count:
                raise ValueError(f"column {place} has {len(column)} pieces for {count} rows")
            pieces[place::width] = column
            lengths += np.fromiter(map(len, column), np.int64, count)
    offsets = np.zeros(count + 1, np.int64)
    np.cumsum(lengths + fixed, out=offsets[1:])
    return Rows(bytearray(b"".join(pieces)), offsets, reserved)


def number_texts(column: npt.NDArray[Any]) -> list[bytes]:
    """Each number as ``repr`` (and so ``json.dumps``) writes it: one ``repr`` of the whole
    list formats in C what a loop would format one by one."""
    return repr(column.tolist()).encode()[1:-1].split(b", ") if len(column) else []


def or_null(texts: list[bytes], column: Integers, none: int) -> list[bytes]:
    """``texts`` with ``null`` where ``column`` holds ``none``."""
    for position in np.flatnonzero(column == none).tolist():
        texts[position] = b"null"
    return texts


_HEX_DIGITS = np.frombuffer(b"0123456789abcdef", np.uint8)


def hex_texts(data: bytes, offsets: npt.NDArray[np.int64]) -> list[bytes]:
    """Lower-case hex of each ``data[offsets[i] : offsets[i + 1]]``, as ``bytes.hex`` writes it,
    for all pieces at once: the digits are laid out by numpy with a separator after each piece
    (``|`` is no hex digit) and split in C."""
    count = len(offsets) - 1
    if count == 0:
        return []
    raw = np.frombuffer(data, np.uint8, int(offsets[-1] - offsets[0]), int(offsets[0]))
    lengths = np.diff(offsets)
    # Piece i's digits start after the digits and separators of the pieces before it.
    starts = 2 * (offsets[:-1] - offsets[0]) + np.arange(count)
    text = np.full(2 * len(raw) + count - 1, ord("|"), np.uint8)
    byte_places = np.repeat(starts - 2 * (offsets[:-1] - offsets[0]), lengths) + 2 * np.arange(len(raw))
    text[byte_places] = _HEX_DIGITS[raw >> 4]
    text[byte_places + 1] = _HEX_DIGITS[raw & 0x0F]
    return text.tobytes().split(b"|")


def seconds_columns(ns: Integers, none: int | None = None) -> list[Column]:
    """Nanoseconds as the exact decimal of seconds (``1700000000.001997592``): see
    :func:`decimal_columns`."""
    return decimal_columns(ns, 9, none)


def decimal_columns(values: Integers, places: int, none: int | None = None) -> list[Column]:
    """``values / 10**places`` as exact decimals (nanoseconds as seconds: ``1700000000.001997592``),
    as three columns for :func:`join_rows`: the whole part by ``repr``, the point, the fraction's
    digits cut by numpy. Several times faster than ``repr`` of floats, which is what matters where
    no one compares spellings (MCAP messages). ``null`` where ``values`` holds ``none``. Negative
    values (never seen, but possible in a text capture) fall back to floats."""
    count = len(values)
    missing = np.flatnonzero(values == none).tolist() if none is not None else []
    present = np.where(values == none, 0, values) if missing else values
    if count and int(present.min()) < 0:
        texts = number_texts(values / 10**places)
        return [or_null(texts, values, none) if none is not None else texts]
    whole, fraction = np.divmod(present, 10**places)
    place_values = 10 ** np.arange(places - 1, -1, -1, dtype=np.int64)
    digits = (fraction[:, None] // place_values % 10 + ord("0")).astype(np.uint8)
    fraction_texts: list[bytes] = digits.view(f"S{places}").ravel().tolist()
    whole_texts = number_texts(whole)
    if not missing:
        return [whole_texts, b".", fraction_texts]
    points = [b"."] * count
    for row in missing:
        whole_texts[row], points[row], fraction_texts[row] = b"null", b"", b""
    return [whole_texts, points, fraction_texts]

"""Records built a batch at a time: columns of byte strings joined into rows in C.

A sink that writes a record per frame (a JSON line, an MCAP message) spends most of its time
putting small pieces together. Here each field is a column: one constant piece for every row, or
a list with one piece per row. :func:`join_rows` interleaves the columns with one list slice
assignment each and joins them with one ``join``: the Python work is per column, not per row.

The columns are built whole too: numbers by one ``repr`` per column (:func:`number_texts`), hex
by numpy (:func:`hex_texts`), small codes through a :class:`Table`. :class:`Pieces` carry the sizes numpy
already knew, so that joining need not measure every piece.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from decoders.runs import spread

#: A field of every row: the same bytes for all, or one piece per row.
Column = bytes | Sequence[bytes]


class Pieces(list[bytes]):
    """A column's pieces whose sizes numpy knew already (from the text they were cut from),
    so that :func:`join_rows` need not measure them one by one."""

    def __init__(self, pieces: list[bytes], sizes: npt.NDArray[np.int64]) -> None:
        super().__init__(pieces)
        self.sizes = sizes

    def fill(self, rows: npt.NDArray[np.int64], piece: bytes) -> None:
        """``piece`` at ``rows``: one by one for a few, through a numpy object array for many."""
        if len(rows) < 16:
            for row in rows.tolist():
                self[row] = piece
        else:
            items = np.empty(len(self), object)
            items[:] = self
            items[rows] = piece
            self[:] = items.tolist()
        self.sizes[rows] = len(piece)

    def take(self, rows: npt.NDArray[np.int64]) -> Pieces:
        """The pieces at ``rows``, in that order."""
        return Pieces(list(map(self.__getitem__, rows.tolist())), self.sizes[rows])


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
            lengths += column_sizes(column, count)
    offsets = np.zeros(count + 1, np.int64)
    np.cumsum(lengths + fixed, out=offsets[1:])
    return Rows(bytearray().join(pieces), offsets, reserved)


def column_sizes(column: Column, count: int) -> npt.NDArray[np.int64]:
    """The size of each of the ``count`` pieces of ``column``: known already for :class:`Pieces`
    and constants, measured otherwise."""
    if isinstance(column, bytes):
        return np.full(count, len(column), np.int64)
    return column.sizes if isinstance(column, Pieces) else np.fromiter(map(len, column), np.int64, count)


def number_texts(column: npt.NDArray[Any]) -> Pieces:
    """Each number as ``repr`` (and so ``json.dumps``) writes it: one ``repr`` of the whole
    list formats in C what a loop would format one by one; the sizes come from where the
    separators are."""
    if not len(column):
        return Pieces([], np.zeros(0, np.int64))
    text = repr(column.tolist()).encode()[1:-1]
    separators = np.flatnonzero(np.frombuffer(text, np.uint8) == ord(","))
    # Piece i runs from after separator i - 1 (and its space) to separator i, or to the end.
    sizes = np.diff(separators, prepend=-2, append=len(text)) - 2
    return Pieces(text.split(b", "), sizes)


class Table:
    """Pieces chosen by a small integer (flags, a level, an outcome): looked up for a whole
    column in C, their sizes by numpy."""

    def __init__(self, pieces: Sequence[bytes]) -> None:
        self._pieces = list(pieces)
        self._sizes = np.fromiter(map(len, self._pieces), np.int64, len(self._pieces))

    def column(self, keys: Integers) -> Pieces:
        """The piece of each key (negative keys count from the end, as in a list)."""
        return Pieces(list(map(self._pieces.__getitem__, keys.tolist())), self._sizes[keys])


def or_null(texts: Pieces, column: Integers, none: int) -> Pieces:
    """``texts`` with ``null`` where ``column`` holds ``none``."""
    texts.fill(np.flatnonzero(column == none), b"null")
    return texts


_HEX_DIGITS = np.frombuffer(b"0123456789abcdef", np.uint8)


def hex_texts(data: bytes, offsets: npt.NDArray[np.int64], *, quoted: bool = False) -> Pieces:
    """Lower-case hex of each ``data[offsets[i] : offsets[i + 1]]``, as ``bytes.hex`` writes it
    (in double quotes: a JSON string, if ``quoted``), for all pieces at once: the digits are laid
    out by numpy with a separator after each piece (``|`` is no hex digit) and split in C."""
    count = len(offsets) - 1
    if count == 0:
        return Pieces([], np.zeros(0, np.int64))
    raw = np.frombuffer(data, np.uint8, int(offsets[-1] - offsets[0]), int(offsets[0]))
    quotes = 2 if quoted else 0
    sizes = 2 * np.diff(offsets) + quotes
    # Piece i starts after the pieces before it and their separators.
    starts = np.zeros(count, np.int64)
    np.cumsum(sizes[:-1] + 1, out=starts[1:])
    text = np.full(int(sizes.sum()) + count - 1, ord("|"), np.uint8)
    digits_at = starts + quotes // 2
    byte_places = spread(digits_at, np.diff(offsets), 2)  # two digits a byte, from each piece's first
    text[byte_places] = _HEX_DIGITS[raw >> 4]
    text[byte_places + 1] = _HEX_DIGITS[raw & 0x0F]
    if quoted:
        text[starts] = text[starts + sizes - 1] = ord('"')
    return Pieces(text.tobytes().split(b"|"), sizes)

"""Rows of one width, laid out by numpy: the per-frame fields of a JSON message in one matrix.

:mod:`sniffer.encoding.rows` joins columns of pieces with one list operation per column; a
message with a dozen small fields (an index, four times, flags, a pairing, a latency) still
costs a dozen list operations per row. Where no one compares bytes with ``json.dumps`` (MCAP
messages), those fields can instead sit at fixed places in a byte matrix, each right-aligned in
the width its widest value in the batch needs and padded with spaces (JSON allows whitespace
before a value): numpy writes each field for all rows at once, and one ``tolist`` gives the rows.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from decoders.distinct import distinct
from sniffer.encoding.rows import Integers, Pieces

#: Writes a field into its columns of the matrix (rows × the field's width).
_Writer = Callable[[npt.NDArray[np.uint8]], None]
_SPACE, _MINUS, _NULL = ord(" "), ord("-"), np.frombuffer(b"null", np.uint8)
_POWERS = 10 ** np.arange(1, 19, dtype=np.uint64)


class Block:
    """Fields of ``count`` rows, described in order; :meth:`pieces` lays them out."""

    def __init__(self, count: int) -> None:
        self.count = count
        self._fields: list[tuple[int, _Writer]] = []

    def text(self, constant: bytes) -> Block:
        """The same bytes in every row (a key, a separator, a reserved slot of zeros)."""
        pattern = np.frombuffer(constant, np.uint8)
        self._fields.append((len(constant), lambda place: place.__setitem__(slice(None), pattern)))
        return self

    def integers(self, values: Integers, none: int | None = None) -> Block:
        """Integers in decimal, as ``repr`` spells them; ``null`` where ``values`` holds ``none``."""
        return self.decimals(values, 0, none)

    def decimals(self, values: Integers, places: int, none: int | None = None) -> Block:
        """``values / 10**places`` as exact decimals (nanoseconds as seconds: ``places`` 9,
        ``-0.000001500``), integers for ``places`` 0; ``null`` where ``values`` holds ``none``."""
        missing = None if none is None else values == none
        if missing is not None and not missing.any():
            missing = None
        negative = (values < 0) if missing is None else (values < 0) & ~missing
        signed = np.flatnonzero(negative)
        # Magnitudes in uint64 (the magnitude of -2**63 fits there).
        magnitude = values.astype(np.uint64)
        if len(signed):
            magnitude[signed] = (-(values[signed] + 1)).astype(np.uint64) + 1
        if missing is not None:
            magnitude[missing] = 0
        whole, fraction = np.divmod(magnitude, np.uint64(10**places))
        lengths = 1 + np.searchsorted(_POWERS, whole, side="right") + negative
        fraction_width = places + 1 if places else 0
        whole_width = max(int(lengths.max(initial=1)), 4 - fraction_width if missing is not None else 0)
        width = whole_width + fraction_width

        def write(place: npt.NDArray[np.uint8]) -> None:
            whole_place = place[:, :whole_width]
            whole_place[:] = fixed_digits(whole, whole_width)
            if int(lengths.min(initial=whole_width)) < whole_width:
                whole_place[np.arange(whole_width) < (whole_width - lengths)[:, None]] = _SPACE
            whole_place[signed, whole_width - lengths[signed]] = _MINUS
            if places:
                place[:, whole_width] = ord(".")
                place[:, whole_width + 1 :] = fixed_digits(fraction, places)
            if missing is not None:
                place[missing] = _SPACE
                place[missing, width - 4 :] = _NULL

        self._fields.append((width, write))
        return self

    def matrix(self, rows: npt.NDArray[np.uint8]) -> Block:
        """Bytes laid out already, a row of ``rows`` per row (see :func:`times_matrix`)."""
        self._fields.append((rows.shape[1], lambda place: place.__setitem__(slice(None), rows)))
        return self

    def choice(self, keys: Integers, pieces: list[bytes]) -> Block:
        """The piece each key picks, right-aligned in the width of the widest picked."""
        used = distinct(keys).tolist()
        width = max((len(pieces[key]) for key in used), default=0)
        table = np.full((len(pieces), width), _SPACE, np.uint8)
        for key in used:
            table[key, width - len(pieces[key]) :] = np.frombuffer(pieces[key], np.uint8)
        self._fields.append((width, lambda place: place.__setitem__(slice(None), table[keys])))
        return self

    def pieces(self) -> Pieces:
        """Each row as bytes, all of one width."""
        width = sum(field_width for field_width, _ in self._fields)
        matrix = np.empty((self.count, width), np.uint8)
        start = 0
        for field_width, write in self._fields:
            write(matrix[:, start : start + field_width])
            start += field_width
        if width and self.count and not matrix[:, -1].all():
            raise ValueError("a block's rows end in a zero byte, which tolist() would drop")
        rows: list[bytes] = matrix.view(f"S{width}").ravel().tolist() if width else [b""] * self.count
        return Pieces(rows, np.full(self.count, width, np.int64))


_TIMES = (
    b',"t":SSSSSSSSSS.NNNNNNNNN,"t_end":SSSSSSSSSS.NNNNNNNNN,"t_ns":DDDDDDDDDDDDDDDDDDD,"t_end_ns":DDDDDDDDDDDDDDDDDDD'
)
_TIMES_TEMPLATE = np.frombuffer(_TIMES, np.uint8)
#: Where each time's digits go: (t_ns digits, fraction digits) per field of the template.
_T, _T_END = _TIMES.index(b"S"), _TIMES.index(b"S", _TIMES.index(b"t_end"))
_T_NS, _T_END_NS = _TIMES.index(b"D"), _TIMES.index(b"D", _TIMES.index(b"t_end_ns"))
EPOCH_DIGITS = 19  # nanoseconds since 1970 from 2001-09-09 to 2286-11-20


def times_matrix(t_start: npt.NDArray[np.int64], t_end: npt.NDArray[np.int64]) -> npt.NDArray[np.uint8] | None:
    """``,"t":…,"t_end":…,"t_ns":…,"t_end_ns":…`` per row of a byte matrix (for :meth:`Block.matrix`),
    all four from the two columns' digits, cut once (``t`` as the exact decimal of ``t_ns``).
    ``None`` unless every time has 19 digits (any capture time from 2001 to 2286)."""
    count = len(t_start)
    if not count or not all(
        int(column.min()) >= 10 ** (EPOCH_DIGITS - 1) and int(column.max()) < 10**EPOCH_DIGITS
        for column in (t_start, t_end)
    ):
        return None
    block = np.empty((count, len(_TIMES)), np.uint8)
    block[:] = _TIMES_TEMPLATE
    for column, seconds_at, digits_at in ((t_start, _T, _T_NS), (t_end, _T_END, _T_END_NS)):
        digits = fixed_digits(column, EPOCH_DIGITS)
        block[:, digits_at : digits_at + EPOCH_DIGITS] = digits
        block[:, seconds_at : seconds_at + 10] = digits[:, :10]
        block[:, seconds_at + 11 : seconds_at + 20] = digits[:, 10:]
    return block


def fixed_digits(values: Integers, width: int) -> npt.NDArray[np.uint8]:
    """Each non-negative value's last ``width`` decimal digits, with leading zeros: a digit
    column at a time, in 32 bits (several times faster than 64): larger values are cut into
    their last nine digits and the rest."""
    if len(values) and width > 9 and int(values.max()) >= 1 << 32:
        high, low = np.divmod(values, values.dtype.type(10**9))
        return np.concatenate([fixed_digits(high, width - 9), fixed_digits(low, 9)], axis=1)
    digits = np.empty((len(values), width), np.uint8)
    rest = values.astype(np.uint32)
    for place in range(width - 1, -1, -1):
        rest, digit = np.divmod(rest, np.uint32(10))
        digits[:, place] = digit
    digits += ord("0")
    return digits

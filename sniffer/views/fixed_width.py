"""Plain frame rows laid out by numpy: every field but the summary, for a whole batch at once.

The plain table (:class:`sniffer.views.table.PlainTableView`) writes fixed-width fields; here
they are digits and letters put into one byte matrix (a row per frame, a column per character)
by whole-column arithmetic and lookups, instead of a ``%`` format per row. The result is the
same text as :meth:`sniffer.views.layout.Layout.plain_prefixes` over
:func:`sniffer.views.frame_cells.frame_cells` (the plain path, which the tests hold it to);
tables with the hex column take the plain path.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from decoders.frame import NO_IDLE
from decoders.message import NONE, MessageBatch
from sniffer.views.clock import NS_PER_S, Clock
from sniffer.views.frame_cells import _FLAGS_JOINED, _NOISE, _ROLE_NAMES
from sniffer.views.layout import Layout

SPACE, DASH, ZERO = ord(" "), ord("-"), ord("0")
_CRC = ["ok", "BAD", "-"]
#: Keys of the columns this module lays out.
KEYS = ("index", "time", "idle", "slave", "function", "role", "request", "latency", "length", "crc", "flags")


class Field:
    """One column's characters for every row, right- or left-justified in a given width."""

    def __init__(self, chars: npt.NDArray[np.uint8], lengths: npt.NDArray[np.int64]) -> None:
        #: Row ``i`` is ``chars[i, :lengths[i]]`` (left-aligned in the matrix).
        self.chars, self.lengths = chars, lengths

    @property
    def width(self) -> int:
        return int(self.lengths.max()) if len(self.lengths) else 0

    def placed(self, width: int, *, right: bool) -> npt.NDArray[np.uint8]:
        """The rows padded with spaces to ``width``."""
        chars = self.chars[:, :width]  # a lookup table may be wider than any row here
        rows, have = chars.shape
        out = np.full((rows, width), SPACE, np.uint8)
        if not right:
            out[:, :have] = np.where(np.arange(have) < self.lengths[:, None], chars, SPACE)
            return out
        # Right-justified: character j of a row goes to width - length + j.
        columns = np.arange(have)
        keep = columns < self.lengths[:, None]
        row_index, column_index = np.nonzero(keep)
        out[row_index, width - self.lengths[row_index] + column_index] = chars[row_index, column_index]
        return out


def numbers(values: npt.NDArray[np.int64], empty: npt.NDArray[np.bool_], *, before: bytes = b"",
            decimals: int = 0) -> Field:
    """Non-negative integers in decimal (``decimals`` of them after a point), ``before`` in front;
    ``-`` where ``empty``."""
    values = np.where(empty, 0, values).astype(np.int64)
    digits = np.maximum(_digit_count(values), decimals + 1)
    total = len(before) + digits + (1 if decimals else 0)
    width = int(total.max()) if len(values) else 1
    chars = np.zeros((len(values), max(width, 1)), np.uint8)
    rows = np.arange(len(values))
    remaining = values.copy()
    # Digits from the last: the k-th from the end sits at total - 1 - k (one more past the point).
    for k in range(int(digits.max()) if len(values) else 0):
        place = total - 1 - k - (1 if decimals and k >= decimals else 0)
        live = k < digits
        chars[rows[live], place[live]] = ZERO + remaining[live] % 10
        remaining //= 10
    if decimals:
        chars[rows, total - 1 - decimals] = ord(".")
    for offset, byte in enumerate(before):
        chars[:, offset] = byte
    lengths = total.astype(np.int64)
    chars[empty, 0] = DASH
    lengths[empty] = 1
    return Field(chars, lengths)


def _digit_count(values: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
    count = np.ones(len(values), np.int64)
    bound = 10
    while len(values) and bound <= values.max():
        count += values >= bound
        bound *= 10
    return count


def texts(table: Sequence[str], codes: npt.NDArray[np.integer]) -> Field:
    """The string ``table[code]`` of each row (ASCII)."""
    encoded = [text.encode("ascii") for text in table]
    width = max(map(len, encoded), default=1)
    matrix = np.frombuffer(b"".join(t.ljust(width, b"\0") for t in encoded), np.uint8).reshape(len(encoded), width)
    lengths = np.fromiter(map(len, encoded), np.int64, len(encoded))
    return Field(matrix[codes], lengths[codes])


def clock_times(clock: Clock, t_ns: npt.NDArray[np.int64]) -> Field:
    """The times as the clock writes them: ``HH:MM:SS.ffffff``, or relative seconds."""
    if clock.mode == "relative":
        if clock.origin_ns is None and len(t_ns):
            clock.origin_ns = int(t_ns[0])
        micros = (t_ns - (clock.origin_ns or 0)) // 1000
        return numbers(micros, np.zeros(len(t_ns), np.bool_), decimals=6)
    of_day = clock.seconds_of_day(t_ns)
    micros = (t_ns % NS_PER_S) // 1000
    parts = [of_day // 3600, of_day // 60 % 60, of_day % 60]
    chars = np.empty((len(t_ns), 15), np.uint8)
    for place, part in enumerate(parts):
        chars[:, 3 * place] = ZERO + part // 10
        chars[:, 3 * place + 1] = ZERO + part % 10
    chars[:, 2] = chars[:, 5] = ord(":")
    chars[:, 8] = ord(".")
    for k in range(6):
        chars[:, 14 - k] = ZERO + micros // 10**k % 10
    return Field(chars, np.full(len(t_ns), 15, np.int64))


def milliseconds(values_ns: npt.NDArray[np.int64], none: int) -> Field:
    """``12.345`` to the nearest microsecond, ``-`` where ``none``."""
    empty = values_ns == none
    micros = (np.where(empty, 0, values_ns) + 500) // 1000
    return numbers(micros, empty, decimals=3)


def fields(batch: MessageBatch, clock: Clock) -> dict[str, Field]:
    """Every column but the summary, for every frame of ``batch``."""
    frames = batch.frames
    crc = np.where(batch.role == _NOISE, 2, np.where(frames.crc_ok, 0, 1))
    return {
        "index": numbers(np.arange(len(batch), dtype=np.int64) + frames.first_index, np.zeros(len(batch), np.bool_)),
        "time": clock_times(clock, frames.t_start_ns),
        "idle": milliseconds(frames.idle_before_ns, NO_IDLE),
        "slave": numbers(batch.slave.astype(np.int64), batch.slave == NONE),
        "function": numbers(batch.function.astype(np.int64), batch.function == NONE),
        "role": texts(_ROLE_NAMES, batch.role),
        "request": numbers(batch.request_index, batch.request_index == NONE, before=b"#"),
        "latency": milliseconds(batch.latency_ns, NONE),
        "length": numbers(np.diff(frames.offsets), np.zeros(len(batch), np.bool_)),
        "crc": texts(_CRC, crc),
        "flags": texts([names or "-" for names in _FLAGS_JOINED], batch.flags),
    }


def prefixes(layout: Layout, batch: MessageBatch, clock: Clock) -> list[str]:
    """The plain rows of ``batch`` but for the summary, each with the gap after it, as
    :meth:`Layout.plain_prefixes` writes them; the layout's widths grow as there."""
    laid = fields(batch, clock)
    for key, field in laid.items():
        if field.width > layout.widths.get(key, 0):
            layout.widths[key] = field.width
    gap = np.full((len(batch), len(layout.gap())), SPACE, np.uint8)
    parts = []
    for column, width in layout.shown()[:-1]:
        parts += [laid[column.key].placed(width, right=column.right), gap]
    block = np.hstack(parts) if parts else np.zeros((len(batch), 0), np.uint8)
    text, size = block.tobytes().decode("ascii"), block.shape[1]
    return [text[start : start + size] for start in range(0, len(text), size)]

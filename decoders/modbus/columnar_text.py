"""The summary lines of frames kept in columns, a kind of frame at a time.

A frame's summary depends on its kind (read, answer, write, write's answer) and function; the
frames of one kind and function are laid out field by field by
:mod:`decoders.modbus.text_layout` (numbers' digits, hex words and coils' bits computed for all
rows at once, not formatted from a Python object each), and one ``split`` makes the lines. The
tests hold every line to the summary of the frame's PDU (the plain path:
``tests/property/test_columnar.py``).

:func:`summaries` gives the lines as Python strings, which every output spells.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from decoders.distinct import distinct
from decoders.modbus.codecs import BIT_VALUES, BULK_SHAPES, BULK_SINGLE
from decoders.modbus.codes import TABLE_NAMES
from decoders.modbus.pdu import COIL_STATES
from decoders.modbus.pdu_text import HEX_WORDS_SHOWN, registers
from decoders.modbus.text_layout import (
    Field,
    bits,
    chosen,
    decimal,
    hex_words,
    lines,
    present,
    upper_hex,
)

#: What a frame kept in columns is: a read request (FC 1-4), its answer (or an FC 23 request's),
#: a write request (FC 5, 6, 15, 16; kept only with its answer), its answer, an FC 23 request
#: (read and write at once; kept only with its answer).
READ, READ_ANSWER, WRITE, WRITE_ANSWER, READ_WRITE = 0, 1, 2, 3, 4
_SHOWN_BITS = 32  # a summary writes 32 bits, then "…"


class SummaryColumns(Protocol):
    """What a summary line is written from: the columns of frames kept in columns
    (:class:`~decoders.modbus.columnar.ColumnarFrames` has them), a row per frame; ``data``:
    where its values start in the batch's bytes."""

    @property
    def function(self) -> npt.NDArray[np.int64]: ...
    @property
    def kind(self) -> npt.NDArray[np.int64]: ...
    @property
    def address(self) -> npt.NDArray[np.int64]: ...
    @property
    def count(self) -> npt.NDArray[np.int64]: ...
    @property
    def read_address(self) -> npt.NDArray[np.int64]: ...
    @property
    def read_count(self) -> npt.NDArray[np.int64]: ...
    @property
    def data(self) -> npt.NDArray[np.int64]: ...
    @property
    def byte_count(self) -> npt.NDArray[np.int64]: ...


def summaries(frames: SummaryColumns, data: bytes) -> list[str]:
    """Each frame's summary line, as its PDU's ``summary()`` writes it (``data``: the batch's)."""
    texts = np.empty(len(frames.kind), object)
    for rows, spelt in _pieces(frames, data):
        texts[rows] = spelt
    said: list[str] = texts.tolist()
    return said


def _pieces(frames: SummaryColumns, data: bytes) -> Iterator[tuple[npt.NDArray[np.int64], list[str]]]:
    """The frames' lines by kind and function, answers by their size too: rows of one width,
    laid out with no field shorter than its column."""
    kind, function = frames.kind, frames.function
    group = ((kind * 256 + function) << 8) + np.where(kind == READ_ANSWER, frames.byte_count, 0)
    for key in distinct(group).tolist():
        rows = np.flatnonzero(group == key)
        yield rows, lines(_fields(frames, data, rows, key >> 16, (key >> 8) & 0xFF), len(rows))


def formatted(template: str, columns: list[Any]) -> list[str]:
    """``template % row`` for every row of ``columns`` (equal lengths: numbers, or texts for
    ``%s``), by one ``%`` of the template repeated with a newline after each (texts must hold
    no newline: the result is cut at them)."""
    count, width = len(columns[0]), len(columns)
    fields: list[Any] = [None] * (count * width)
    for place, column in enumerate(columns):  # row after row, interleaved by slices in C
        fields[place::width] = column if isinstance(column, list) else column.tolist()
    lines = ((template + "\n") * count % tuple(fields)).split("\n")
    lines.pop()  # after the last newline
    return lines


def words_at(raw: npt.NDArray[np.uint8], at: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
    """The big-endian 16-bit word at each of ``at`` in a batch's bytes ``raw``: the words' bytes
    taken, then widened (not the batch's every byte)."""
    words: npt.NDArray[np.int64] = (raw[at].astype(np.int64) << 8) | raw[at + 1]
    return words


def _fields(frames: SummaryColumns, data: bytes, rows: npt.NDArray[np.int64], kind: int,
            function: int) -> list[Field | str]:
    """The fields (for :func:`~decoders.modbus.text_layout.lines`) of the summaries of the frames
    at ``rows``, all of one kind and function (answers of one size): what each frame's PDU's
    ``summary()`` writes."""
    table = TABLE_NAMES.get(function, "")
    address = frames.address[rows]
    if BULK_SHAPES[function] == BULK_SINGLE:  # a request and its echo say the same
        values = words_at(np.frombuffer(data, np.uint8), frames.data[rows])
        if not BIT_VALUES[function]:
            return ["write HR ", decimal(address), " = ", decimal(values), " (0x", upper_hex(values, 4), ")"]
        states = list(COIL_STATES.values())
        state = np.full(len(rows), len(states))  # past the table: nothing, the value is invalid
        for place, value in enumerate(COIL_STATES):
            state[values == value] = place
        invalid = state == len(states)
        return ["write coil ", decimal(address), " = ", chosen(state, [*states, ""]),
                present(invalid, "invalid 0x"), present(invalid, upper_hex(values, 4))]
    if kind == READ_ANSWER and BIT_VALUES[function]:  # of coils or inputs
        size = frames.byte_count[rows]
        return [f"{table} = ", bits(data, frames.data[rows], 8 * size, _SHOWN_BITS), " (", decimal(size), " bytes)"]
    if kind == READ_ANSWER:  # of registers, all of one size (an even one: an odd one is never in columns)
        words = frames.byte_count[rows] // 2
        return [f"{table} = ", *_words(data, frames.data[rows], words), f" ({registers(int(words[0]))})"]
    count = frames.count[rows]
    if kind == WRITE and BIT_VALUES[function]:
        return ["write coils ", *_span(address, count), " = ", bits(data, frames.data[rows], count, _SHOWN_BITS)]
    if kind in (WRITE, READ_WRITE):  # of registers (FC 16, FC 23)
        written = ["write HR ", *_span(address, count), " = ", *_words(data, frames.data[rows], count)]
        if kind == WRITE:
            return written
        read_count = frames.read_count[rows]
        return ["read HR ", *_span(frames.read_address[rows], read_count), " (", decimal(read_count), "), ",
                *written]
    head = f"read {table} " if kind == READ else f"wrote {table} "
    return [head, *_span(address, count), " (", decimal(count), ")"]


def _words(data: bytes, starts: npt.NDArray[np.int64], counts: npt.NDArray[np.int64]) -> list[Field | str]:
    """``000F 03FE``: the first :data:`HEX_WORDS_SHOWN` of the ``counts[i]`` words from byte
    ``starts[i]``, then ``… (+N)`` where there are more, as fields."""
    more = counts > HEX_WORDS_SHOWN
    if not more.any():
        return [hex_words(data, starts, counts)]
    return [hex_words(data, starts, np.minimum(counts, HEX_WORDS_SHOWN)), present(more, " … (+"),
            present(more, decimal(np.maximum(counts - HEX_WORDS_SHOWN, 0))), present(more, ")")]


def _span(address: npt.NDArray[np.int64], count: npt.NDArray[np.int64]) -> list[Field | str]:
    """``3201..3202`` (one register: ``3201``), as fields."""
    more = count != 1
    return [decimal(address), present(more, ".."), present(more, decimal(address + count - 1))]

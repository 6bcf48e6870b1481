"""The summary lines of frames kept in columns, a kind of frame at a time.

A frame's summary depends on its kind (read, answer, write, write's answer) and function; the
frames of one kind and function are summarised by one list comprehension over their columns,
the bits of coils read or written taken from one unpacking of their bytes. The tests hold every
line to the summary of the frame's PDU (the plain path: ``tests/property/test_columnar.py``).

Read requests, register answers of up to eight registers (a polled bus's every frame), coil
answers, write answers, FC 5, FC 6 and FC 15 writes, and FC 16 and FC 23 writes of up to eight
registers are written faster (the others by a comprehension over their columns; the tests
hold both to the PDU's summary). Register answers of one size are rows of one template, each
byte's two digits placed at the same columns of every row; every other kind is laid out field
by field by :mod:`decoders.modbus.text_layout` (numbers' digits, hex words and coils' bits
computed for all rows at once, not formatted from a Python object each), and one ``split``
makes the lines.

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
from decoders.modbus.pdu_text import HEX_WORDS_SHOWN, hex_payload, registers
from decoders.modbus.text_layout import (
    UPPER_HEX,
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
_SHOWN_BYTES = _SHOWN_BITS // 8


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
    """The frames' lines by kind and function."""
    kind, function = frames.kind, frames.function
    group = kind * 256 + function
    for key in distinct(group).tolist():
        rows = np.flatnonzero(group == key)
        kind_of, function_of = key >> 8, key & 0xFF
        bits, single = bool(BIT_VALUES[function_of]), BULK_SHAPES[function_of] == BULK_SINGLE
        if kind_of == READ_ANSWER and not bits:
            yield from _answer_texts(rows, function_of, data, frames)
        elif kind_of in (WRITE, READ_WRITE) and not (bits or single):
            yield from _register_write_texts(rows, kind_of, data, frames)
        elif single or kind_of in (READ, WRITE_ANSWER) or bits:
            yield rows, lines(_fields(frames, data, rows, kind_of, function_of), len(rows))
        else:
            yield rows, _group(frames, data, rows, kind_of, function_of)


def _answer_texts(rows: npt.NDArray[np.int64], function: int, data: bytes,
                  frames: SummaryColumns) -> Iterator[tuple[npt.NDArray[np.int64], list[str]]]:
    """``HR = 0627 04EC (2 registers)`` of the frames at ``rows``; answers of more than
    :data:`HEX_WORDS_SHOWN` registers by the plain path (their byte counts are even: an odd
    one is never kept in columns, :mod:`decoders.modbus.columnar_find`)."""
    size = frames.byte_count[rows]
    plain = size > 2 * HEX_WORDS_SHOWN
    if plain.any():
        yield rows[plain], _group(frames, data, rows[plain], READ_ANSWER, function)
    quick = rows[~plain]
    for at, spelt in _answer_lines(f"{TABLE_NAMES[function]} = ", data, frames.data[quick], size[~plain]):
        yield quick[at], spelt


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


def _answer_lines(head: str, data: bytes, starts: npt.NDArray[np.int64],
                  sizes: npt.NDArray[np.int64]) -> Iterator[tuple[npt.NDArray[np.int64], list[str]]]:
    """``HR = 0627 04EC (2 registers)`` (``head``: ``HR = ``) of each answer's values
    ``data[starts[i] : starts[i] + sizes[i]]`` (even sizes), the answers of each size (each
    piece's rows) laid out by numpy as rows of one template, each byte's two digits at the same
    columns of every row, and cut apart by one ``split``: no ``%`` pass, no byte placed one by
    one."""
    raw = np.frombuffer(data, np.uint8)
    for size in distinct(sizes).tolist():
        rows = np.flatnonzero(sizes == size)
        words = size // 2
        template = f"{head}{' '.join(['0000'] * words)} ({registers(words)})\n"
        text = np.tile(np.frombuffer(template.encode("ascii"), np.uint8), (len(rows), 1))
        values = raw[starts[rows][:, None] + np.arange(size)]
        digits = len(head) + 2 * np.arange(size) + np.arange(size) // 2  # 4 digits and a space a word
        text[:, digits] = UPPER_HEX[values >> 4]
        text[:, digits + 1] = UPPER_HEX[values & 0x0F]
        spelt = text.tobytes().decode("ascii").split("\n")
        spelt.pop()  # after the last line
        yield rows, spelt


def _fields(frames: SummaryColumns, data: bytes, rows: npt.NDArray[np.int64], kind: int,
            function: int) -> list[Field | str]:
    """The fields of the summaries of the frames at ``rows``, all of one kind and function (FC 5
    and FC 6 of either kind, reads and write answers of any function, coil answers and FC 15
    writes), for :func:`~decoders.modbus.text_layout.lines`; ``_group`` spells the same."""
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
    if kind == READ_ANSWER:  # of coils or inputs
        size = frames.byte_count[rows]
        return [f"{table} = ", bits(data, frames.data[rows], 8 * size, _SHOWN_BITS), " (", decimal(size), " bytes)"]
    count = frames.count[rows]
    if kind == WRITE:  # of coils
        return ["write coils ", *_span(address, count), " = ", bits(data, frames.data[rows], count, _SHOWN_BITS)]
    head = f"read {table} " if kind == READ else f"wrote {table} "
    return [head, *_span(address, count), " (", decimal(count), ")"]


def _span(address: npt.NDArray[np.int64], count: npt.NDArray[np.int64]) -> list[Field | str]:
    """``3201..3202`` (one register: ``3201``), as fields."""
    more = count != 1
    return [decimal(address), present(more, ".."), present(more, decimal(address + count - 1))]


def _register_write_texts(rows: npt.NDArray[np.int64], kind: int, data: bytes,
                          frames: SummaryColumns) -> Iterator[tuple[npt.NDArray[np.int64], list[str]]]:
    """``write HR 8501..8502 = 000F 03FE`` (FC 16) or ``read HR 12741..12742 (2), write HR
    12761..12762 = 000F 046C`` (FC 23) of the frames at ``rows``; writes of more than
    :data:`HEX_WORDS_SHOWN` registers by the plain path."""
    count = frames.count[rows]
    plain = count > HEX_WORDS_SHOWN
    if plain.any():
        yield rows[plain], _group(frames, data, rows[plain], kind, frames.function[rows[0]])
    at = rows[~plain]
    if not len(at):
        return
    fields: list[Field | str] = ["write HR ", *_span(frames.address[at], frames.count[at]), " = ",
                                 hex_words(data, frames.data[at], frames.count[at])]
    if kind == READ_WRITE:
        read_count = frames.read_count[at]
        fields = ["read HR ", *_span(frames.read_address[at], read_count), " (", decimal(read_count), "), ", *fields]
    yield at, lines(fields, len(at))


def _group(frames: SummaryColumns, data: bytes, rows: npt.NDArray[np.int64], kind: int, function: int) -> list[str]:
    """The summaries of the frames at ``rows``, all of one kind and function."""
    table = TABLE_NAMES.get(function, "")
    address, count = frames.address[rows].tolist(), frames.count[rows].tolist()
    start, size = frames.data[rows].tolist(), frames.byte_count[rows].tolist()
    if kind == READ:
        return [f"read {table} {a} ({c})" if c == 1 else f"read {table} {a}..{a + c - 1} ({c})"
                for a, c in zip(address, count, strict=True)]
    if kind == READ_ANSWER and not BIT_VALUES[function]:
        return [f"{table} = {hex_payload(data[s : s + n])} ({registers(n // 2)})"
                for s, n in zip(start, size, strict=True)]
    if kind == READ_ANSWER:
        bits = _bit_texts(data, frames.data[rows], 8 * frames.byte_count[rows])
        return [f"{table} = {b} ({n} bytes)" for b, n in zip(bits, size, strict=True)]
    if BULK_SHAPES[function] == BULK_SINGLE:  # a request and its echo say the same
        values = words_at(np.frombuffer(data, np.uint8), frames.data[rows]).tolist()
        if BIT_VALUES[function]:
            return [f"write coil {a} = {COIL_STATES.get(v) or f'invalid 0x{v:04X}'}"
                    for a, v in zip(address, values, strict=True)]
        return [f"write HR {a} = {v} (0x{v:04X})" for a, v in zip(address, values, strict=True)]
    spans = [f"{a}" if c == 1 else f"{a}..{a + c - 1}" for a, c in zip(address, count, strict=True)]
    if kind == READ_WRITE:
        reads = zip(frames.read_address[rows].tolist(), frames.read_count[rows].tolist(), strict=True)
        return [f"read HR {a if c == 1 else f'{a}..{a + c - 1}'} ({c}), write HR {span} = "
                f"{hex_payload(data[s : s + 2 * n])}" for (a, c), span, s, n in zip(reads, spans, start, count,
                                                                                     strict=True)]
    if kind == WRITE_ANSWER:
        return [f"wrote {table} {span} ({c})" for span, c in zip(spans, count, strict=True)]
    if BIT_VALUES[function]:
        bits = _bit_texts(data, frames.data[rows], frames.count[rows])
        return [f"write coils {span} = {b}" for span, b in zip(spans, bits, strict=True)]
    return [f"write HR {span} = {hex_payload(data[s : s + 2 * c])}" for span, s, c in zip(spans, start, count,
                                                                                          strict=True)]


def _bit_texts(data: bytes, starts: npt.NDArray[np.int64], counts: npt.NDArray[np.int64]) -> list[str]:
    """The first ``counts[i]`` bits from byte ``starts[i]``, least significant first, as ``0`` and
    ``1`` (``_bit_string`` of :mod:`decoders.modbus.pdu`): at most 32, then "…"."""
    raw = np.frombuffer(data, np.uint8)
    # The first 4 bytes of each (past the data's end: any byte, never shown).
    at = np.minimum(starts[:, None] + np.arange(_SHOWN_BYTES), len(raw) - 1)
    text = (np.unpackbits(raw[at], axis=1, bitorder="little") + ord("0")).tobytes().decode("ascii")
    shown = np.minimum(counts, _SHOWN_BITS).tolist()
    return [text[_SHOWN_BITS * row : _SHOWN_BITS * row + n] + ("…" if n < c else "")
            for row, (n, c) in enumerate(zip(shown, counts.tolist(), strict=True))]

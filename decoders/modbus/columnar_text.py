"""The summary lines of frames kept in columns, a kind of frame at a time.

A frame's summary depends on its kind (read, answer, write, write's answer) and function; the
frames of one kind and function are summarised by one list comprehension over their columns,
the bits of coils read or written taken from one unpacking of their bytes. The tests hold every
line to the summary of the frame's PDU (the plain path: ``tests/property/test_columnar.py``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from decoders.modbus.pdu import COIL_OFF, COIL_ON
from decoders.modbus.pdu_text import hex_payload

if TYPE_CHECKING:
    from decoders.modbus.columnar import ColumnarFrames

#: What a frame kept in columns is: a read request (FC 1-4), its answer, a write request
#: (FC 5, 6, 15, 16; kept only with its answer), its answer.
READ, READ_ANSWER, WRITE, WRITE_ANSWER = 0, 1, 2, 3
_TABLES = {1: "coils", 2: "inputs", 3: "HR", 4: "IR", 15: "coils", 16: "HR"}
_SHOWN_BITS = 32  # a summary writes 32 bits, then "…"
_SHOWN_BYTES = _SHOWN_BITS // 8
_COIL_STATES = {COIL_ON: "ON", COIL_OFF: "OFF"}


def summaries(frames: ColumnarFrames, data: bytes) -> list[str]:
    """Each frame's summary line, as its PDU's ``summary()`` writes it (``data``: the batch's)."""
    kind, function = frames.kind, frames.function
    texts = np.empty(len(kind), object)
    group = kind * 256 + function
    for key in np.unique(group).tolist():
        rows = np.flatnonzero(group == key)
        texts[rows] = _group(frames, data, rows, key >> 8, key & 0xFF)
    lines: list[str] = texts.tolist()
    return lines


def _group(frames: ColumnarFrames, data: bytes, rows: npt.NDArray[np.int64], kind: int, function: int) -> list[str]:
    """The summaries of the frames at ``rows``, all of one kind and function."""
    table = _TABLES.get(function, "")
    address, count = frames.address[rows].tolist(), frames.count[rows].tolist()
    start, size = frames.data[rows].tolist(), frames.byte_count[rows].tolist()
    if kind == READ:
        return [f"read {table} {a} ({c})" if c == 1 else f"read {table} {a}..{a + c - 1} ({c})"
                for a, c in zip(address, count, strict=True)]
    if kind == READ_ANSWER and function >= 3:
        return [f"{table} = {hex_payload(data[s : s + n])} ({n // 2} registers)"
                for s, n in zip(start, size, strict=True)]
    if kind == READ_ANSWER:
        bits = _bit_texts(data, frames.data[rows], 8 * frames.byte_count[rows])
        return [f"{table} = {b} ({n} bytes)" for b, n in zip(bits, size, strict=True)]
    if function in (5, 6):  # a request and its echo say the same
        raw = np.frombuffer(data, np.uint8).astype(np.int64)
        at = frames.data[rows]
        values = ((raw[at] << 8) | raw[at + 1]).tolist()
        if function == 5:
            return [f"write coil {a} = {_COIL_STATES.get(v) or f'invalid 0x{v:04X}'}"
                    for a, v in zip(address, values, strict=True)]
        return [f"write HR {a} = {v} (0x{v:04X})" for a, v in zip(address, values, strict=True)]
    spans = [f"{a}" if c == 1 else f"{a}..{a + c - 1}" for a, c in zip(address, count, strict=True)]
    if kind == WRITE_ANSWER:
        return [f"wrote {table} {span} ({c})" for span, c in zip(spans, count, strict=True)]
    if function == 15:
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

"""The summary column of the Parquet ``frames`` and ``anomalies`` tables.

Every message's summary line by position: a decoded message's own, a frame left in columns
(``AnnotatedBatch.columnar``) the one its columns spell (:mod:`sniffer.encoding.columnar_parts`,
once per group of frames alike). Frames whose profile names their values end their lines with
the names' texts (``HR = 05DC (1 register): NM1→ETA = 16#05DC warning, …``); for JSONL and
MCAP :meth:`~decoders.modbus.columnar.ColumnarNames.suffixed` writes each line as a Python
string, and the Parquet column then read them all again. Here Arrow joins them from their
parts instead (:func:`_named_lines`): the frames' lines as their PDUs write them, and a column
per place of the named texts they show (taken from the small table of the batch's named texts),
joined with the ``: `` or ``, `` before each by one ``binary_join_element_wise`` for the
frames showing as many; one ``take`` then lays out every message's line, those decoded one by
one among them: less work than Python strings read by the column again, where frames show names.

The lines as PDUs write them come in pieces, a kind of frame at a time
(:func:`~decoders.modbus.columnar_text.summary_pieces`), and those numpy lays out come packed as
a string column's buffers (:class:`~decoders.modbus.text_layout.PackedLines`): the column is
made of their bytes, no Python string per line, and one ``take`` orders them with the rest.
Arrow's functions are called by name
(:mod:`sniffer.exports.arrow_compute`): no export imports ``pyarrow.compute``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
import pyarrow as pa

from decoders.decoded_batch import SHOWN_PARAMS, AnnotatedBatch, Lines
from decoders.distinct import distinct
from sniffer.encoding.columnar_parts import columnar_parts
from sniffer.exports.arrow_compute import arrow_call, taken

_FIRST, _AFTER, _MORE, _NOTHING = (pa.scalar(text, pa.string()) for text in (": ", ", ", " …", ""))


class Summaries:
    """Every message's summary line of a batch, by position: Python strings, or an Arrow column
    where Arrow joined them."""

    def __init__(self, texts: npt.NDArray[np.object_] | None = None, column: pa.Array | None = None) -> None:
        self._texts, self._column = texts, column

    def of(self, rows: npt.NDArray[np.int64] | None = None) -> pa.Array:
        """The lines of the messages at ``rows`` (any of them, any number of times; ``None``:
        every message, in order), as a column."""
        if self._column is not None:
            return self._column if rows is None else taken(self._column, rows)
        assert self._texts is not None
        texts = self._texts if rows is None else self._texts[rows]
        # From a list: pyarrow reads one faster than an object array.
        return pa.array(texts.tolist(), pa.string())


def summaries(batch: AnnotatedBatch) -> Summaries:
    """Every message's summary line of ``batch`` (see the module docstring)."""
    decodings, columnar = batch.decoded, batch.columnar  # those in columns: spelt from the columns
    if columnar is None:
        texts = np.empty(len(decodings), object)
        texts[:] = [decoding.summary for decoding in decodings]
        return Summaries(texts)
    decoded = np.ones(len(decodings), np.bool_)
    decoded[columnar.positions] = False
    rows = np.flatnonzero(decoded)
    plain = [decodings[row].summary for row in rows.tolist()]
    parts = columnar_parts(columnar, batch.messages)
    base, spelt_at = _base_lines(parts.base_summary_pieces())
    shown = parts.spelt.shown_names()
    lines, place = (base, spelt_at) if shown is None else _named_lines(base, spelt_at, *shown)
    where = np.empty(len(decodings), np.int64)
    where[columnar.positions] = place if parts.inverse is None else place[parts.inverse]
    where[rows] = len(lines) + np.arange(len(rows))
    return Summaries(column=taken(pa.concat_arrays([lines, pa.array(plain, pa.string())]), where))


def _base_lines(pieces: list[tuple[npt.NDArray[np.int64], Lines]]) -> tuple[pa.Array, npt.NDArray[np.int64]]:
    """The lines of the pieces (:meth:`~sniffer.encoding.columnar_parts.ColumnarParts.base_summary_pieces`)
    one after the other as a column, packed ones taken as their buffers are; and where each
    frame's line is in it."""
    columns = [_column(lines) for _, lines in pieces]
    rows = np.concatenate([rows for rows, _ in pieces]) if pieces else np.zeros(0, np.int64)
    at = np.empty(len(rows), np.int64)
    at[rows] = np.arange(len(rows))
    return (pa.concat_arrays(columns) if columns else pa.array([], pa.string())), at


def _column(lines: Lines) -> pa.Array:
    """``lines`` as a string column: packed ones as their buffers are, no Python string made."""
    if isinstance(lines, list):
        return pa.array(lines, pa.string())
    return pa.Array.from_buffers(pa.string(), len(lines), [None, pa.py_buffer(lines.offsets), pa.py_buffer(lines.data)])


def _named_lines(base: pa.Array, base_at: npt.NDArray[np.int64], named_texts: list[str | None],
                 entries: npt.NDArray[np.int64],
                 counts: npt.NDArray[np.int64]) -> tuple[pa.Array, npt.NDArray[np.int64]]:
    """The lines of frames followed by the named values they show, as
    :func:`~decoders.profiles.naming.summary_with` writes them (``base``: the frames' lines as
    their PDUs write them, frame ``i``'s at ``base_at[i]``; ``named_texts``, ``entries``, ``counts``:
    :meth:`~decoders.modbus.columnar.ColumnarNames.shown`), the frames that show as many laid
    out together; and where each frame's line is among them."""
    texts = pa.array(named_texts, pa.string())
    starts = np.cumsum(counts) - counts
    pieces: list[Any] = []
    place = np.empty(len(base_at), np.int64)
    laid = 0
    for count in distinct(counts).tolist():
        frames = np.flatnonzero(counts == count)
        line = taken(base, base_at[frames])
        if count:
            # Each named text shown with what comes before it: ": " the first, ", " each after it.
            shown = []
            for at in range(min(count, SHOWN_PARAMS)):
                shown += [_AFTER if at else _FIRST, taken(texts, entries[starts[frames] + at])]
            more = [_MORE] if count > SHOWN_PARAMS else []
            line = arrow_call("binary_join_element_wise", line, *shown, *more, _NOTHING)
        pieces.append(line)
        place[frames] = laid + np.arange(len(frames))
        laid += len(frames)
    return pa.concat_arrays(pieces), place

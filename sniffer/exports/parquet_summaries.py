"""The summary column of the Parquet ``frames`` and ``anomalies`` tables.

Every message's summary line by position: a decoded message's own, a frame left in columns
(``AnnotatedBatch.columnar``) the one its columns spell (:mod:`sniffer.encoding.columnar_parts`,
once per group of frames alike), as JSONL and MCAP spell it.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pyarrow as pa

from decoders.decoded_batch import AnnotatedBatch
from sniffer.encoding.columnar_parts import columnar_parts


class Summaries:
    """Every message's summary line of a batch, by position."""

    def __init__(self, texts: npt.NDArray[np.object_]) -> None:
        self._texts = texts

    def of(self, rows: npt.NDArray[np.int64] | None = None) -> pa.Array:
        """The lines of the messages at ``rows`` (any of them, any number of times; ``None``:
        every message, in order), as a column."""
        texts = self._texts if rows is None else self._texts[rows]
        # From a list: pyarrow reads one faster than an object array.
        return pa.array(texts.tolist(), pa.string())

    def texts(self) -> list[str]:
        """Every message's line, in order."""
        lines: list[str] = self._texts.tolist()
        return lines


def summaries(batch: AnnotatedBatch) -> Summaries:
    """Every message's summary line of ``batch`` (see the module docstring)."""
    decodings, columnar = batch.decoded, batch.columnar  # those in columns: spelt from the columns
    texts = np.empty(len(decodings), object)
    if columnar is None:
        texts[:] = [decoding.summary for decoding in decodings]
        return Summaries(texts)
    decoded = np.ones(len(decodings), np.bool_)
    decoded[columnar.positions] = False
    rows = np.flatnonzero(decoded)
    texts[rows] = [decodings[row].summary for row in rows.tolist()]
    texts[columnar.positions] = columnar_parts(columnar, batch.messages).summaries()
    return Summaries(texts)

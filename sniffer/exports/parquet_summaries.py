"""The summary column of the Parquet ``frames`` and ``anomalies`` tables.

Every message's summary line by position (:meth:`decoders.decoded_batch.AnnotatedBatch.summaries`,
which pcapng comments and the table read too).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pyarrow as pa

from decoders.decoded_batch import AnnotatedBatch


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


def summaries(batch: AnnotatedBatch) -> Summaries:
    """Every message's summary line of ``batch`` (every frame delivered: an export filters none)."""
    assert batch.rows is None, "a dataset holds every frame delivered: nothing filters them"
    texts = np.empty(len(batch.messages), object)
    texts[:] = batch.summaries()
    return Summaries(texts)

"""A decoded batch: framed and paired messages in columns with what each says.

The one form the annotator hands to every output (``Sink.messages``); built low in
``decoders/`` so that every output and every decoder can name it without a cycle.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from decoders.message import Decoding, Message, MessageBatch
from decoders.modbus.columnar import ColumnarFrames


@dataclass(frozen=True, slots=True)
class AnnotatedBatch:
    """Decoded messages in columns: a :class:`MessageBatch` and each message's decoding.

    ``rows``: the positions a filter kept, ``None`` for all. Iterating yields the kept
    messages as objects; sinks that can stay in columns read ``messages`` and ``decodings``.
    ``columnar``: the frames left in columns (:meth:`Annotator.annotate_columnar`, only for
    sinks that take them): their decodings are :data:`IN_COLUMNS`, and ``rows`` leaves them out.
    """

    messages: MessageBatch
    decodings: list[Decoding]
    rows: npt.NDArray[np.int64] | None = None
    columnar: ColumnarFrames | None = None

    def __len__(self) -> int:
        return len(self.decodings) if self.rows is None else len(self.rows)

    def __iter__(self) -> Iterator[Message]:
        messages = self.messages.rows()
        for position in self.positions():
            message = messages[position]
            message.decoding = self.decodings[position]  # fresh from the batch: set rather than copied
            yield message

    def positions(self) -> list[int]:
        """The kept positions, in order."""
        return list(range(len(self.decodings))) if self.rows is None else self.rows.tolist()

    def record_positions(self) -> list[int]:
        """The positions of the messages a sink writes a record of: the kept ones, and those
        left in columns (every message: frames are left in columns only where nothing filters)."""
        return list(range(len(self.messages))) if self.columnar is not None else self.positions()

    def decodings_at(self, positions: list[int]) -> list[Decoding]:
        """The decodings at ``positions`` (ordered and distinct, as :meth:`positions` gives them:
        all of them when as many)."""
        if len(positions) == len(self.decodings):
            return self.decodings
        return list(map(self.decodings.__getitem__, positions))

    def select(self, keep: npt.NDArray[np.bool_]) -> AnnotatedBatch:
        """Only the messages where ``keep`` (one flag per message of ``messages``) is true."""
        rows = np.flatnonzero(keep)
        if self.rows is not None:
            rows = np.intersect1d(rows, self.rows)
        return AnnotatedBatch(self.messages, self.decodings, rows.astype(np.int64))

"""Hypothesis: statistics do not depend on how the messages are cut into batches.

The reference is one batch holding the whole capture; the same messages cut into
random batches (as the framer delivers them from reads of any size) must add up to
the same figures, field for field.
"""

from __future__ import annotations

from functools import cache

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.capture import ChunkBatch
from decoders.frame import concat_frames, slice_frames
from decoders.message import MessageBatch
from decoders.pipeline import Decoder
from decoders.stats import Statistics
from tests.corpus import LINES, SCENARIOS, build


@cache
def whole_capture() -> MessageBatch:
    """The 'everything' corpus decoded as one message batch."""
    corpus = build(SCENARIOS[-1], LINES[1], exchanges=120)
    decoder = Decoder(corpus.line, corpus.timing)
    batches = [b for b in (*decoder.feed(ChunkBatch.from_chunks(corpus.chunks)), *decoder.flush()) if len(b)]
    return MessageBatch(
        concat_frames([b.frames for b in batches]),
        *(np.concatenate([getattr(b, name) for b in batches]) for name in _COLUMNS),
    )


_COLUMNS = ("role", "slave", "function", "exception_code", "flags", "request_index", "latency_ns")


def _slice(batch: MessageBatch, start: int, stop: int) -> MessageBatch:
    return MessageBatch(slice_frames(batch.frames, start, stop),
                        *(getattr(batch, name)[start:stop] for name in _COLUMNS))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(1, 400), min_size=1, max_size=40))
def test_statistics_over_random_batch_splits(sizes: list[int]) -> None:
    whole = whole_capture()
    reference = Statistics()
    reference.add_batch(whole)
    split = Statistics()
    position, turn = 0, 0
    while position < len(whole):
        size = sizes[turn % len(sizes)]
        split.add_batch(_slice(whole, position, min(len(whole), position + size)))
        position += size
        turn += 1
    assert split.to_dict() == reference.to_dict()

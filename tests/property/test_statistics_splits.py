"""Hypothesis: statistics do not depend on how the messages are cut into batches.

The reference is one batch holding the whole capture; the same messages cut into
random batches (as the framer delivers them from reads of any size) must add up to
the same figures, field for field. And the counters of each slave and function are those of
counting the messages one by one, for any mix of role, CRC and flags.
"""

from __future__ import annotations

from dataclasses import replace
from functools import cache
from random import Random

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.capture import ChunkBatch
from decoders.frame import FrameFlag, concat_frames, slice_frames
from decoders.message import ROLE_ORDER, MessageBatch, Role
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


def _counted_one_by_one(batch: MessageBatch) -> dict[tuple[int, int], dict[str, int]]:
    """The counters per slave and function, one message at a time."""
    pairs: dict[tuple[int, int], dict[str, int]] = {}
    flag_names = {"timeouts": FrameFlag.TIMEOUT, "retries": FrameFlag.RETRY, "unexpected": FrameFlag.UNEXPECTED,
                  "gap_1_5": FrameFlag.GAP_1_5, "short_idle": FrameFlag.SHORT_IDLE}
    columns = zip(batch.role.tolist(), batch.slave.tolist(), batch.function.tolist(), batch.flags.tolist(),
                  batch.frames.crc_ok.tolist(), strict=True)
    for role, slave, function, flags, crc_ok in columns:
        if ROLE_ORDER[role] is Role.NOISE or slave < 0 or function < 0:
            continue
        counters = pairs.setdefault((slave, function), {})
        for name, counts in (("requests", ROLE_ORDER[role] is Role.REQUEST),
                             ("responses", ROLE_ORDER[role] is Role.RESPONSE),
                             ("broadcasts", ROLE_ORDER[role] is Role.BROADCAST), ("crc_errors", not crc_ok),
                             *((name, bool(flags & flag)) for name, flag in flag_names.items())):
            counters[name] = counters.get(name, 0) + counts
    return pairs


@settings(max_examples=40, deadline=None)
@given(st.randoms(use_true_random=False))
def test_the_counters_are_those_of_counting_each_message(random: Random) -> None:
    """Every mix of role, CRC and flags (the capture's columns shuffled apart) is counted as
    counting message by message counts it."""
    whole = whole_capture()
    order = [list(range(len(whole))) for _ in range(3)]
    for column in order:
        random.shuffle(column)
    flags = whole.flags[order[2]] | np.array([random.choice([0, 1, 2, 16, 32, 64, 255]) for _ in range(len(whole))],
                                             np.uint16)
    frames = replace(whole.frames, crc_ok=whole.frames.crc_ok[order[1]])
    mixed = replace(whole, frames=frames, role=whole.role[order[0]], flags=flags)
    statistics = Statistics()
    statistics.add_batch(mixed)
    names = ("requests", "responses", "broadcasts", "crc_errors", "timeouts", "retries", "unexpected", "gap_1_5",
             "short_idle")
    got = {key: {name: getattr(stats, name) for name in names} for key, stats in statistics.per_function.items()}
    assert got == _counted_one_by_one(mixed)

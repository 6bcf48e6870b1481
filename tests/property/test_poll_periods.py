"""Hypothesis: the bookkeeping of poll periods (:mod:`decoders.stats`) groups requests as a
lexicographic sort does, by its radix path and by its fallbacks, and its table of when each
request was last seen gives a shared slot to the request seen last, whatever order it is told."""

from __future__ import annotations

from functools import cache

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.stats import NONE, LastSeen, _by_signature_then_time, _mixed, _slots


@cache
def _sharing(kind: str) -> tuple[int, int]:
    """Two signatures whose LastSeen slot (``"slot"``) or whose 32-bit sort hash (``"hash"``) is one."""
    # Random signatures: a hash spreads an arithmetic progression out without any two meeting.
    candidates = np.unique(np.random.default_rng(7).integers(-(2**63), 2**63 - 1, 1 << 19))
    keys = _slots(candidates) if kind == "slot" else (_mixed(candidates) >> np.uint64(32)).astype(np.int64)
    order = np.argsort(keys, kind="stable")
    same = np.flatnonzero(keys[order][1:] == keys[order][:-1])[0]
    return int(candidates[order[same]]), int(candidates[order[same + 1]])


def _runs(signatures: np.ndarray, order: np.ndarray) -> dict[int, list[int]]:  # type: ignore[type-arg]
    """The positions of each signature's requests, in the order given; checking that each
    signature's requests are together."""
    runs: dict[int, list[int]] = {}
    if not len(order):
        return runs
    grouped = signatures[order]
    starts = np.flatnonzero(grouped != np.roll(grouped, 1))
    starts = starts if len(starts) and starts[0] == 0 else np.array([0, *starts])
    for start, stop in zip(starts.tolist(), [*starts[1:].tolist(), len(order)], strict=True):
        signature = int(grouped[start])
        assert signature not in runs, "a signature's requests are split"
        runs[signature] = order[start:stop].tolist()
    return runs


_pool = st.lists(st.integers(-(2**63), 2**63 - 1), min_size=1, max_size=6)


@settings(max_examples=200, deadline=None)
@given(_pool, st.booleans(), st.booleans(),
       st.lists(st.tuples(st.integers(0, 7), st.integers(0, 50)), max_size=300), st.booleans())
def test_requests_are_grouped_as_lexsort_groups_them(pool: list[int], slot_pair: bool, hash_pair: bool,
                                                     drawn: list[tuple[int, int]], in_order: bool) -> None:
    pool = [*(_sharing("slot") if slot_pair else ()), *(_sharing("hash") if hash_pair else ()), *pool]
    signatures = np.array([pool[which % len(pool)] for which, _ in drawn], np.int64)
    steps = np.array([step for _, step in drawn], np.int64)
    times = np.cumsum(steps) if in_order else steps  # in order (ties too), or not
    order = _by_signature_then_time(signatures, times)
    assert sorted(order.tolist()) == list(range(len(drawn)))
    assert _runs(signatures, order) == _runs(signatures, np.lexsort((times, signatures)))


@settings(max_examples=100, deadline=None)
@given(st.permutations(range(4)), st.lists(st.integers(0, 10**9), min_size=4, max_size=4, unique=True))
def test_a_shared_slot_goes_to_the_request_seen_last(told: list[int], times: list[int]) -> None:
    first, second = _sharing("slot")
    other, another = 5, 7 << 40  # two signatures of slots of their own
    signatures = np.array([first, second, other, another], np.int64)
    assert len({*_slots(signatures[1:]).tolist()}) == 3
    table = LastSeen()
    table.store(signatures[told], np.array(times, np.int64)[told])
    found = table.lookup(signatures).tolist()
    latest = 0 if times[0] > times[1] else 1
    assert found[latest] == times[latest] and found[1 - latest] == NONE
    assert found[2:] == times[2:]

"""The two-generation memo: bounded, and what is used stays."""

from __future__ import annotations

from decoders.memo import Memo


def test_bounded_to_two_generations() -> None:
    memo: Memo[int, str] = Memo(4)
    for key in range(100):
        memo.put(key, str(key))
        assert len(memo) <= 8
    assert memo.get(99) == "99"
    assert memo.get(0) is None  # a one-off, long forgotten


def test_what_is_used_stays_and_one_offs_go() -> None:
    memo: Memo[str, int] = Memo(4)
    memo.put("status", 1)
    for key in range(1000):
        assert memo.get("status") == 1  # a hit in the old generation moves back to the young one
        memo.put(f"value {key}", key)
    assert memo.get("value 3") is None
    assert memo.get("value 999") == 999

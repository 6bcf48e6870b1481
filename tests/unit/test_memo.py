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


def test_get_all_builds_each_missing_key_once() -> None:
    """A batch: young hits, an old-generation hit, and a new key that comes twice."""
    memo: Memo[str, str] = Memo(2)
    memo.put("old", "OLD")
    memo.put("a", "A")
    memo.put("b", "B")  # "old" and "a" are now the old generation
    built: list[int] = []

    def build(row: int) -> str:
        built.append(row)
        return keys[row].upper()

    keys = ["b", "old", "new", "b", "new"]
    assert memo.get_all(keys, build) == ["B", "OLD", "NEW", "B", "NEW"]
    assert built == [2]  # "new" at row 4 found what row 2 built
    assert memo.get_all(["b", "new"], build) == ["B", "NEW"] and built == [2]

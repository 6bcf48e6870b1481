"""The two-generation memo: bounded, and what is used stays."""

from __future__ import annotations

from collections.abc import Callable
from typing import cast

from hypothesis import given
from hypothesis import strategies as st

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



def reference_get_all(memo: Memo[int, str], keys: list[int], build: Callable[[int], str]) -> list[str]:
    """:meth:`Memo.get_all` through ``get`` and ``put``: what it did before they were inlined."""
    values = list(map(memo._young.get, keys))
    for row, value in enumerate(values):
        if value is None:
            found = memo.get(keys[row])
            if found is None:
                found = build(row)
                memo.put(keys[row], found)
            values[row] = found
    return cast(list[str], values)


@given(st.integers(1, 4), st.lists(st.lists(st.integers(0, 12), max_size=12), max_size=6))
def test_get_all_is_its_plain_form(size: int, batches: list[list[int]]) -> None:
    """The batch lookup (get and put inlined for speed) against the plain one: the same values,
    the same keys built, the same generations after every batch (they roll over mid-batch)."""
    fast: Memo[int, str] = Memo(size)
    plain: Memo[int, str] = Memo(size)
    for keys in batches:
        built: dict[str, list[int]] = {"fast": [], "plain": []}

        def builder(name: str, keys: list[int] = keys, built: dict[str, list[int]] = built) -> Callable[[int], str]:
            def build(row: int) -> str:
                built[name].append(keys[row])
                return f"v{keys[row]}"
            return build

        assert fast.get_all(keys, builder("fast")) == reference_get_all(plain, keys, builder("plain"))
        assert built["fast"] == built["plain"]
        assert (fast._young, fast._old) == (plain._young, plain._old)

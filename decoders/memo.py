"""A memo that forgets in bulk, for what is built once per distinct frame.

Two generations: when the young one is full it becomes the old one and the oldest is dropped;
a hit in the old generation moves back to the young one. Entries in use all day (a drive's
status answer) stay; the rest go, with no per-entry bookkeeping on the hot path.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

#: Decodings the annotator keeps for repeats, per generation: what a bus repeats stays while
#: one-off frames pass through. Sinks that derive something per decoding keep as many, so that
#: a repeat finds its parts.
KEPT_DECODINGS = 8192

Key = TypeVar("Key", bound=Hashable)
Value = TypeVar("Value")


class Memo(Generic[Key, Value]):
    """At most ``2 × size`` entries; ``get`` answers ``None`` for what it does not hold."""

    def __init__(self, size: int) -> None:
        self.size = size
        self._young: dict[Key, Value] = {}
        self._old: dict[Key, Value] = {}

    def get(self, key: Key) -> Value | None:
        value = self._young.get(key)
        if value is None:
            value = self._old.get(key)
            if value is not None:
                self.put(key, value)
        return value

    def older(self, key: Key) -> Value | None:
        """:meth:`get` for a key the young generation was just asked for (through :meth:`recent`)."""
        value = self._old.get(key)
        if value is not None:
            self.put(key, value)
        return value

    def recent(self) -> Callable[[Key], Value | None]:
        """The young generation's lookup, to ``map`` over a batch in C: what it misses (``None``),
        ``get`` answers. Valid until the next ``put``."""
        return self._young.get

    def put(self, key: Key, value: Value) -> None:
        if len(self._young) >= self.size:
            self._old, self._young = self._young, {}
        self._young[key] = value

    def __len__(self) -> int:
        return len(self._young) + len(self._old)

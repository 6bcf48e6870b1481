"""Memos that forget in bulk, for what is built once per distinct frame or param.

:class:`Memo`: two generations; when the young one is full it becomes the old one and the oldest
is dropped; a hit in the old generation moves back to the young one. Entries in use all day (a
drive's status answer) stay; the rest go, with no per-entry bookkeeping on the hot path.

:class:`KeptByIdentity`: what is made of objects that do not hash by value (a param, the params
of a frame), kept by the object's identity: a profile's namer hands the same param to every
frame with that value, frames alike share their params.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from operator import itemgetter
from typing import Any, Generic, TypeVar

#: Decodings the annotator keeps for repeats, per generation: what a bus repeats stays while
#: one-off frames pass through. Sinks that derive something per decoding keep as many, so that
#: a repeat finds its parts.
KEPT_DECODINGS = 8192

#: Objects :class:`KeptByIdentity` keeps at most, unless told otherwise; all are let go past it.
KEPT_OBJECTS = 65536

Key = TypeVar("Key", bound=Hashable)
Value = TypeVar("Value")
Thing = TypeVar("Thing")
Made = TypeVar("Made")
_SECOND = itemgetter(1)


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


class KeptByIdentity(Generic[Thing, Made]):
    """What ``make`` makes of each object, made once per object and kept by its identity: the
    object stays alive here, so its id is not reused while kept. All are let go at ``most``."""

    def __init__(self, make: Callable[[Thing], Made], most: int = KEPT_OBJECTS) -> None:
        self._make, self.most = make, most
        #: By the object's identity: the object and what was made of it (writers look it up in
        #: C, in a comprehension, and call :meth:`entry` for what is missing).
        self.kept: dict[int, tuple[Thing, Made]] = {}

    def entry(self, thing: Thing) -> tuple[Thing, Made]:
        """``thing`` and what was made of it (made and kept now where new)."""
        kept = self.kept.get(id(thing))
        if kept is None:
            if len(self.kept) >= self.most:
                self.kept.clear()
            kept = self.kept[id(thing)] = (thing, self._make(thing))
        return kept

    def of(self, thing: Thing) -> Made:
        """What was made of ``thing``."""
        return self.entry(thing)[1]

    def made(self, things: list[Thing]) -> list[Made]:
        """What was made of each of ``things`` (made and kept now where new): the kept ones looked
        up in C (a batch's table of named values is thousands, mostly kept already)."""
        found: list[Any] = list(map(self.kept.get, map(id, things)))
        for place in [place for place, entry in enumerate(found) if entry is None]:
            found[place] = self.entry(things[place])
        made: list[Made] = list(map(_SECOND, found))  # none is None now
        return made

"""``--filter KEY=VALUE``: which frames ``analyze`` shows.

Keys: ``slave`` (0-247), ``function`` (1-127), ``role`` (request, response, exception,
broadcast, noise, unknown), ``flag`` (a JSONL flag name). Values of one key are
alternatives (``slave=2 slave=3`` shows both); different keys must all match.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from decoders.frame import FrameFlag
from decoders.message import ROLE_CODE, MessageBatch, Role
from sniffer.errors import ErrorKind, RtuSniffError

FLAG_NAMES = {name: flag for flag in FrameFlag if flag for name in flag.names}
ROLE_NAMES = {role.value: role for role in Role}


@dataclass(frozen=True)
class MessageFilter:
    """Alternatives per key; an empty filter lets everything through."""

    slaves: frozenset[int] = frozenset()
    functions: frozenset[int] = frozenset()
    roles: frozenset[Role] = frozenset()
    flags: FrameFlag = FrameFlag.NONE

    def __call__(self, batch: MessageBatch) -> npt.NDArray[np.bool_]:
        """Which messages of ``batch`` pass."""
        keep = np.ones(len(batch), np.bool_)
        if self.slaves:
            keep &= np.isin(batch.slave, list(self.slaves))
        if self.functions:
            keep &= np.isin(batch.function, list(self.functions))
        if self.roles:
            keep &= np.isin(batch.role, [ROLE_CODE[role] for role in self.roles])
        if self.flags:
            keep &= (batch.flags & int(self.flags)) != 0
        return keep

    @property
    def empty(self) -> bool:
        return not (self.slaves or self.functions or self.roles or self.flags)


def _number(key: str, low: int, high: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text, 0)
        except ValueError:
            value = -1
        if not low <= value <= high:
            raise RtuSniffError(ErrorKind.USAGE, f"--filter {key}={text}: {key} must be a number from {low} to {high}")
        return value

    return parse


def _choice(key: str, names: dict[str, object]) -> Callable[[str], object]:
    def parse(text: str) -> object:
        if text not in names:
            raise RtuSniffError(ErrorKind.USAGE, f"--filter {key}={text}: {key} is one of {', '.join(names)}")
        return names[text]

    return parse


def parse_filters(specs: Sequence[str]) -> MessageFilter:
    """``["slave=2", "flag=timeout"]`` → a filter; errors say what is allowed."""
    parsers: dict[str, Callable[[str], object]] = {
        "slave": _number("slave", 0, 247),
        "function": _number("function", 1, 127),
        "role": _choice("role", dict(ROLE_NAMES)),
        "flag": _choice("flag", dict(FLAG_NAMES)),
    }
    values: dict[str, set[object]] = {key: set() for key in parsers}
    for spec in specs:
        key, sep, text = spec.partition("=")
        if not sep or key not in parsers:
            raise RtuSniffError(
                ErrorKind.USAGE, f"--filter {spec}: use KEY=VALUE with KEY one of {', '.join(parsers)}"
            )
        values[key].add(parsers[key](text))
    flags = FrameFlag.NONE
    for flag in values["flag"]:
        assert isinstance(flag, FrameFlag)
        flags |= flag
    return MessageFilter(
        slaves=frozenset(v for v in values["slave"] if isinstance(v, int)),
        functions=frozenset(v for v in values["function"] if isinstance(v, int)),
        roles=frozenset(v for v in values["role"] if isinstance(v, Role)),
        flags=flags,
    )

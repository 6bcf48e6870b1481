"""``--filter``: which frames a command shows.

Keys (``KEY=VALUE``; values of one key are alternatives, different keys must all match):

=================  ===========================================================================
``slave=N``        slave address 0-247
``function=N``     function code 1-127
``role=NAME``      request, response, exception, broadcast, noise, unknown
``flag=NAME``      a JSONL flag (timeout, retry, gap_1_5, …)
``crc=ok|bad``     frames whose CRC is right or wrong (noise has none)
``exception=CODE`` exception responses with this code (1-255, ``0x0B`` too)
``address=N``      frames that name register or coil N, or any of ``A-B``; an answer matches
                   when its request does (an exception to a read of N too)
``param=CODE``     frames naming a device profile's parameter (``ETA``, ``LFR``), as ``address``
``latency>MS``     answers later than MS milliseconds (also ``<``, ``>=``, ``<=``)
=================  ===========================================================================

Addresses are the register numbers on the wire (from 0), as the summaries write them.
"""

from __future__ import annotations

import operator
import re
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from decoders.decoded_batch import AnnotatedBatch
from decoders.frame import FrameFlag
from decoders.message import NONE, ROLE_CODE, Role
from sniffer.errors import ErrorKind, RtuSniffError

FLAG_NAMES = {name: flag for flag in FrameFlag if flag for name in flag.names}
ROLE_NAMES = {role.value: role for role in Role}
COMPARISONS: dict[str, Callable[[Any, Any], Any]] = {
    ">=": operator.ge, "<=": operator.le, ">": operator.gt, "<": operator.lt}
_SPEC = re.compile(r"([a-z_]+)(>=|<=|=|>|<)(.*)", re.DOTALL)
#: Requests remembered as matching an address filter, for their answers.
KEPT_REQUESTS = 4096
_REQUEST_ROLES = [ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.BROADCAST]]


@dataclass
class MessageFilter:
    """Alternatives per key; an empty filter lets everything through. Follows the capture in
    order (an answer matches an address when its request did)."""

    slaves: frozenset[int] = frozenset()
    functions: frozenset[int] = frozenset()
    roles: frozenset[Role] = frozenset()
    flags: FrameFlag = FrameFlag.NONE
    crc: frozenset[bool] = frozenset()
    exceptions: frozenset[int] = frozenset()
    addresses: tuple[tuple[int, int], ...] = ()
    params: frozenset[str] = frozenset()
    latency: tuple[tuple[str, float], ...] = ()
    _requests: OrderedDict[int, None] = field(default_factory=OrderedDict)

    def __call__(self, batch: AnnotatedBatch) -> npt.NDArray[np.bool_]:
        """Which messages of ``batch`` pass."""
        messages = batch.messages
        keep = np.ones(len(messages), np.bool_)
        if self.slaves:
            keep &= np.isin(messages.slave, list(self.slaves))
        if self.functions:
            keep &= np.isin(messages.function, list(self.functions))
        if self.roles:
            keep &= np.isin(messages.role, [ROLE_CODE[role] for role in self.roles])
        if self.flags:
            keep &= (messages.flags & int(self.flags)) != 0
        if self.crc:
            noise = messages.role == ROLE_CODE[Role.NOISE]
            ok = messages.frames.crc_ok & ~noise
            bad = ~messages.frames.crc_ok & ~noise
            keep &= (ok if True in self.crc else False) | (bad if False in self.crc else False)
        if self.exceptions:
            keep &= np.isin(messages.exception_code, list(self.exceptions))
        for symbol, limit_ms in self.latency:
            latency = messages.latency_ns
            keep &= (latency != NONE) & np.asarray(COMPARISONS[symbol](latency, limit_ms * 1e6), np.bool_)
        if self.addresses or self.params:
            keep &= self._touching(batch)
        return keep

    def _touching(self, batch: AnnotatedBatch) -> npt.NDArray[np.bool_]:
        """Messages naming a wanted address or parameter, or answering a request that did."""
        messages = batch.messages
        touching = np.zeros(len(messages), np.bool_)
        first = messages.frames.first_index
        roles, requests = messages.role.tolist(), messages.request_index.tolist()
        for position, params in enumerate(batch.message_params()):
            hit = any(self._wanted(p.address, p.code) for p in params)
            if not hit and requests[position] != NONE:
                hit = requests[position] in self._requests
            elif hit and roles[position] in _REQUEST_ROLES:
                self._requests[first + position] = None
                if len(self._requests) > KEPT_REQUESTS:
                    self._requests.popitem(last=False)
            touching[position] = hit
        return touching

    def _wanted(self, address: int, code: str | None) -> bool:
        return (code is not None and code.upper() in self.params) or any(low <= address <= high
                                                                  for low, high in self.addresses)

    @property
    def empty(self) -> bool:
        return not (self.slaves or self.functions or self.roles or self.flags or self.crc or self.exceptions
                    or self.addresses or self.params or self.latency)


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


def _address_range(text: str) -> tuple[int, int]:
    number = _number("address", 0, 65535)
    low, sep, high = text.replace("..", "-").partition("-")
    first = number(low)
    last = number(high) if sep else first
    if last < first:
        raise RtuSniffError(ErrorKind.USAGE, f"--filter address={text}: the range ends before it starts")
    return first, last


def _milliseconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value >= 0:
        raise RtuSniffError(ErrorKind.USAGE, f"--filter latency: give milliseconds, not {text!r}")
    return value


def parse_filters(specs: Sequence[str]) -> MessageFilter:
    """``["slave=2", "flag=timeout", "latency>20"]`` → a filter; errors say what is allowed."""
    parsers: dict[str, Callable[[str], object]] = {
        "slave": _number("slave", 0, 247),
        "function": _number("function", 1, 127),
        "role": _choice("role", dict(ROLE_NAMES)),
        "flag": _choice("flag", dict(FLAG_NAMES)),
        "crc": _choice("crc", {"ok": True, "bad": False}),
        "exception": _number("exception", 1, 255),
        "address": _address_range,
        "param": lambda text: text.strip().upper(),
    }
    values: dict[str, set[object]] = {key: set() for key in parsers}
    latency: list[tuple[str, float]] = []
    for spec in specs:
        match = _SPEC.fullmatch(spec.strip())
        key, symbol, text = (match[1], match[2], match[3]) if match else ("", "", "")
        if key == "latency" and symbol != "=":
            latency.append((symbol, _milliseconds(text)))
            continue
        if symbol != "=" or key not in parsers:
            raise RtuSniffError(ErrorKind.USAGE, f"--filter {spec}: use KEY=VALUE with KEY one of "
                                f"{', '.join(parsers)}, or latency>MS")
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
        crc=frozenset(v for v in values["crc"] if isinstance(v, bool)),
        exceptions=frozenset(v for v in values["exception"] if isinstance(v, int)),
        addresses=tuple(sorted(v for v in values["address"] if isinstance(v, tuple))),
        params=frozenset(v for v in values["param"] if isinstance(v, str)),
        latency=tuple(latency),
    )

"""The interfaces every capture format implements."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Protocol

from decoders.capture import CaptureInfo, ChunkBatch, TimingQuality
from decoders.line import LineSettings

#: The largest single read (chunk) a capture may hold, in MiB, unless the environment says otherwise.
#: A serial port delivers at most 64 KiB a read; a chunk of many megabytes is a damaged or hostile
#: file, and framing one costs about 100 bytes of memory per byte (it does not stream within a chunk).
MAX_READ_MIB = 1
READ_LIMIT_VARIABLE = "RTUSNIFF_MAX_READ_MB"


def max_read_bytes() -> int:
    """The most bytes one chunk may hold: ``MAX_READ_MIB``, or ``$RTUSNIFF_MAX_READ_MB``."""
    given = os.environ.get(READ_LIMIT_VARIABLE, "")
    return (int(given) if given.isdigit() and int(given) > 0 else MAX_READ_MIB) * 2**20


def read_limit_message(size: int) -> str:
    """The error for a chunk of ``size`` bytes over the limit, saying how to raise it."""
    limit = max_read_bytes()
    return (f"holds one read of {size:,} bytes or more, over the {limit // 2**20} MiB rtusniff reads at once (a serial "
            f"port delivers at most 64 KiB a read: a damaged or hostile file). {READ_LIMIT_VARIABLE}=N (MiB) raises it")


class CaptureReader(Protocol):
    """Reads a capture: ``info`` is known once it is open; ``batches`` streams the bytes."""

    info: CaptureInfo
    #: Notes found after the header; complete once ``batches`` is exhausted.
    late_notes: list[str]
    #: Things to tell the user once reading is done (e.g. a recording cut short).
    warnings: list[str]

    def batches(self) -> Iterator[ChunkBatch]: ...

    def last_time_ns(self) -> int | None:
        """About when the capture ends, if the file says it without being read through (its
        last line, an index): what progress is measured against. ``None``: unknown (stdin)."""
        ...

    def close(self) -> None: ...


class CaptureWriter(Protocol):
    """Writes a capture; ``close`` leaves a complete, valid file."""

    def write_batch(self, batch: ChunkBatch) -> None: ...

    def add_notes(self, notes: list[str]) -> None: ...

    def flush(self) -> None:
        """Make everything written so far durable (on disk)."""

    @property
    def size(self) -> int:
        """Bytes written so far."""
        ...

    def close(self) -> None: ...

    def abandon(self) -> None:
        """Close the file as it is, without closing records (after a failed write)."""


@dataclass(frozen=True)
class ReaderOptions:
    """What the command line tells a reader beyond the file: a format whose files do not
    say their line settings, timing or channel takes them from here."""

    #: ``--line``: the line settings the user gave, if any.
    line: LineSettings | None = None
    #: ``--timing``: the timing quality the user gave, if any.
    timing: TimingQuality | None = None
    #: Which channels of a multi-channel recording carry the bus (``--channel``, by name or
    #: number; RX and TX may be two), if the user said.
    channels: tuple[str, ...] = ()
    #: ``--follow``: keep reading as the file grows (:mod:`sniffer.io.following`).
    follow: bool = False
    #: ``--invert``/``--no-invert``: read a logic analyzer's lines inverted or not; ``None``: as
    #: their samples decode best (:mod:`sniffer.io.polarity`).
    invert: bool | None = None


def channel_number(requested: str, names: dict[int, str]) -> int | None:
    """The channel ``--channel`` names among ``names`` (number from 1 → name): a name first
    (sigrok names probes "0", "1", …), then a number; ``None`` if neither."""
    by_name = [number for number, name in names.items() if name == requested]
    if by_name:
        return by_name[0]
    return next((number for number in names if str(number) == requested), None)


class ChannelChoiceError(ValueError):
    """``--channel`` named no channel, or one channel twice: the message says which."""


def chosen_channels(requested: tuple[str, ...], names: dict[int, str],
                    what: str = "channel") -> tuple[list[int], list[str]]:
    """The channels the ``--channel`` options name among ``names`` (number from 1 → name), in
    order, and a warning for each that its name matched where its number names another channel
    (sigrok names probes "0", "1", …: ``--channel 1`` is the probe named "1", the second), unless
    another option is a name that is no number (``--channel 0 --channel 1``: names, plainly).
    Raises :class:`ChannelChoiceError` for a name that matches nothing, and for two options
    that name one channel: the same bytes read twice are no RX and TX. ``what``: what the
    recording calls a channel, in the messages (a sigrok session's are probes)."""
    chosen: list[int] = []
    said: list[str] = []
    numbers = {str(index): index for index in names}
    plainly_names = any(channel in names.values() and channel not in numbers for channel in requested)
    for channel in requested:
        number = channel_number(channel, names)
        if number is None:
            listed = ", ".join(f"{index}={name}" for index, name in sorted(names.items()))
            raise ChannelChoiceError(f"--channel {channel}: no such {what} (here: {listed})")
        if number in chosen:
            earlier = requested[chosen.index(number)]
            raise ChannelChoiceError(
                f"--channel {earlier} and --channel {channel} both name {what} {number} "
                f"(named {names[number]!r}; a name is matched before a number): name two different {what}s")
        by_number = numbers.get(channel)
        if by_number is not None and by_number != number and not plainly_names:
            said.append(f"--channel {channel} is {what} {number}, named {channel!r} (a name is matched before "
                        f"a number: {what} {by_number} is named {names[by_number]!r})")
        chosen.append(number)
    return chosen, said


@dataclass(frozen=True)
class CaptureFormat:
    """One capture format, declared by its module in :mod:`sniffer.io.formats` as ``FORMAT``.

    A format may be read-only or write-only (``open_writer`` / ``open_reader`` ``None``).
    Its module stays light: the factories import a heavy dependency when called.
    """

    name: str
    suffixes: tuple[str, ...]
    description: str
    #: Whether a file's first ``SNIFF_BYTES`` bytes are of this format.
    sniff: Callable[[bytes], bool]
    open_reader: Callable[[str, ReaderOptions], CaptureReader] | None = None
    open_writer: Callable[[str, CaptureInfo], CaptureWriter] | None = None
    #: Whether its reader can follow a file still being written (``--follow``).
    followable: bool = False

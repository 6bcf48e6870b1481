"""``--from``/``--to``, ``--around``/``--context`` and ``--limit``: which part of a capture a
command looks at.

A window (times or frame numbers) is the part of the capture a command reads: its statistics
count the window only, and reading stops where the window ends. ``--limit N`` stops after N
frames shown (after ``--filter``).

Times: an offset from the capture's first frame (``90``, ``90s``, ``250ms``, ``2min``,
``1.5h``, optionally with a leading ``+``), a time of day on the capture's first day
(``14:05``, ``14:05:30.25``), or a date and time (``2026-11-24 14:05:30``,
``2026-11-24T14:05:30Z``, ``…+01:00``). Times without a zone are in UTC, or in local time
with ``--time local``.
"""

from __future__ import annotations

import argparse
import re
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np

from decoders.message import MessageBatch
from sniffer.errors import ErrorKind, RtuSniffError

NS_PER_S = 1_000_000_000
_UNITS = {"": NS_PER_S, "s": NS_PER_S, "ms": 1_000_000, "us": 1_000, "µs": 1_000, "min": 60 * NS_PER_S,
          "h": 3600 * NS_PER_S}
_OFFSET = re.compile(r"\+?(\d+(?:\.\d*)?|\.\d+)\s*(ms|us|µs|s|min|h)?")
_TIME_OF_DAY = re.compile(r"(\d{1,2}):(\d{2})(?::(\d{2}(?:\.\d+)?))?")
#: ``--context`` when ``--around`` is given without it.
DEFAULT_CONTEXT = 10


@dataclass(frozen=True)
class TimeBound:
    """A bound as given: an offset from the first frame, a time of day, or an instant."""

    option: str
    text: str
    offset_ns: int | None = None
    of_day_ns: int | None = None
    instant_ns: int | None = None
    local: bool = False

    def resolve(self, first_ns: int) -> int:
        """Nanoseconds since the epoch, for a capture whose first frame starts at ``first_ns``."""
        if self.offset_ns is not None:
            return first_ns + self.offset_ns
        if self.instant_ns is not None:
            return self.instant_ns
        assert self.of_day_ns is not None
        first = datetime.fromtimestamp(first_ns // NS_PER_S, UTC)
        if self.local:
            first = first.astimezone()
        midnight = first.replace(hour=0, minute=0, second=0, microsecond=0)
        if self.local:  # the zone's offset at midnight, not at the first frame (a DST change between)
            midnight = midnight.replace(tzinfo=None).astimezone()
        return int(midnight.timestamp()) * NS_PER_S + self.of_day_ns


def parse_time(option: str, text: str, *, local: bool) -> TimeBound:
    """One ``--from``/``--to`` value; a usage error says what is accepted."""
    spelled = text.strip()
    if match := _OFFSET.fullmatch(spelled):
        return TimeBound(option, text, offset_ns=round(float(match[1]) * _UNITS[match[2] or ""]))
    if match := _TIME_OF_DAY.fullmatch(spelled):
        hours, minutes, seconds = int(match[1]), int(match[2]), float(match[3] or 0)
        if hours < 24 and minutes < 60 and seconds < 60:
            return TimeBound(option, text, of_day_ns=round((hours * 3600 + minutes * 60 + seconds) * NS_PER_S),
                             local=local)
    try:
        moment = datetime.fromisoformat(spelled.replace("Z", "+00:00"))
    except ValueError:
        moment = None
    if moment is not None:
        if moment.tzinfo is None:
            moment = moment.astimezone() if local else moment.replace(tzinfo=UTC)
        whole = moment.replace(microsecond=0)
        nanos = int(whole.timestamp()) * NS_PER_S + moment.microsecond * 1000
        return TimeBound(option, text, instant_ns=nanos)
    raise RtuSniffError(ErrorKind.USAGE, f"{option} {text}: give an offset from the start (90s, 250ms, 2min), "
                        "a time of day (14:05:30.25) or a date and time (2026-11-24 14:05:30)")


@dataclass(frozen=True)
class Selection:
    """The window and the limit; ``everything`` when none was given."""

    start: TimeBound | None = None
    stop: TimeBound | None = None
    first_index: int | None = None
    last_index: int | None = None
    limit: int | None = None

    @property
    def windowed(self) -> bool:
        return (self.start, self.stop, self.first_index, self.last_index) != (None, None, None, None)


#: No window and no limit.
EVERYTHING = Selection()


class Window:
    """Applies a :class:`Selection`'s window to batches in capture order."""

    def __init__(self, selection: Selection) -> None:
        self.selection = selection
        self._start_ns: int | None = None
        self._stop_ns: int | None = None
        self._resolved = False
        #: Set once a batch went past the window's end: nothing after it can be in the window.
        self.past = False
        #: Frames read (in the window or not), the first one's start and the last one's end.
        self.read = 0
        self._read_span: tuple[int, int] | None = None
        self.delivered = 0

    def span(self, batch: MessageBatch) -> tuple[int, int]:
        """The positions ``[begin, end)`` of ``batch`` inside the window (frames are in time order)."""
        frames, selection = batch.frames, self.selection
        if not self._resolved and len(frames):
            first = int(frames.t_start_ns[0])
            self._start_ns = None if selection.start is None else selection.start.resolve(first)
            self._stop_ns = None if selection.stop is None else selection.stop.resolve(first)
            self._resolved = True
        if len(frames):
            self.read += len(frames)
            first_ns = int(frames.t_start_ns[0]) if self._read_span is None else self._read_span[0]
            self._read_span = (first_ns, int(frames.t_end_ns[-1]))
        begin, end = 0, len(frames)
        if self._start_ns is not None:
            begin = max(begin, int(np.searchsorted(frames.t_start_ns, self._start_ns, "left")))
        if self._stop_ns is not None:
            end = min(end, int(np.searchsorted(frames.t_start_ns, self._stop_ns, "right")))
        if selection.first_index is not None:
            begin = max(begin, selection.first_index - frames.first_index)
        if selection.last_index is not None:
            end = min(end, selection.last_index + 1 - frames.first_index)
        if end < len(frames):
            self.past = True
        begin = min(max(begin, 0), len(frames))
        end = max(min(end, len(frames)), begin)
        self.delivered += end - begin
        return begin, end

    def missed(self) -> str | None:
        """What to tell when the window held none of the frames read (a time of day in the wrong
        zone, an index past the end): where the frames read lie. ``None`` when it held some."""
        if self.delivered or self._read_span is None:
            return None
        first, last = (_utc(t_ns) for t_ns in self._read_span)
        missed = "no frame falls in the window of --from/--to/--around: "
        if self.past:  # the window ends before the capture starts: the rest was not read
            return missed + f"the capture's first frame starts at {first} UTC, after the window's end"
        return missed + f"the capture's {self.read:,} frames run from {first} to {last} UTC (#0 to #{self.read - 1:,})"


def _utc(t_ns: int) -> str:
    return datetime.fromtimestamp(t_ns // NS_PER_S, UTC).strftime("%Y-%m-%d %H:%M:%S") + f".{t_ns % NS_PER_S:09d}"[:4]


def add_selection_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("which part of the capture")
    group.add_argument("--from", dest="start", metavar="TIME",
                       help="start at TIME: an offset (90s, 250ms, 2min), a time of day (14:05:30.25) or a date "
                       "and time (2026-11-24 14:05:30); UTC unless --time local")
    group.add_argument("--to", dest="stop", metavar="TIME", help="stop after TIME (as --from)")
    group.add_argument("--around", type=_count("--around"), metavar="INDEX",
                       help="only the frames around frame INDEX (see --context)")
    group.add_argument("--context", type=_count("--context"), metavar="N",
                       help=f"frames before and after --around (default {DEFAULT_CONTEXT})")
    group.add_argument("--limit", type=_count("--limit", low=1), metavar="N", help="stop after N frames shown")


def _count(option: str, low: int = 0) -> argparse._ActionType:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = low - 1
        if value < low:
            raise argparse.ArgumentTypeError(f"{option} takes a whole number from {low}")
        return value

    return parse


def selection_from(args: argparse.Namespace) -> Selection:
    """The selection the options give (usage errors for contradictions)."""
    local = getattr(args, "time", "utc") == "local"
    start = None if args.start is None else parse_time("--from", args.start, local=local)
    stop = None if args.stop is None else parse_time("--to", args.stop, local=local)
    if args.context is not None and args.around is None:
        raise RtuSniffError(ErrorKind.USAGE, "--context goes with --around INDEX")
    first = last = None
    if args.around is not None:
        context = DEFAULT_CONTEXT if args.context is None else args.context
        first, last = max(args.around - context, 0), args.around + context
    if start and stop and start.offset_ns is not None and stop.offset_ns is not None and \
            stop.offset_ns < start.offset_ns:
        raise RtuSniffError(ErrorKind.USAGE, f"--to {stop.text} is before --from {start.text}")
    return Selection(start, stop, first, last, args.limit)


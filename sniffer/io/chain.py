"""Several capture files read as one capture: rotated recordings (``capture --rotate`` writes
``site-0001.mcap``, ``site-0002.mcap``, …) or a recording split by hand.

The files are put in time order by their first chunk, whatever order they were named in, and
read one after the other: frame indices run on across them, and a frame that one file ends in
the middle of is completed by the next. Files that overlap in time, or that say different line
settings or timing, are refused with one line naming the file: they are not one capture.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

from decoders.capture import CaptureInfo, ChunkBatch
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.io.base import CaptureReader, ReaderOptions
from sniffer.io.registry import STDIO, open_reader


def _format_ns(t_ns: int) -> str:
    seconds, nanos = divmod(t_ns, 1_000_000_000)
    return f"{seconds}.{nanos:09d}"


@dataclass
class _Part:
    path: str
    reader: CaptureReader
    #: The first batch, read to learn where the file starts (``None``: the file has no chunks).
    first: ChunkBatch | None
    batches: Iterator[ChunkBatch]

    @property
    def start_ns(self) -> int | None:
        return None if self.first is None else int(self.first.t_end_ns[0])


class ChainedReader:
    """The files of ``paths`` as one :class:`CaptureReader` (see the module docstring)."""

    def __init__(self, paths: list[str], format_name: str | None, options: ReaderOptions) -> None:
        if STDIO in paths:
            raise RtuSniffError(ErrorKind.USAGE, "- (standard input) is a capture of its own; name files to join")
        self.late_notes: list[str] = []
        self.warnings: list[str] = []
        self._parts: list[_Part] = []
        try:
            for path in paths:
                reader = open_reader(path, format_name, options)
                self._parts.append(_Part(path, reader, None, iter(())))
                batches = reader.batches()
                part = self._parts[-1]
                part.batches, part.first = batches, next(batches, None)
        except BaseException:
            self.close()
            raise
        self._parts.sort(key=lambda part: (part.start_ns is None, part.start_ns or 0))
        self.info = self._common_info(options)
        self._check_order()

    def _check_order(self) -> None:
        """Refuse overlapping files before reading them, where their ends are known cheaply (a
        text file's last line, an MCAP index); :meth:`batches` checks the rest as it reads."""
        for before, after in zip(self._parts, self._parts[1:], strict=False):
            end, start = before.reader.last_time_ns(), after.start_ns
            if end is not None and start is not None and start < end:
                raise _overlap(after, before, start, end)

    def _common_info(self, options: ReaderOptions) -> CaptureInfo:
        first = self._parts[0]
        for part in self._parts[1:]:
            info, expected = part.reader.info, first.reader.info
            if options.line is None and info.line != expected.line:
                said = "no line settings" if info.line is None else f"line {info.line.format()}"
                raise RtuSniffError(ErrorKind.BAD_HEADER, f"{said}, but {first.path} says "
                                    f"{expected.line.format() if expected.line else 'none'}: files of one capture "
                                    "share one line (or give --line)", path=part.path)
            if options.timing is None and info.timing is not expected.timing:
                raise RtuSniffError(ErrorKind.BAD_HEADER, f"timing {info.timing.value}, but {first.path} says "
                                    f"{expected.timing.value}: files of one capture share one timing "
                                    "(or give --timing)", path=part.path)
            if info.channels != expected.channels:
                raise RtuSniffError(ErrorKind.BAD_HEADER, f"channels {' '.join(info.channels) or 'none'}, but "
                                    f"{first.path} says {' '.join(expected.channels) or 'none'}: files of one "
                                    "capture share their channels", path=part.path)
        notes = tuple(note for part in self._parts for note in part.reader.info.notes)
        return CaptureInfo(first.reader.info.line, first.reader.info.timing, tuple(dict.fromkeys(notes)),
                           first.reader.info.channels)

    def batches(self) -> Iterator[ChunkBatch]:
        previous: _Part | None = None
        last_ns: int | None = None
        for part in self._parts:
            if part.first is None:
                continue
            if last_ns is not None and previous is not None and int(part.first.t_end_ns[0]) < last_ns:
                raise _overlap(part, previous, int(part.first.t_end_ns[0]), last_ns)
            batch: ChunkBatch | None = part.first
            while batch is not None:
                if len(batch):
                    last_ns = int(batch.t_end_ns[-1])
                yield batch
                batch = next(part.batches, None)
            self.late_notes += part.reader.late_notes
            previous = part

    def last_time_ns(self) -> int | None:
        ends = [part.reader.last_time_ns() for part in self._parts]
        known = [end for end in ends if end is not None]
        return max(known) if len(known) == len(ends) else None

    def close(self) -> None:
        for part in self._parts:
            part.reader.close()
            self.warnings += part.reader.warnings


def _overlap(part: _Part, before: _Part, start_ns: int, end_ns: int) -> RtuSniffError:
    return RtuSniffError(ErrorKind.DECREASING_TIME, f"starts at {_format_ns(start_ns)}, before {before.path} ends "
                         f"({_format_ns(end_ns)}): the files overlap, so they are not one recording split in time",
                         path=part.path)


def open_capture(paths: list[str], format_name: str | None, options: ReaderOptions) -> CaptureReader:
    """One file's reader, or the files chained into one capture."""
    if len(paths) == 1:
        return open_reader(paths[0], format_name, options)
    return ChainedReader(paths, format_name, options)

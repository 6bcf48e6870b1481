"""Errors that end a command with one line and a distinct exit code."""

from __future__ import annotations

from enum import Enum


class ErrorKind(Enum):
    """What went wrong, and the process exit code that says so."""

    RUNTIME = 1
    USAGE = 2
    FILE_NOT_FOUND = 3
    FILE_UNREADABLE = 4
    UNKNOWN_FORMAT = 5
    BAD_HEADER = 6
    BAD_DATA = 7
    DECREASING_TIME = 8
    BAD_MCAP = 9
    NO_LINE_SETTINGS = 10
    OUTPUT_FAILED = 11
    BAD_PROFILE = 12
    PORT_GONE = 13
    NO_DATA = 14

    @property
    def exit_code(self) -> int:
        return self.value


def shown(text: str, limit: int = 40) -> str:
    """``text`` quoted for an error line, cut to ``limit`` characters (a hostile file's value
    may be megabytes long)."""
    return repr(text) if len(text) <= limit else f"{text[:limit]!r}… ({len(text):,} characters)"


class RtuSniffError(Exception):
    """An error in a file or an option, reported as ``error: WHERE: WHAT``."""

    def __init__(self, kind: ErrorKind, message: str, *, path: str | None = None,
                 location: str | None = None) -> None:
        self.kind = kind
        self.message = message
        self.path = path
        self.location = location
        where = ":".join(part for part in (path, location) if part)
        super().__init__(f"{where}: {message}" if where else message)

    def __reduce__(self) -> tuple[object, ...]:
        # Pickled (from the decoding process) by the arguments it was made with, not by its text.
        return (_rebuilt, (type(self), self.kind, self.message, self.path, self.location))


def _rebuilt(
    cls: type[RtuSniffError], kind: ErrorKind, message: str, path: str | None, location: str | None
) -> RtuSniffError:
    return cls(kind, message, path=path, location=location)


class CaptureFormatError(RtuSniffError):
    """A capture file that cannot be read as its format says."""

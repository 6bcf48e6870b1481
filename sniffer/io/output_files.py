"""How every output file is created, so that no command destroys what it was not told to.

* A file is created **exclusively** (``O_CREAT | O_EXCL``): a file that appeared after the
  command checked its outputs (another program, a second capture, a rotation's next name) is
  never truncated, and a symbolic link, even a dangling one, is never followed to create its
  target (``O_NOFOLLOW``).
* Only a file the command's ``--force`` approved (:func:`allow_replacing`, called by the check
  of a command's outputs) is replaced, and never through a symbolic link.
* A device or a pipe (``-o /dev/null``, ``/dev/stdout``) is written as it is: writing to it
  destroys nothing, and nothing ever deletes it.
* :func:`published_whole` writes a copy (``convert``, ``cut``, ``report``) beside its path and
  puts it in place only once it is whole: a copy that broke off leaves nothing behind, and only
  the part file this process created is ever removed. An export interrupted by Ctrl-C is kept
  under a name that says so (``poll.incomplete.mcap``), never under the name of a whole one.
"""

from __future__ import annotations

import errno
import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, Any, BinaryIO, TextIO, cast

from sniffer.errors import ErrorKind, RtuSniffError

_REPLACEABLE: set[str] = set()
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)  # not on Windows, which creates no links by accident
_BINARY = getattr(os, "O_BINARY", 0)  # Windows: no newline translation


def allow_replacing(paths: list[str]) -> None:
    """The files ``--force`` lets this command replace (only these; the last call counts)."""
    _REPLACEABLE.clear()
    _REPLACEABLE.update(os.path.abspath(path) for path in paths)


def is_device(path: str) -> bool:
    """Whether ``path`` is an existing device or pipe (through links): written as it is."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False
    return not stat.S_ISREG(mode) and not stat.S_ISDIR(mode)


def open_new(path: str) -> BinaryIO:
    """Create ``path`` for writing bytes (see the module docstring); errors name the file."""
    return cast(BinaryIO, _open(path, binary=True, encoding=None))


def open_new_text(path: str, encoding: str = "utf-8") -> TextIO:
    """Create ``path`` for writing text (see the module docstring); errors name the file."""
    return cast(TextIO, _open(path, binary=False, encoding=encoding))


def _open(path: str, *, binary: bool, encoding: str | None) -> IO[Any]:
    mode = "wb" if binary else "w"
    if is_device(path):
        return open(path, mode, encoding=encoding)
    replace = os.path.abspath(path) in _REPLACEABLE
    flags = os.O_WRONLY | os.O_CREAT | _NOFOLLOW | _BINARY | (os.O_TRUNC if replace else os.O_EXCL)
    try:
        fd = os.open(path, flags, 0o666)
    except FileExistsError:
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, "exists (it appeared after it was checked, or is a link); "
                            "rtusniff never overwrites a file it was not told to (--force)", path=path) from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise RtuSniffError(ErrorKind.OUTPUT_FAILED, "is a symbolic link: name the file it points to",
                                path=path) from None
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"cannot write: {exc.strerror}", path=path) from None
    return os.fdopen(fd, mode, encoding=encoding)


@contextmanager
def published_whole(path: str, *, kept_when_interrupted: list[str] | None = None) -> Iterator[str]:
    """The path to write ``path``'s content to: a part file beside it, renamed to ``path`` when
    the block ends without error and removed when it fails. ``-``, a device or a pipe: ``path``
    itself (nothing to remove). ``kept_when_interrupted``: Ctrl-C keeps the part, closed as far
    as it got, under :func:`incomplete_name` (appended to the list): what the user stopped is
    theirs, but nothing may pass it for a whole export."""
    if path == "-" or is_device(path):
        yield path
        return
    target = Path(path)
    part = str(target.with_name(f".{target.stem}.{os.urandom(4).hex()}.part{target.suffix}"))
    try:
        yield part
    except KeyboardInterrupt:
        if kept_when_interrupted is not None and os.path.exists(part):
            kept_when_interrupted.append(_publish_incomplete(part, path))
        else:
            _discard(part)
        raise
    except RtuSniffError as error:
        _discard(part)
        if error.path != part:
            raise
        # Errors name the file the user asked for, not the part file that no longer exists.
        raise type(error)(error.kind, error.message, path=path, location=error.location) from None
    except BaseException:
        _discard(part)
        raise
    try:
        _publish(part, path)
    except BaseException:
        _discard(part)
        raise


def incomplete_name(path: str, attempt: int = 0) -> str:
    """Where an interrupted output of ``path`` is kept: ``poll.incomplete.mcap`` (then
    ``poll.incomplete-2.mcap``, … where that exists)."""
    target = Path(path)
    return str(target.with_name(f"{target.stem}.incomplete{f'-{attempt + 1}' if attempt else ''}{target.suffix}"))


def _publish_incomplete(part: str, path: str) -> str:
    """``part`` put in place under the first free :func:`incomplete_name` of ``path``; that name."""
    for attempt in range(1000):
        name = incomplete_name(path, attempt)
        try:
            _publish(part, name)
        except RtuSniffError:  # it exists: the next one
            continue
        return name
    _discard(part)
    raise RtuSniffError(ErrorKind.OUTPUT_FAILED, "1 000 incomplete exports of it exist already", path=path)


def _discard(part: str) -> None:
    with suppress(FileNotFoundError):
        os.remove(part)


def _publish(part: str, path: str) -> None:
    if os.path.abspath(path) in _REPLACEABLE:
        if os.path.islink(path):
            raise RtuSniffError(ErrorKind.OUTPUT_FAILED, "is a symbolic link: name the file it points to", path=path)
        os.replace(part, path)
        return
    try:
        os.link(part, path)  # fails if path exists, whatever appeared meanwhile
    except FileExistsError:
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, "exists (it appeared while rtusniff was writing); rtusniff "
                            "never overwrites a file it was not told to (--force)", path=path) from None
    except OSError:  # a file system without hard links: the small window of a check, then the rename
        if os.path.lexists(path):
            raise RtuSniffError(ErrorKind.OUTPUT_FAILED, "exists; rtusniff never overwrites a file it was not "
                                "told to (--force)", path=path) from None
        os.replace(part, path)
        return
    os.remove(part)

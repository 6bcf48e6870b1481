"""Following a recording that is still being written (``--follow``), as ``tail -f`` does.

A ``capture -o FILE`` running as a service makes its file durable every second; anyone may
then watch it with ``analyze --follow FILE``. :class:`GrowingFile` is the file as such a
reader sees it: a read that reaches the current end waits for the writer to add more,
instead of meeting the end of the file. The readers that can follow (the native MCAP and
the text format) check :meth:`GrowingFile.caught_up` after each record or line, and hand on
what they hold when nothing more is there yet, so that the frames written so far are
decoded at once rather than after a batch fills.

Following ends where the recording ends: an MCAP recording's closing record (the capture
stopped, or rotated to its next file), or Ctrl-C (or SIGTERM). A text recording has no closing
record: it is followed until Ctrl-C. Ctrl-C while following is how one stops it, so it is not
an interruption: the reads end where the file ends now (:func:`stopping_on_signals`), and the
command finishes as at the end of a file (``stats`` prints its table, exports are closed
whole) and exits 0. A second Ctrl-C interrupts at once.
"""

from __future__ import annotations

import os
import queue
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType
from typing import BinaryIO

from decoders.capture import CaptureInfo, ChunkBatch
from sniffer.io.base import CaptureReader
from sniffer.io.rotation import next_rotated, rotated_files

#: How often a caught-up reader looks for more (a recorder flushes every second).
POLL_S = 0.1
#: Set by Ctrl-C or SIGTERM while following: waiting reads return what they have.
STOP = threading.Event()
#: A recording that has not grown for this long was quiet for at least ``QUIET_NS`` after its
#: last byte: a recorder writes what it read at least every second.
QUIET_AFTER_S = 2.0
QUIET_NS = 500_000_000
#: What :class:`FollowingReader` yields when the recording has been quiet: decode what is open.
QUIET = ChunkBatch.from_chunks([])
#: Blocks read ahead, and the bytes joined into one batch when catching up (each batch costs
#: the decoder a fixed overhead).
QUEUED_BATCHES = 64
JOINED_BYTES = 1 << 20


@contextmanager
def stopping_on_signals() -> Iterator[None]:
    """While following, the first Ctrl-C or SIGTERM ends the reads (``STOP``); a second Ctrl-C
    is an interruption as usual. Installed in the main thread before a decoding process is
    forked, so that both stop at the end of what is written."""
    def stop(signum: int, frame: FrameType | None) -> None:
        STOP.set()
        signal.signal(signal.SIGINT, signal.default_int_handler)

    STOP.clear()
    previous = {number: signal.signal(number, stop) for number in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for number, handler in previous.items():
            if handler is not None:
                signal.signal(number, handler)


class GrowingFile:
    """A read-only binary file whose reads wait for the bytes a writer has yet to add.

    While it waits it also watches that the file it follows is still the one it read: one that
    shrinks below what was read (truncated), whose name now leads to another file (replaced by a
    rename, or removed), or whose last bytes read are no longer there (rewritten) ends following
    as Ctrl-C does, with what was read decoded, and ``lost`` saying which (the readers add it to
    their warnings)."""

    #: Bytes before the read position kept to tell a rewritten file.
    TAIL = 64

    def __init__(self, path: str, *, poll_s: float = POLL_S, sleep: Callable[[float], None] = time.sleep,
                 warnings: list[str] | None = None) -> None:
        self.name = path
        self._file: BinaryIO = open(path, "rb")  # noqa: SIM115 - closed by close()
        self._poll_s, self._sleep = poll_s, sleep
        self._warnings = warnings if warnings is not None else []
        #: Why following ended before the file did (``None`` while it is the file read).
        self.lost: str | None = None
        self._tail = b""
        self._mtime_ns = os.fstat(self._file.fileno()).st_mtime_ns

    def _kept(self, piece: bytes) -> bytes:
        self._tail = (self._tail + piece)[-self.TAIL :]
        return piece

    def _waits(self) -> bool:
        """Nothing more to read yet: whether to wait for it (else reads end where they are)."""
        if STOP.is_set() or self.lost is not None:
            return False
        self.lost = self._change()
        if self.lost is not None:
            self._warnings.append(f"{self.name}: {self.lost}: following stopped at byte {self._file.tell():,}; "
                                  "what was read before is decoded")
            return False
        self._sleep(self._poll_s)
        return True

    def _change(self) -> str | None:
        position, mine = self._file.tell(), os.fstat(self._file.fileno())
        if mine.st_size < position:
            return f"truncated to {mine.st_size:,} bytes while followed"
        try:
            named = os.stat(self.name)
        except OSError:
            return "removed or renamed while followed"
        if (named.st_dev, named.st_ino) != (mine.st_dev, mine.st_ino):
            return "replaced by another file of its name while followed"
        if mine.st_mtime_ns != self._mtime_ns and self._tail:
            self._mtime_ns = mine.st_mtime_ns
            self._file.seek(position - len(self._tail))
            again = self._file.read(len(self._tail))
            self._file.seek(position)
            if again != self._tail:
                return "rewritten while followed (the bytes last read changed)"
        return None

    def read(self, size: int = -1) -> bytes:
        """``size`` bytes, waiting as long as it takes for them (all there is: ``size`` < 0)."""
        if size < 0:
            return self._kept(self._file.read())
        pieces: list[bytes] = []
        wanted = size
        while wanted > 0:
            piece = self._file.read(wanted)
            if piece:
                pieces.append(self._kept(piece))
                wanted -= len(piece)
            elif not self._waits():
                break
        return b"".join(pieces)

    def readline(self, limit: int = -1) -> bytes:
        """A whole line (up to ``limit`` bytes), waiting for its newline."""
        pieces: list[bytes] = []
        taken = 0
        while True:
            piece = self._kept(self._file.readline(limit - taken if limit >= 0 else -1))
            pieces.append(piece)
            taken += len(piece)
            if piece.endswith(b"\n") or (limit >= 0 and taken >= limit):
                return b"".join(pieces)
            if not piece and not self._waits():
                return b""  # a line still being written when following stopped: not read

    @property
    def stopped(self) -> bool:
        """Whether following was stopped (the reads now end where the file ends)."""
        return STOP.is_set() or self.lost is not None

    def caught_up(self) -> bool:
        """Whether everything written so far has been read (a reader then hands on what it holds)."""
        return self._file.tell() >= os.fstat(self._file.fileno()).st_size

    def tell(self) -> int:
        return self._file.tell()

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        return self._file.seek(offset, whence)

    def fileno(self) -> int:
        return self._file.fileno()

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def close(self) -> None:
        self._file.close()

    @property
    def closed(self) -> bool:
        return self._file.closed


#: How long a rotation's next file may take to appear after the last one closed: the recorder
#: opens it at once; when none comes, the capture stopped.
NEXT_FILE_S = 3.0


def followed_path(path: str) -> str:
    """What ``--follow PATH`` reads first: PATH, or, where PATH names a rotation that has only
    numbered files (``site.mcap`` → ``site-0007.mcap``), its newest file."""
    if os.path.exists(path):
        return path
    numbered = rotated_files(path)
    return numbered[-1] if numbered else path


class FollowingReader:
    """A reader of a growing recording: its batches come from a thread, so that while the file
    does not grow this one can say so (``QUIET``, an empty batch, once per quiet spell) and the
    decoding can close the frame it holds open instead of waiting for the next bytes. A file of
    a rotation is followed into the next one, as ``tail -F`` follows a log: ``open_next`` opens
    it once it appears (within ``NEXT_FILE_S`` of the last one ending)."""

    def __init__(self, reader: CaptureReader, *, path: str | None = None,
                 open_next: Callable[[str], CaptureReader] | None = None,
                 quiet_after_s: float = QUIET_AFTER_S, next_file_s: float = NEXT_FILE_S) -> None:
        self._reader, self._quiet_after_s = reader, quiet_after_s
        self._path, self._open_next, self._next_file_s = path, open_next, next_file_s
        #: The files read, in order (the first one's ``info`` is the capture's).
        self.files: list[str] = [path] if path else []
        self.info: CaptureInfo = reader.info
        self.late_notes: list[str] = reader.late_notes
        self.warnings: list[str] = reader.warnings
        self._items: queue.Queue[ChunkBatch | BaseException | None] = queue.Queue(maxsize=QUEUED_BATCHES)
        self._thread = threading.Thread(target=self._read, name="rtusniff-follow", daemon=True)

    def last_time_ns(self) -> int | None:
        return None  # a growing file has no end to measure progress against

    def close(self) -> None:
        self._reader.close()

    def _next_reader(self) -> CaptureReader | None:
        """The rotation's next file, once it appears; ``None`` when none comes (or following stopped)."""
        following = next_rotated(self._path) if self._path and self._open_next else None
        if following is None or self._open_next is None:
            return None
        deadline = time.monotonic() + self._next_file_s
        while not os.path.exists(following):
            if STOP.is_set() or time.monotonic() > deadline:
                return None
            time.sleep(POLL_S)
        self._reader.close()
        self._path = following
        self.files.append(following)
        reader = self._open_next(following)
        self.late_notes.extend(reader.late_notes)
        return reader

    def batches(self) -> Iterator[ChunkBatch]:
        self._thread.start()
        quiet_told = True  # nothing to close before the first bytes
        while True:
            try:
                item = self._items.get(timeout=self._quiet_after_s)
            except queue.Empty:
                if not quiet_told:
                    quiet_told = True
                    yield QUIET
                continue
            quiet_told = False
            batches, last = self._joined(item)
            if batches:
                yield ChunkBatch.concat(batches)
            if last is None:
                return
            if isinstance(last, BaseException):
                raise last

    def _joined(self, item: ChunkBatch | BaseException | None) -> tuple[list[ChunkBatch], BaseException | bool | None]:
        """``item`` and the batches queued behind it (catching up on what was written before),
        up to ``JOINED_BYTES``; and what ended them: ``True`` (more may come), the end (``None``)
        or a failure."""
        batches: list[ChunkBatch] = []
        size = 0
        while isinstance(item, ChunkBatch):
            batches.append(item)
            size += len(item.data)
            if size >= JOINED_BYTES:
                return batches, True
            try:
                item = self._items.get_nowait()
            except queue.Empty:
                return batches, True
        return batches, item

    def _read(self) -> None:
        try:
            reader: CaptureReader | None = self._reader
            while reader is not None:
                self._reader = reader
                for batch in reader.batches():
                    self._items.put(batch)
                self.warnings.extend(warning for warning in reader.warnings if warning not in self.warnings)
                reader = self._next_reader()
            self._items.put(None)
        except BaseException as exc:
            self._items.put(exc)

"""``--line auto``: find the line settings by listening.

Each candidate setting is opened in turn and listened to for a while; the bytes heard
are framed, and the setting under which the largest share of them forms frames with
valid CRCs wins. What was chosen, and how sure, is said in one line.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from decoders.capture import Chunk, ChunkBatch, TimingQuality
from decoders.framer import Framer
from decoders.line import LineSettings
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.serial_source import SerialSource

CANDIDATES = [
    "19200 8E1", "9600 8E1", "19200 8N1", "9600 8N1", "38400 8E1", "115200 8N1", "57600 8N1",
    "38400 8N1", "4800 8E1", "19200 8O1", "9600 8O1", "19200 8N2", "9600 8N2",
]  # fmt: skip


#: How long ``--line auto`` listens to each setting unless told (``capture --probe-seconds``, the extcap).
PROBE_SECONDS = 1.5
#: How far (a share of the bytes heard) another setting must read worse for the choice to be sure.
SURE_MARGIN = 0.1


@dataclass(frozen=True)
class Trial:
    line: LineSettings
    heard: int
    valid: int
    frames: int
    refused: str | None = None

    @property
    def share(self) -> float:
        return self.valid / self.heard if self.heard else 0.0


def probe_line(port: str, seconds: float, candidates: list[str] | None = None) -> tuple[LineSettings, str]:
    """The best setting and a line that says why."""
    trials = [_listen(port, LineSettings.parse(text), seconds) for text in candidates or CANDIDATES]
    heard = [t for t in trials if t.heard]
    if not heard:
        refused = [t.line.format() for t in trials if t.refused]
        extra = f" ({len(refused)} settings the port refused)" if refused else ""
        raise RtuSniffError(ErrorKind.RUNTIME, f"no traffic heard in {seconds:g} s per setting{extra}; "
                            "give the settings with --line BAUD FORMAT", path=port)
    # The best share wins; within a percent of it, the more common setting (earlier in the list).
    top = max(t.share for t in heard)
    best = next(t for t in heard if t.share >= top - 0.01)
    others = sorted((t for t in heard if t is not best), key=lambda t: -t.share)
    runner_up = f"; next best {others[0].line.format()}: {others[0].share:.0%}" if others else ""
    report = (f"line {best.line.format()} chosen ({certainty(best, others)}): {best.share:.0%} of {best.heard} "
              f"bytes formed {best.frames} valid frames{runner_up}")
    if best.valid == 0:
        raise RtuSniffError(ErrorKind.RUNTIME, f"no setting gives valid frames ({report}); give --line", path=port)
    return best.line, report


def certainty(best: Trial, others: list[Trial]) -> str:
    """How sure the choice is: ``sure`` where nearly every byte heard formed valid frames and no
    other setting came near (a pseudo-terminal, which has no baud rate, gives every setting 100 %:
    that is a tie, and a tie is never sure); else ``not sure``, naming the settings that tied."""
    tied = [trial for trial in others if trial.share >= best.share - SURE_MARGIN]
    if tied:
        names = ", ".join(trial.line.format() for trial in tied[:3]) + (", …" if len(tied) > 3 else "")
        return f"not sure: {names} read as well; the commoner setting is taken"
    return "sure" if best.share >= 0.9 and best.frames >= 3 else "not sure"


def _listen(port: str, line: LineSettings, seconds: float) -> Trial:
    source = SerialSource(port, line)
    try:
        source.open()
    except RtuSniffError as exc:
        return Trial(line, 0, 0, 0, refused=str(exc))
    chunks: list[Chunk] = []
    try:
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            chunk = source.read(min(left, 0.1))
            if chunk is not None:
                chunks.append(chunk)
    finally:
        source.close()
    if not chunks:
        return Trial(line, 0, 0, 0)
    framer = Framer(line, TimingQuality.HOST)
    frames = [*framer.feed(ChunkBatch.from_chunks(chunks)), *framer.flush()]
    valid = [f for f in frames if f.crc_ok and not f.is_noise]
    return Trial(line, sum(len(c.data) for c in chunks), sum(len(f.data) for f in valid), len(valid))

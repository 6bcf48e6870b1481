"""Do the bytes fit the line settings? A wrong baud rate must not pass in silence.

Decoded at 9600 Bd, a 19200 Bd capture still "frames" (content finds the frames), but
every time derived from the line is wrong: negative silences, dozens of false
``short_idle``. The bytes themselves say so: a line cannot carry characters faster
than one per character time.

* ``exact`` captures (bytes stamped at the end of their stop bit): two chunks closer
  than the second one's characters take on the wire, with :data:`EXACT_SLACK` for
  clock rounding, are impossible at these settings.
* ``host`` captures (stamped when the PC read them): reads come in bursts, so single
  gaps prove nothing; but over any :data:`HOST_WINDOW_NS` the bytes read cannot exceed
  what the line carries in that window plus :data:`HOST_BUFFER_BYTES` held in buffers.

The check counts violations; :meth:`LineRateCheck.warning` words them once, at the end.
"""

from __future__ import annotations

import numpy as np

from decoders.capture import ChunkBatch, TimingQuality
from decoders.line import LineSettings

#: An exact gap may be this share of the characters' wire time short (timestamp rounding,
#: a logic analyzer's sample clock against the sender's baud clock: a few percent at most).
EXACT_SLACK = 0.2
#: The window over which host read rates are compared with the line's rate.
HOST_WINDOW_NS = 1_000_000_000
#: Bytes a host window may hold beyond the line rate: USB adapter and driver buffers
#: delivered late (an FTDI holds up to 4 KiB).
HOST_BUFFER_BYTES = 4096
#: Too-fast chunks below this count are called rounding, not a wrong line.
MIN_VIOLATIONS = 3


class LineRateCheck:
    """Fed every chunk batch of a capture, in order; says whether the bytes came faster
    than ``line`` allows."""

    def __init__(self, line: LineSettings, timing: TimingQuality) -> None:
        self.line = line
        self.timing = timing
        self.chunks = 0
        self.too_fast = 0
        self._last_end_ns: int | None = None
        # Host: the chunks of the last window (ends and lengths), carried between batches.
        self._ends = np.zeros(0, np.int64)
        self._lengths = np.zeros(0, np.int64)
        self._worst_bytes = 0

    def feed(self, batch: ChunkBatch) -> None:
        if not len(batch):
            return
        ends = batch.t_end_ns
        lengths = np.diff(batch.ends, prepend=0).astype(np.int64)
        self.chunks += len(batch)
        if self.timing is TimingQuality.EXACT:
            self._feed_exact(ends, lengths)
        else:
            self._feed_host(ends, lengths)

    def _feed_exact(self, ends: np.ndarray, lengths: np.ndarray) -> None:
        previous = np.concatenate(([self._last_end_ns if self._last_end_ns is not None else -(2**62)], ends[:-1]))
        needed = lengths * self.line.char_time_ns * (1 - EXACT_SLACK)
        self.too_fast += int(np.count_nonzero((ends - previous) < needed))
        self._last_end_ns = int(ends[-1])

    def _feed_host(self, ends: np.ndarray, lengths: np.ndarray) -> None:
        all_ends = np.concatenate((self._ends, ends))
        all_lengths = np.concatenate((self._lengths, lengths))
        total = np.cumsum(all_lengths)
        # Bytes read in the window that ends at each new chunk (itself included).
        starts = np.searchsorted(all_ends, all_ends[len(self._ends):] - HOST_WINDOW_NS, side="right")
        before = np.where(starts > 0, total[np.maximum(starts - 1, 0)], 0)
        in_window = total[len(self._ends):] - before
        allowed = HOST_WINDOW_NS / self.line.char_time_ns + HOST_BUFFER_BYTES
        self.too_fast += int(np.count_nonzero(in_window > allowed))
        self._worst_bytes = max(self._worst_bytes, int(in_window.max()))
        keep = all_ends > all_ends[-1] - HOST_WINDOW_NS
        self._ends, self._lengths = all_ends[keep], all_lengths[keep]

    def warning(self) -> str | None:
        """One sentence when the bytes do not fit the line settings, else ``None``."""
        if self.too_fast < MIN_VIOLATIONS:
            return None
        line = self.line.format()
        if self.timing is TimingQuality.EXACT:
            evidence = (f"{self.too_fast} of {self.chunks} stamped chunks came sooner after the one before than "
                        f"their characters take at {line}")
        else:
            evidence = (f"up to {self._worst_bytes} bytes were read within one second, more than {line} carries "
                        "plus the adapter's buffers")
        return (f"the bytes come faster than the line settings allow ({evidence}): a faster baud rate? "
                "Times, silences and short_idle flags are wrong until --line is right")

"""How late a host capture's read loop delivers bytes, learned from the frames themselves.

A host-timed capture records when each read returned, not when its bytes were on
the wire; how late that can be depends on the read loop (a USB latency timer of
16 ms, a pyserial ``read(N)`` that waits out a 500 ms timeout, ...). Two silences
in the host times show it, because content says the wire had none there (or only
the slave's turnaround):

* inside a CRC-valid frame: its bytes were contiguous, so a silence between them is
  how late the read holding the rest of the frame came;
* between a request and the next frame, its answer: the same slave and function, the
  first frame fitting only the request layout and the second only the response one.

:class:`DeliveryDelay` keeps the longest of these; the decoder never times out an
answer sooner than twice that (:class:`decoders.pipeline.Decoder`).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from decoders.byte_times import ByteClock
from decoders.capture import Int64Array
from decoders.framing.rule_tables import REQUEST_RULES, RESPONSE_RULES, padded_bytes
from decoders.modbus.codes import EXCEPTION_BIT


class DeliveryDelay:
    """The longest delivery delay seen so far, in ns (0 until a frame shows one)."""

    def __init__(self) -> None:
        self.longest_ns = 0

    def learn(
        self, data: bytes, times: tuple[ByteClock, Int64Array, Int64Array], pieces: tuple[Int64Array, Int64Array],
        valid: npt.NDArray[np.bool_],
    ) -> None:
        """Learn from the pieces ``[first[i], last[i])`` of ``data`` (``valid``: CRC-valid
        frames) whose bytes' host times ``times`` give: their clock, and the silences where
        its chunks meet (:meth:`ByteClock.silences`; inside a chunk there are none)."""
        clock, silent_at, silences = times
        first, last = pieces
        frames = np.flatnonzero(valid & (last - first >= 2))
        if not len(frames):
            return
        # The largest silence before bytes first+1 .. last-1 of a valid frame.
        frame_first, frame_last = first[frames], last[frames]
        holder = np.searchsorted(frame_first, silent_at, side="right") - 1
        held = holder >= 0
        inside = held & (silent_at > frame_first[holder]) & (silent_at < frame_last[holder])
        inner = int(silences[inside].max()) if inside.any() else 0
        self.longest_ns = max(self.longest_ns, inner, self._answer_silence(data, clock, frame_first, frame_last))

    @staticmethod
    def _answer_silence(data: bytes, clock: ByteClock, first: Int64Array, last: Int64Array) -> int:
        """The longest silence between a request and the valid frame after it that answers it."""
        if len(first) < 2:
            return 0
        padded = padded_bytes(data)
        lengths = last - first
        functions = padded[first + 1].astype(np.intp)
        plain = (functions & EXCEPTION_BIT) == 0
        as_request = plain & REQUEST_RULES.fits(padded, first, functions, lengths)
        as_response = plain & RESPONSE_RULES.fits(padded, first, functions, lengths)
        ask = as_request[:-1] & ~as_response[:-1]
        answer = as_response[1:] & ~as_request[1:]
        same = (padded[first[:-1]] == padded[first[1:]]) & (functions[:-1] == functions[1:]) & (padded[first[1:]] != 0)
        pairs = np.flatnonzero(ask & answer & same)
        if not len(pairs):
            return 0
        return int((clock.starts_at(first[pairs + 1]) - clock.ends_at(last[pairs] - 1)).max())

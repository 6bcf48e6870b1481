"""What broke in a damaged frame: its CRC as received against the CRC of its bytes, and, for a
damaged answer the master asked for again, which bytes differ from the good answer.

A damaged answer followed by a retry of the same request and a good answer of the same length
is the clearest evidence a sniffer can give of a disturbed line: the two answers should be
equal (a slave that holds its values answers the same bytes), so the bytes that differ are
what the line changed, often a single bit (``58`` → ``50``).
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from decoders.capture import uart_error_name
from decoders.crc import crc_bytes
from decoders.message import ROLE_CODE, MessageBatch, Role

#: Requests remembered for comparing the two answers' requests.
KEPT_DAMAGED = 64
#: Frames after a damaged answer within which its good retry is looked for.
RETRY_FRAMES = 8
_REQUESTS = [ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.BROADCAST]]
_NOISE = ROLE_CODE[Role.NOISE]
#: Differing bytes listed before "and N more".
LISTED_BYTES = 4


def crc_note(data: bytes) -> str | None:
    """``CRC c8 a5 on the wire, c9 a5 computed`` (bytes in wire order, as a hex dump shows
    them) for a frame whose CRC is wrong; ``None`` when it is right or the frame too short."""
    if len(data) < 4:
        return None
    received, expected = data[-2:], crc_bytes(data[:-2])
    if received == expected:
        return None
    return f"CRC {received.hex(' ')} on the wire, {expected.hex(' ')} computed"


def uart_error_note(marks: tuple[tuple[int, int], ...]) -> str:
    """``UART framing error at byte 1, parity error at byte 4`` (positions from 0, as in
    ``byte_diff``) for a frame with characters the receiver found wrong."""
    parts = [f"{uart_error_name(kind)} error at byte {position}" for position, kind in marks[:LISTED_BYTES]]
    more = f" and {len(marks) - LISTED_BYTES} more" if len(marks) > LISTED_BYTES else ""
    return f"UART {', '.join(parts)}{more}"


def byte_diff(damaged: bytes, good: bytes) -> str:
    """Where ``damaged`` differs from ``good`` (same length), byte positions from 0."""
    places = [i for i in range(len(good)) if damaged[i] != good[i]]
    parts = []
    for place in places[:LISTED_BYTES]:
        flipped = damaged[place] ^ good[place]
        bits = bin(flipped).count("1")
        what = "one bit" if bits == 1 else f"{bits} bits"
        parts.append(f"byte {place} {damaged[place]:02x}, good {good[place]:02x} ({what}, 0x{flipped:02x})")
    more = f" and {len(places) - LISTED_BYTES} more" if len(places) > LISTED_BYTES else ""
    return "; ".join(parts) + more


class RetryDiff:
    """Follows the capture in order; for each good answer that follows a damaged one from the
    same slave and function, of the same length, within ``RETRY_FRAMES`` frames, to a request
    with the same bytes (where both requests were seen), says how the damaged one differed."""

    def __init__(self) -> None:
        #: Bytes of recent requests by frame index.
        self._requests: OrderedDict[int, bytes] = OrderedDict()
        #: Damaged answers waiting for a good one: (frame index, request index, bytes).
        self._damaged: list[tuple[int, int, bytes]] = []

    def notes(self, batch: MessageBatch) -> dict[int, str]:
        """Notes by position in ``batch`` for the good answers that follow a damaged one."""
        frames = batch.frames
        broken = ~frames.crc_ok & (batch.role != _NOISE)
        # Only frames within RETRY_FRAMES after a damaged one (or after one still waiting) matter.
        near = np.zeros(len(batch) + RETRY_FRAMES + 1, np.int64)
        if self._damaged:
            near[0] += 1
            near[max(self._damaged[-1][0] + RETRY_FRAMES - frames.first_index + 1, 0)] -= 1
        starts = np.flatnonzero(broken)
        np.add.at(near, starts, 1)
        np.add.at(near, starts + RETRY_FRAMES + 1, -1)
        wanted = np.flatnonzero(np.cumsum(near)[: len(batch)] > 0)
        notes = self._walk(batch, broken, wanted) if len(wanted) else {}
        self._remember_requests(batch)
        return notes

    def _remember_requests(self, batch: MessageBatch) -> None:
        """The bytes of the batch's last requests, for answers in the next batch."""
        for position in np.flatnonzero(np.isin(batch.role, _REQUESTS))[-RETRY_FRAMES:].tolist():
            self._remember_request(batch, batch.frames.first_index + position)

    def _walk(self, batch: MessageBatch, broken: np.ndarray, wanted: np.ndarray) -> dict[int, str]:
        frames, notes = batch.frames, {}
        offsets, data, first = frames.offsets, frames.data, frames.first_index
        roles, requests = batch.role[wanted].tolist(), batch.request_index[wanted].tolist()
        for position, role, request, is_bad in zip(wanted.tolist(), roles, requests, broken[wanted].tolist(),
                                                   strict=True):
            index = first + position
            self._damaged = [d for d in self._damaged if index - d[0] <= RETRY_FRAMES]
            if role == _NOISE or role in _REQUESTS:
                continue
            self._remember_request(batch, request)
            payload = data[offsets[position] : offsets[position + 1]]
            if is_bad:
                self._damaged.append((index, request, payload))
            elif self._damaged:
                note = self._compare(payload, request)
                if note:
                    notes[position] = note
        return notes

    def _remember_request(self, batch: MessageBatch, request: int) -> None:
        position = request - batch.frames.first_index
        if 0 <= position < len(batch):
            frames = batch.frames
            self._requests[request] = frames.data[frames.offsets[position] : frames.offsets[position + 1]]
            if len(self._requests) > KEPT_DAMAGED:
                self._requests.popitem(last=False)

    def _compare(self, good: bytes, request: int) -> str | None:
        for entry in self._damaged:
            index, damaged_request, damaged = entry
            asked, asked_again = self._requests.get(damaged_request), self._requests.get(request)
            if len(damaged) != len(good) or damaged[:2] != good[:2] or damaged == good or damaged_request == request:
                continue
            if asked is not None and asked_again is not None and asked != asked_again:
                continue
            self._damaged.remove(entry)
            return f"good retry of damaged #{index}: {byte_diff(damaged, good)}"
        return None

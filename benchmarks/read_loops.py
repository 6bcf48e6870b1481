"""How real read loops deliver a wire's bytes: host-timed captures from exact ones.

A passive tap on a PC records what its read loop got and when: a chunk per read,
stamped when the read returned. The models here take an exact capture (every
byte's true end on the wire) and give the host-timed capture a read loop would
record, for tests and benchmarks (``benchmarks.generate_capture --timing``):

* ``usb-1ms``, ``usb-16ms``: a USB adapter's latency timer
  (:func:`benchmarks.wire_synthesis.usb_adapter_chunks`);
* ``read-timeout``: pyserial ``read(32)`` with a 500 ms timeout: a read returns
  when 32 bytes are in, often mid-frame, and the rest of that frame comes with
  the next read, up to the timeout later;
* ``in-waiting``: ``in_waiting`` polled every 2-8 ms, then ``read(in_waiting)``;
* ``random-sizes``: reads of 1-64 bytes chosen at random, 50 ms timeout;
* ``slow-delivery``: ``read(256)`` with a 300 ms timeout: every read waits out its
  timeout, so an answer usually arrives one read after its request.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from benchmarks.wire_synthesis import usb_adapter_chunks
from decoders.capture import Chunk
from decoders.line import LineSettings

MS = 1_000_000


def wire_byte_ends(chunks: Iterable[Chunk], line: LineSettings) -> tuple[bytes, list[int]]:
    """The bytes of an exact capture and the end of each one's stop bit."""
    data = bytearray()
    ends: list[int] = []
    for chunk in chunks:
        last = len(chunk.data) - 1
        ends.extend(chunk.t_end_ns - round((last - i) * line.char_time_ns) for i in range(len(chunk.data)))
        data += chunk.data
    return bytes(data), ends


@dataclass(frozen=True)
class ReadLoop:
    """A read loop: how many bytes each read asks for, how long it waits, what runs between reads."""

    name: str
    sizes: Callable[[random.Random], int]
    timeout_ns: int
    #: Time between a read's return and the next read's start (the loop's own work).
    processing_ns: tuple[int, int] = (0, MS)
    #: Delay between a read's return and its time stamp.
    jitter_ns: int = 200_000
    #: ``in_waiting`` polling: a read takes what is there at each poll, never waits.
    poll_ns: tuple[int, int] | None = None

    def deliver(self, chunks: Iterable[Chunk], line: LineSettings, seed: int = 0) -> list[Chunk]:
        """What this loop records of an exact capture."""
        data, ends = wire_byte_ends(chunks, line)
        rng = random.Random(f"{self.name}/{seed}")
        delivered: list[Chunk] = []
        taken = 0
        now = ends[0] - rng.randrange(self.timeout_ns or MS) if ends else 0
        last_stamp = 0
        while taken < len(data):
            if self.poll_ns is not None:
                now += rng.randint(*self.poll_ns)
                available = _count_until(ends, taken, now)
                if available == taken:
                    continue
                returned, until = now, available
            else:
                want = taken + self.sizes(rng)
                deadline = now + self.timeout_ns
                if want <= len(data) and ends[want - 1] <= deadline:
                    returned, until = max(now, ends[want - 1]), want
                else:
                    until = _count_until(ends, taken, deadline)
                    returned = deadline
                    if until == taken:
                        now = deadline
                        continue
            stamp = max(last_stamp, returned + rng.randrange(self.jitter_ns + 1))
            delivered.append(Chunk(stamp, data[taken:until]))
            last_stamp, taken = stamp, until
            now = returned + rng.randint(*self.processing_ns)
        return delivered


def _count_until(ends: list[int], taken: int, moment: int) -> int:
    """How many bytes have fully arrived by ``moment`` (at least ``taken``)."""
    count = taken
    while count < len(ends) and ends[count] <= moment:
        count += 1
    return count


def _usb(latency_ms: float) -> Callable[[Iterable[Chunk], LineSettings, int], list[Chunk]]:
    def deliver(chunks: Iterable[Chunk], line: LineSettings, seed: int = 0) -> list[Chunk]:
        return usb_adapter_chunks(chunks, line, latency_ns=int(latency_ms * MS), seed=seed)

    return deliver


READ_LOOPS: dict[str, Callable[[Iterable[Chunk], LineSettings, int], list[Chunk]]] = {
    "usb-1ms": _usb(1.0),
    "usb-16ms": _usb(16.0),
    "read-timeout": ReadLoop("read-timeout", lambda rng: 32, 500 * MS).deliver,
    "in-waiting": ReadLoop("in-waiting", lambda rng: 0, 0, poll_ns=(2 * MS, 8 * MS)).deliver,
    "random-sizes": ReadLoop("random-sizes", lambda rng: rng.randint(1, 64), 50 * MS).deliver,
    "slow-delivery": ReadLoop("slow-delivery", lambda rng: 256, 300 * MS).deliver,
}

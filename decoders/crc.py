"""CRC-16/MODBUS (init 0xFFFF, reflected polynomial 0xA001, sent low byte first).

The per-frame function is the Rust ``fastcrc`` package, many times the pure-Python table's
speed (``benchmarks/bench_crc.py``).
A pure-Python table version is the oracle the tests hold ``fastcrc`` to (``tests/oracles.py``).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import numpy.typing as npt
from fastcrc import crc16


def _make_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        table.append(crc)
    return tuple(table)


CRC_TABLE = _make_table()


def crc16_modbus(data: bytes) -> int:
    """CRC-16/MODBUS of ``data`` as an integer (wire order: low byte, then high byte)."""
    return int(crc16.modbus(data))


def crc_bytes(data: bytes) -> bytes:
    """The two CRC bytes in wire order, ready to append to ``data``."""
    return crc16_modbus(data).to_bytes(2, "little")


def crc_ok(frame: bytes) -> bool:
    """Whether the last two bytes of ``frame`` are the CRC of the bytes before them."""
    if len(frame) < 3:
        return False
    return crc16_modbus(frame[:-2]) == frame[-2] | (frame[-1] << 8)


#: Spans shorter than this never pass: a frame has an address and a function code before its CRC.
MIN_CHECKED = 3
#: Frame lengths checked in lockstep (see :func:`crc_ok_many`) when at least this many share one.
LOCKSTEP_MIN_FRAMES = 16
LOCKSTEP_MAX_LENGTH = 64
#: :data:`CRC_TABLE` as an array, for the numpy paths below.
_STEP_TABLE = np.array(CRC_TABLE, np.uint32)


def crc_ok_many(data: bytes, offsets: npt.NDArray[np.int64]) -> npt.NDArray[np.bool_]:
    """CRC check of every frame ``data[offsets[i]:offsets[i+1]]``.

    A frame followed by its own CRC (low byte first) leaves the CRC register at zero.
    Frames of one length (a bus has a few: its requests, its answers) are stepped in
    lockstep by numpy, two bytes a step through a table of 65 536 registers; lengths
    that fewer than ``LOCKSTEP_MIN_FRAMES`` frames share, or longer than
    ``LOCKSTEP_MAX_LENGTH``, go one ``fastcrc`` call a frame as in
    :func:`tests.oracles.crc_ok_many_reference`. Twice as fast on the polling benchmark
    (``python -m benchmarks.bench_crc``). The frames are grouped by length in one stable sort
    of their lengths as bytes (a radix sort), longer ones in one group past the longest.
    """
    lengths = np.diff(offsets)
    valid = np.zeros(len(lengths), np.bool_)
    if not len(lengths):
        return valid
    starts = offsets[:-1]
    capped = np.minimum(lengths, LOCKSTEP_MAX_LENGTH + 1).astype(np.uint8)
    order = np.argsort(capped, kind="stable")
    grouped = capped[order]
    edges = [0, *(np.flatnonzero(grouped[1:] != grouped[:-1]) + 1).tolist(), len(order)]
    words: _Words | None = None
    for begin, end in itertools.pairwise(edges):
        size = int(grouped[begin])
        if size < MIN_CHECKED:
            continue
        rows = order[begin:end]
        if end - begin < LOCKSTEP_MIN_FRAMES or size > LOCKSTEP_MAX_LENGTH:
            bounds = zip(starts[rows].tolist(), offsets[rows + 1].tolist(), strict=True)
            valid[rows] = [crc16.modbus(data[start:stop]) == 0 for start, stop in bounds]
        else:
            words = words or _Words(data)
            valid[rows] = words.remainders(starts[rows], size) == 0
    return valid


def _pair_table() -> npt.NDArray[np.uint16]:
    """``table[r]``: the register after two bytes, where ``r`` is the register with the two
    bytes (the first low) already XORed in: their two table steps depend on ``r`` alone."""
    registers = np.arange(1 << 16, dtype=np.uint32)
    for _ in range(2):
        registers = (registers >> 8) ^ _STEP_TABLE[registers & 0xFF]
    return registers.astype(np.uint16)


_PAIR_TABLE = _pair_table()


def _first_byte_table() -> npt.NDArray[np.uint16]:
    """``table[b]``: the register after the single byte ``b`` from the initial 0xFFFF."""
    registers = np.full(256, 0xFFFF, np.uint32)
    table: npt.NDArray[np.uint16] = ((registers >> 8) ^ _STEP_TABLE[(registers ^ np.arange(256, dtype=np.uint32))
                                                                    & 0xFF]).astype(np.uint16)
    return table


_FIRST_BYTE_TABLE = _first_byte_table()


class _Words:
    """A run of bytes as little-endian 16-bit words from every offset: those from even offsets,
    then those from odd ones, so any frame's byte pairs are one gather (no bytes widened)."""

    def __init__(self, data: bytes) -> None:
        self.wire = np.frombuffer(data, np.uint8)
        self.even = len(data) // 2
        # From a copy one byte on: a view at an odd offset would be unaligned, slow to copy.
        odd = np.frombuffer(data[1:], "<u2", count=(len(data) - 1) // 2)
        self.words = np.concatenate([np.frombuffer(data, "<u2", count=self.even), odd])

    def remainders(self, starts: npt.NDArray[np.int64], size: int) -> npt.NDArray[np.uint16]:
        """The CRC register after each frame ``data[starts[i]:starts[i] + size]``, all stepped
        in lockstep: an odd length's first byte alone, then two bytes a step."""
        first = size % 2
        # An odd length: its first byte alone, then pairs.
        register = _FIRST_BYTE_TABLE[self.wire[starts]] if first else np.full(len(starts), 0xFFFF, np.uint16)
        pairs_at = starts + first
        at = (pairs_at >> 1) + (pairs_at & 1) * self.even
        columns = self.words[at + np.arange(size // 2)[:, None]]  # a row per word of the frames
        for column in columns:
            register = _PAIR_TABLE.take(register ^ column)  # take: faster than indexing
        return register


#: Spans up to this long are checked by :func:`crc_ok_spans`.
MAX_SPAN = 320


def _zero_shift_tables() -> npt.NDArray[np.uint32]:
    """``tables[0, x, n]`` / ``tables[1, x, n]``: the register ``x`` / ``x << 8`` after n
    zero bytes, with no initial value (CRC is linear: a register's effect splits by byte). The
    shifts of one register lie side by side, for :func:`crc_ok_lengths` to slice; gathering
    across them (:func:`crc_ok_spans`) is as fast as from a table laid out shift first."""
    tables = np.empty((2, 256, MAX_SPAN + 1), np.uint32)
    current = np.stack([np.arange(256, dtype=np.uint32), np.arange(256, dtype=np.uint32) << 8])
    for shift in range(MAX_SPAN + 1):
        tables[:, :, shift] = current
        current = (current >> 8) ^ _STEP_TABLE[current & 0xFF]
    return tables


_ZERO_SHIFT = _zero_shift_tables()


def _shifted(registers: npt.NDArray[np.uint32], counts: npt.NDArray[np.int64]) -> npt.NDArray[np.uint32]:
    """Each register carried through ``counts`` zero bytes (no initial value)."""
    shifted: npt.NDArray[np.uint32] = _ZERO_SHIFT[0, registers & 0xFF, counts] ^ _ZERO_SHIFT[1, registers >> 8, counts]
    return shifted


def prefix_registers(data: bytes) -> npt.NDArray[np.uint32]:
    """``registers[k]``: the CRC register after ``data[:k]`` (``registers[0]`` = 0xFFFF).

    Blocks of ``data`` are stepped in lockstep by numpy, one byte position of every
    block at a time, from each block's initial register (chained by ``fastcrc``). Narrow
    blocks make many ``fastcrc`` calls, wide ones many numpy steps of few elements: a quarter
    of the square root of the size, 16 to 128 bytes, is faster than the square root (at least
    64) from 3 kB to 2 MB (a host-timed batch holds about 450 kB).
    """
    size = len(data)
    block = min(128, max(16, math.isqrt(size) // 4))
    blocks = -(-size // block) if size else 0
    initial = np.empty(blocks, np.uint32)
    register = 0xFFFF
    for k in range(blocks):
        initial[k] = register
        register = crc16.modbus(data[k * block : (k + 1) * block], initial=register)
    matrix = np.frombuffer(data + bytes(blocks * block - size), np.uint8).reshape(blocks, block)
    steps = np.empty((blocks, block), np.uint32)
    current = initial
    for column in range(block):
        current = (current >> 8) ^ _STEP_TABLE[(current ^ matrix[:, column]) & 0xFF]
        steps[:, column] = current
    registers = np.empty(size + 1, np.uint32)
    registers[0] = 0xFFFF
    registers[1:] = steps.ravel()[:size]
    return registers


def crc_ok_lengths(registers: npt.NDArray[np.uint32], start: int, shortest: int, longest: int) -> list[int]:
    """The lengths ``shortest..longest`` (3..``MAX_SPAN``) at which the span from ``start``
    passes the CRC, from :func:`prefix_registers`: :func:`crc_ok_spans` of them all, with the
    start's register shifted through every length at once (two rows of a table) instead of
    gathered per length (a CRC search tries some 250 lengths from one start)."""
    if longest < shortest:
        return []
    initial = int(registers[start]) ^ 0xFFFF
    shifted = _ZERO_SHIFT[0, initial & 0xFF, shortest : longest + 1] ^ _ZERO_SHIFT[1, initial >> 8,
                                                                                    shortest : longest + 1]
    own = registers[start + shortest : start + longest + 1] ^ shifted
    found: list[int] = (np.flatnonzero(own == 0) + shortest).tolist()
    return found


def crc_ok_spans(
    registers: npt.NDArray[np.uint32], starts: npt.NDArray[np.int64], lengths: npt.NDArray[np.int64]
) -> npt.NDArray[np.bool_]:
    """Whether each span ``data[starts[i] : starts[i] + lengths[i]]`` passes the CRC, from
    :func:`prefix_registers` (lengths 3..``MAX_SPAN``): the span's own register from
    0xFFFF is ``R[end] ^ shift(R[start] ^ 0xFFFF, length)``, zero when the CRC holds."""
    own = registers[starts + lengths] ^ _shifted(registers[starts] ^ np.uint32(0xFFFF), lengths)
    valid: npt.NDArray[np.bool_] = (own == 0) & (lengths >= 3)
    return valid

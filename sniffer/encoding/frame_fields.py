"""The fields of JSONL frame records that no decoding says, laid out a batch at a time.

Index, times, flags, pairing and latency are columns of the batch; so is who a frame is (bytes,
CRC, slave, function, role, exception), which for a batch of many distinct frames is laid out
here too (:data:`IDENTITIES_FROM`). None of it needs a decoding, so :func:`frame_fields` runs
where frames are paired (the JSONL view's ``prepare``: the decoding process with ``--jobs 2``);
:class:`sniffer.encoding.records.FrameRecordEncoder` joins it with each decoding's part.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from decoders.decoded_batch import mostly_distinct
from decoders.frame import FrameFlag, flag_set
from decoders.message import NONE, ROLE_NAMES, MessageBatch
from decoders.runs import spread
from sniffer.encoding.blocks import Block, times_matrix
from sniffer.encoding.float_text import float_texts
from sniffer.encoding.rows import Column, Pieces, Table, hex_texts, join_rows, number_texts, or_null

NS_PER_S = 1e9
#: The share of distinct frames from which a batch's frames say who they are in columns
#: (:class:`FrameFields`): a little less a frame, all of them, where frames are paired (the
#: decoding process, which has time to spare where frames are new) than a new decoding costs
#: where they are annotated; below it, repeats are spelt once per group where they are written.
IDENTITIES_FROM = 0.25
#: Each flag set's ``flags`` array, by its value.
FLAG_TEXTS = [json.dumps(list(flag_set(value).names), separators=(",", ":")).encode()
              for value in range(1 << len(FrameFlag))]
_FLAGS_JSON = Table(FLAG_TEXTS)
_CRC_JSON = Table([b"false", b"true"])
_ROLE_JSON = Table([f'"{name}"'.encode() for name in ROLE_NAMES])
#: A byte's number, and ``null`` for :data:`NONE` (the last entry: a key of -1).
_BYTE_JSON = Table([b"%d" % number for number in range(256)] + [b"null"])


@dataclass(frozen=True)
class FrameFields:
    """The fields of frame records that no decoding says, one piece per frame: ``heads`` from
    the record's start to the comma before ``hex`` (kind, index, times), ``middles`` from after
    ``"flags":`` to the comma before ``params`` (flags, pairing, latency). ``identities``: from
    ``hex`` to ``exception_code`` (bytes, CRC, slave, function, role, exception), made only for a
    batch of many distinct frames (:data:`IDENTITIES_FROM`); otherwise the encoder writes them
    once per decoding, which repeats share."""

    heads: Pieces
    middles: Pieces
    identities: Pieces | None = None

    def take(self, rows: npt.NDArray[np.int64]) -> FrameFields:
        """The fields of the frames at ``rows``, in that order."""
        return FrameFields(self.heads.take(rows), self.middles.take(rows),
                           None if self.identities is None else self.identities.take(rows))


def frame_fields(batch: MessageBatch) -> FrameFields:
    """Every frame's :class:`FrameFields`: needs no decoding, so it may be made where frames are
    paired (``prepare``, in the decoding process with ``--jobs 2``)."""
    frames, count = batch.frames, len(batch)
    t_start, t_end, requests = frames.t_start_ns, frames.t_end_ns, batch.request_index
    heads: list[Column] = [
        b'{"kind":"frame","index":', number_texts(np.arange(count, dtype=np.int64) + frames.first_index),
        b',"t":', _seconds(t_start), b',"t_end":', _seconds(t_end),
        b',"t_ns":', number_texts(t_start), b',"t_end_ns":', number_texts(t_end), b",",
    ]  # fmt: skip
    middles: list[Column] = [
        _FLAGS_JSON.column(batch.flags),
        b',"request_index":', or_null(number_texts(requests), requests, NONE),
        b',"latency_s":', or_null(_seconds(batch.latency_ns), batch.latency_ns, NONE), b",",
    ]  # fmt: skip
    identities = _identities(batch) if mostly_distinct(batch, IDENTITIES_FROM) else None
    return FrameFields(_pieces(heads, count), _pieces(middles, count), identities)


@dataclass(frozen=True)
class BlockFields:
    """The fields of MCAP's frame records that no decoding says, one piece per frame: ``heads``
    from the record's start to the comma before ``hex``, laid out to one width
    (:func:`block_heads`), and ``identities`` (``hex`` to ``exception_code``), made only for a
    batch of many distinct frames, as :class:`FrameFields` has them."""

    heads: Pieces
    identities: Pieces | None = None

    def take(self, rows: npt.NDArray[np.int64]) -> BlockFields:
        """The fields of the frames at ``rows``, in that order."""
        return BlockFields(self.heads.take(rows), None if self.identities is None else self.identities.take(rows))


def block_fields(batch: MessageBatch) -> BlockFields:
    """Every frame's :class:`BlockFields`: needs no decoding, so it may be made where frames are
    paired (the MCAP export's ``prepare``, in the decoding process with ``--jobs 2``)."""
    identities = _identities(batch) if mostly_distinct(batch, IDENTITIES_FROM) else None
    return BlockFields(block_heads(batch, np.arange(len(batch), dtype=np.int64)), identities)


def block_heads(batch: MessageBatch, kept: npt.NDArray[np.int64]) -> Pieces:
    """What the frames at ``kept`` say themselves (index, times, flags, pairing, latency), laid
    out as one :class:`~sniffer.encoding.blocks.Block`: the start of their MCAP frame records."""
    frames = batch.frames
    t_start, t_end = frames.t_start_ns[kept], frames.t_end_ns[kept]
    block = Block(len(kept)).text(b'{"kind":"frame","index":')
    block.integers(kept + frames.first_index)
    times = times_matrix(t_start, t_end)  # the digits of each time once, for both spellings
    if times is not None:
        block.matrix(times)
    else:
        block.text(b',"t":').decimals(t_start, 9).text(b',"t_end":').decimals(t_end, 9)
        block.text(b',"t_ns":').integers(t_start).text(b',"t_end_ns":').integers(t_end)
    return (
        block.text(b',"flags":').choice(batch.flags[kept], FLAG_TEXTS)
        .text(b',"request_index":').integers(batch.request_index[kept], NONE)
        .text(b',"latency_s":').decimals(batch.latency_ns[kept], 9, NONE)
        .text(b",")
        .pieces()
    )  # fmt: skip


def _identities(batch: MessageBatch) -> Pieces:
    """Each frame's record from ``hex`` to ``exception_code``."""
    frames = batch.frames
    return _identity_pieces(batch, hex_texts(frames.data, frames.offsets, quoted=True), slice(None))


def identities_at(batch: MessageBatch, positions: npt.NDArray[np.int64]) -> Pieces:
    """:func:`_identities` of the frames at ``positions`` only."""
    frames = batch.frames
    starts, sizes = frames.offsets[positions], np.diff(frames.offsets)[positions]
    taken = np.frombuffer(frames.data, np.uint8)[spread(starts, sizes)]
    offsets = np.zeros(len(positions) + 1, np.int64)
    np.cumsum(sizes, out=offsets[1:])
    return _identity_pieces(batch, hex_texts(taken.tobytes(), offsets, quoted=True), positions)


def _identity_pieces(batch: MessageBatch, hex_column: Pieces, at: npt.NDArray[np.int64] | slice) -> Pieces:
    columns: list[Column] = [
        b'"hex":', hex_column,
        b',"crc_ok":', _CRC_JSON.column(batch.frames.crc_ok[at].view(np.uint8)),
        b',"slave":', _BYTE_JSON.column(batch.slave[at]), b',"function":', _BYTE_JSON.column(batch.function[at]),
        b',"role":', _ROLE_JSON.column(batch.role[at]),
        b',"exception_code":', _BYTE_JSON.column(batch.exception_code[at]),
    ]  # fmt: skip
    return _pieces(columns, len(hex_column))


def _seconds(ns: npt.NDArray[np.int64]) -> Pieces:
    return float_texts(ns / NS_PER_S)


def _pieces(columns: list[Column], count: int) -> Pieces:
    """``columns`` joined into one piece per row (cut in C at a separator no JSON text holds)."""
    rows = join_rows([*columns, b"\x00"], count)
    pieces = bytes(rows.data).split(b"\x00")
    pieces.pop()  # after the last separator
    return Pieces(pieces, rows.lengths() - 1)

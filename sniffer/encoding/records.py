"""JSONL records exactly as docs/jsonl-output.md defines them."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from decoders.capture import CaptureInfo, uart_error_name
from decoders.decoded_batch import AnnotatedBatch
from decoders.frame import PROTOCOL_NAMES, FrameBatch, FrameFlag
from decoders.line import LineSettings
from decoders.memo import KEPT_DECODINGS, Memo
from decoders.message import NONE, ROLE_NAMES, Decoding, DeviceIdentity, MessageBatch
from sniffer.encoding.columnar_parts import ColumnarParts, in_columns_too
from sniffer.encoding.frame_fields import (
    NS_PER_S,
    BlockFields,
    FrameFields,
    block_heads,
    frame_fields,
    identities_at,
)
from sniffer.encoding.param_text import PARAM_JSON, encode_json
from sniffer.encoding.rows import (
    Column,
    Rows,
    Table,
    join_rows,
)


def capture_record(source: str, info: CaptureInfo, line: LineSettings) -> dict[str, Any]:
    """The first record: what the capture is and how far its times can be trusted."""
    return {
        "kind": "capture",
        "source": source,
        "line": line.format(),
        "timing": info.timing.value,
        "char_time_s": line.char_time_ns / NS_PER_S,
        "t1_5_s": line.t1_5_ns / NS_PER_S,
        "t3_5_s": line.t3_5_ns / NS_PER_S,
        "notes": list(info.notes),
        **({"channels": list(info.channels)} if info.channels else {}),
    }


def channel_name(channels: tuple[str, ...], channel: int) -> str:
    """The name of a frame's line (1-based into ``channels``; a number if the capture names none)."""
    return channels[channel - 1] if channel <= len(channels) else str(channel)


def channel_column(frames: FrameBatch, kept: npt.NDArray[np.int64], channels: tuple[str, ...]) -> list[Column]:
    """The ``,"channel":"TX"`` member of each kept frame's record as a column; none when the
    capture says no frame's line."""
    if frames.channels is None:
        return []
    members = [b""] + [b',"channel":' + encode_json(channel_name(channels, code)) for code in range(1, 256)]
    return [Table(members).column(frames.channels[kept])]


def uart_error_records(marks: tuple[tuple[int, int], ...]) -> list[dict[str, Any]]:
    """``uart_errors`` of a frame record: each character the receiver found wrong, by its
    byte's position in ``hex``."""
    return [{"at": position, "error": uart_error_name(kind)} for position, kind in marks]


def uart_error_column(frames: FrameBatch, kept: npt.NDArray[np.int64]) -> list[Column]:
    """The ``,"uart_errors":[...]`` member of each kept frame's record (empty for frames
    without) as a column; no column when no kept frame has one (a capture without UART errors)."""
    if frames.uart_errors is None:
        return []
    marked = (frames.flags[kept] & FrameFlag.UART_ERROR) != 0
    if not marked.any():
        return []
    rows = frames.rows()
    return [[
        b',"uart_errors":' + encode_json(uart_error_records(rows[position].uart_errors)) if flagged else b""
        for position, flagged in zip(kept.tolist(), marked.tolist(), strict=True)
    ]]


_PROTOCOL_JSON = {code: f'"{name}"'.encode() for code, name in PROTOCOL_NAMES.items()}
class FrameRecordEncoder:
    """Frame records as JSON, exactly ``encode_record(frame_record(m))`` (``tests/oracles.py``), a batch at a time.

    Every frame passes through here. What a decoding determines (params, summary, protocol,
    remarks) is encoded once per :class:`Decoding` (the annotator shares one between
    repeats), a profiled param's JSON once per param (:data:`~sniffer.encoding.param_text.PARAM_JSON`); the frame's own
    fields (times, bytes, slave, role, flags, pairing) are columns of the batch
    (:func:`frame_fields`), each formatted at once (numbers by one ``repr``, which is how
    ``json.dumps`` writes them; hex by numpy), and the columns are joined into records by
    :func:`~sniffer.encoding.rows.join_rows`.
    """

    def __init__(self, *, exact: bool = True) -> None:
        """``exact``: spelt as ``json.dumps`` spells it (JSONL); otherwise the times
        (``t``, ``t_end``, ``latency_s``) are the exact decimals of their nanoseconds and the
        frame's own fields come first, padded to one width (:meth:`block_rows`), several
        times faster."""
        self._exact = exact
        #: The capture's line names (:attr:`CaptureInfo.channels`), for the ``channel`` field.
        self.channels: tuple[str, ...] = ()
        # As many as the annotator keeps decodings: a repeat finds its parts.
        self._parts: Memo[Decoding, tuple[bytes, bytes]] = Memo(KEPT_DECODINGS)
        #: A decoding's part alone, for batches whose frames' identities are columns.
        self._tails_alone: Memo[Decoding, bytes] = Memo(KEPT_DECODINGS)
        #: Not exact: a decoding's part of the record in one piece, from ``hex`` to the end.
        self._tails: Memo[Decoding, bytes] = Memo(KEPT_DECODINGS)

    def rows(self, batch: AnnotatedBatch, *, reserved: int = 0, end: bytes = b"",
             fields: FrameFields | None = None) -> Rows:
        """The kept messages' frame records, each followed by ``end`` (and preceded by
        ``reserved`` bytes, see :func:`~sniffer.encoding.rows.join_rows`). ``fields``: the
        batch's :func:`frame_fields`, where they were made already (in the decoding process)."""
        if not self._exact:
            return self.block_rows(batch, reserved, end)
        messages, frames = batch.messages, batch.messages.frames
        positions = batch.positions()
        kept = np.array(positions, np.int64)
        own = fields if fields is not None else frame_fields(messages)
        if len(positions) != len(messages):
            own = own.take(kept)
        rest = batch.decoded_positions()  # those decoded one by one (the rest: spelt from columns)
        decodings = batch.decoded_at(rest)
        if own.identities is not None:  # mostly distinct frames: their own columns say who they are
            tails = self._tails_alone_of(batch, rest, decodings)
            middle: list[Column] = [own.identities, b',"flags":', own.middles, tails]
        else:
            facts = _FrameFacts(messages)
            found = self._parts.get_all(decodings, lambda row: self._frame_parts(facts, rest[row], decodings[row]))
            identities = in_columns_too(batch, lambda parts: parts.each(identities_at(messages, parts.spelt.positions)),
                                        [parts[0] for parts in found])
            tails = in_columns_too(batch, lambda parts: parts.record_tails(), [parts[1] for parts in found])
            middle = [identities, b',"flags":', own.middles, tails]
        columns: list[Column] = [
            own.heads, *middle, *channel_column(frames, kept, self.channels), *uart_error_column(frames, kept),
            b"}" + end,
        ]  # fmt: skip
        return join_rows(columns, len(positions), reserved)

    def block_rows(self, batch: AnnotatedBatch, reserved: int, end: bytes = b"",
                   fields: BlockFields | None = None) -> Rows:
        """Not exact: what a frame's own columns say (index, times, flags, pairing, latency)
        first, laid out as one :class:`~sniffer.encoding.blocks.Block`, then the decoding's part
        in one piece. ``fields``: the batch's :func:`block_fields`, where they were made already
        (in the decoding process)."""
        messages, frames = batch.messages, batch.messages.frames
        positions = batch.positions()
        kept = np.array(positions, np.int64)
        rest = batch.decoded_positions()  # those decoded one by one (the rest: spelt from columns)
        decodings = batch.decoded_at(rest)
        if fields is not None and len(positions) != len(messages):
            fields = fields.take(kept)
        heads: Column = block_heads(messages, kept) if fields is None else fields.heads
        if fields is not None and fields.identities is not None:  # mostly distinct frames
            middle: list[Column] = [fields.identities, b",", self._tails_alone_of(batch, rest, decodings)]
        else:
            facts = _FrameFacts(batch.messages)
            middle = [in_columns_too(batch, lambda parts: _joined_parts(messages, parts), self._tails.get_all(
                decodings, lambda row: b",".join(self._frame_parts(facts, rest[row], decodings[row]))))]
        optional = [*channel_column(frames, kept, self.channels), *uart_error_column(frames, kept)]
        return join_rows([heads, *middle, *optional, b"}" + end], len(positions), reserved)

    def _tails_alone_of(self, batch: AnnotatedBatch, rest: list[int], decodings: list[Decoding]) -> list[bytes]:
        """Each written message's :meth:`_decoding_part` (``rest``: the positions of
        ``decodings``; frames left in columns: spelt from them)."""
        protocols = _Protocols(batch.messages.frames)
        return in_columns_too(batch, lambda parts: parts.record_tails(), self._tails_alone.get_all(
            decodings, lambda row: self._decoding_part(decodings[row], protocols(rest[row]))))

    def encode_batch(self, batch: AnnotatedBatch) -> list[str]:
        """The records as text, one per kept message."""
        rows = self.rows(batch)
        return [rows.row(index).decode() for index in range(len(rows))]

    def _frame_parts(self, facts: _FrameFacts, position: int, decoding: Decoding) -> tuple[bytes, bytes]:
        """A record's parts that a frame's bytes, role and decoding determine (the annotator
        shares a decoding only between frames with the same bytes, role and protocol): from
        ``hex`` to ``exception_code``, and :meth:`_decoding_part`."""
        data, crc_ok, slave, function, role, code, protocol = facts(position)
        return (
            f'"hex":"{data.hex()}","crc_ok":{"true" if crc_ok else "false"},'
            f'"slave":{"null" if slave == NONE else slave},"function":{"null" if function == NONE else function},'
            f'"role":"{ROLE_NAMES[role]}","exception_code":{"null" if code == NONE else code}'.encode(),
            self._decoding_part(decoding, protocol),
        )

    def _decoding_part(self, decoding: Decoding, protocol: int) -> bytes:
        """A record's part from ``params`` to the end of ``remarks``."""
        texts, entry = PARAM_JSON.kept, PARAM_JSON.entry
        params = b",".join([(texts.get(id(p)) or entry(p))[1] for p in decoding.params])
        tail = [b'"params":[', params, b'],"summary":', encode_json(decoding.summary)]
        remarks = encode_json(list(decoding.remarks)) if decoding.remarks else b"[]"
        tail += (b',"protocol":', _PROTOCOL_JSON[protocol], b',"remarks":', remarks)
        return b"".join(tail)


def _joined_parts(messages: MessageBatch, parts: ColumnarParts) -> list[bytes]:
    """The records of frames in columns from ``hex`` to the end of ``remarks``: spelt once per
    group of frames alike (the same bytes and role, so the same identity too)."""
    identities = identities_at(messages, parts.spelt.positions)
    return parts.each([b",".join((identity, tail))
                       for identity, tail in zip(identities, parts.spelt_record_tails(), strict=True)])


class _Protocols:
    """The protocol of a frame by position, the column read into a list when first asked."""

    def __init__(self, frames: FrameBatch) -> None:
        self._frames = frames
        self._list: list[int] | None = None

    def __call__(self, position: int) -> int:
        if self._list is None:
            self._list = self._frames.protocols().tolist()
        return self._list[position]


class _FrameFacts:
    """What a frame record takes from a batch's columns besides its times, by position: the
    columns are read into lists at the first frame whose decoding is new (none, for a batch
    of repeats)."""

    def __init__(self, batch: MessageBatch) -> None:
        self._batch = batch
        self._lists: tuple[list[Any], ...] | None = None

    def __call__(self, position: int) -> tuple[bytes, bool, int, int, int, int, int]:
        if self._lists is None:
            batch, frames = self._batch, self._batch.frames
            self._lists = tuple(column.tolist() for column in (
                frames.offsets, frames.crc_ok, batch.slave, batch.function, batch.role, batch.exception_code,
                frames.protocols()))
        offsets, crc_ok, slave, function, role, code, protocol = self._lists
        data = self._batch.frames.data[offsets[position] : offsets[position + 1]]
        return data, crc_ok[position], slave[position], function[position], role[position], code[position], \
            protocol[position]


def device_record(index: int, device: DeviceIdentity) -> dict[str, Any]:
    """A slave said what it is (FC 43): the ``device`` record that follows its frame ``index``."""
    return {
        "kind": "device",
        "index": index,
        "slave": device.slave,
        "vendor": device.vendor,
        "product_code": device.product_code,
        "revision": device.revision,
        "profile": device.profile,
        "applied": device.applied,
    }

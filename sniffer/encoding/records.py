"""JSONL records exactly as docs/jsonl-output.md defines them."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from decoders.capture import CaptureInfo, uart_error_name
from decoders.decoded_batch import AnnotatedBatch
from decoders.frame import FrameBatch, FrameFlag
from decoders.line import LineSettings
from decoders.message import DeviceIdentity, MessageBatch
from sniffer.encoding.decoded_texts import FrameTexts, each_message
from sniffer.encoding.frame_fields import (
    NS_PER_S,
    BlockFields,
    FrameFields,
    block_heads,
    frame_fields,
    identities_at,
)
from sniffer.encoding.param_text import encode_json
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


class FrameRecordEncoder:
    """Frame records as JSON, exactly ``encode_record(frame_record(m))`` (``tests/oracles.py``), a batch at a time.

    Every frame passes through here. What a decoding determines (params, summary, protocol,
    remarks) is spelt once per decoding or group of frames alike
    (:mod:`sniffer.encoding.decoded_texts`), a profiled param's JSON once per param
    (:data:`~sniffer.encoding.param_text.PARAM_JSON`); the frame's own fields (times, bytes,
    slave, role, flags, pairing) are columns of the batch (:func:`frame_fields`), each
    formatted at once (numbers by one ``repr``, which is how ``json.dumps`` writes them; hex by
    numpy), and the columns are joined into records by :func:`~sniffer.encoding.rows.join_rows`.
    """

    def __init__(self, *, exact: bool = True) -> None:
        """``exact``: spelt as ``json.dumps`` spells it (JSONL); otherwise the times
        (``t``, ``t_end``, ``latency_s``) are the exact decimals of their nanoseconds and the
        frame's own fields come first, padded to one width (:meth:`block_rows`), several
        times faster."""
        self._exact = exact
        #: The capture's line names (:attr:`CaptureInfo.channels`), for the ``channel`` field.
        self.channels: tuple[str, ...] = ()

    def rows(self, batch: AnnotatedBatch, *, reserved: int = 0, end: bytes = b"",
             fields: FrameFields | None = None) -> Rows:
        """The kept messages' frame records, each followed by ``end`` (and preceded by
        ``reserved`` bytes, see :func:`~sniffer.encoding.rows.join_rows`). ``fields``: the
        batch's :func:`frame_fields`, where they were made already (in the decoding process)."""
        if not self._exact:
            return self.block_rows(batch, reserved, end)
        messages = batch.messages
        positions = batch.positions()
        kept = np.array(positions, np.int64)
        own = fields if fields is not None else frame_fields(messages)
        if len(positions) != len(messages):
            own = own.take(kept)
        # Mostly distinct frames: their own columns say who they are.
        identities = own.identities if own.identities is not None else each_message(
            batch, lambda parts: parts.each(identities_at(messages, parts.spelt_positions)))
        columns: list[Column] = [
            own.heads, identities, b',"flags":', own.middles, each_message(batch, FrameTexts.record_tails),
            *self._optional(batch, kept), b"}" + end,
        ]  # fmt: skip
        return join_rows(columns, len(positions), reserved)

    def block_rows(self, batch: AnnotatedBatch, reserved: int, end: bytes = b"",
                   fields: BlockFields | None = None) -> Rows:
        """Not exact: what a frame's own columns say (index, times, flags, pairing, latency)
        first, laid out as one :class:`~sniffer.encoding.blocks.Block`, then the decoding's part
        in one piece. ``fields``: the batch's :func:`block_fields`, where they were made already
        (in the decoding process)."""
        messages = batch.messages
        positions = batch.positions()
        kept = np.array(positions, np.int64)
        if fields is not None and len(positions) != len(messages):
            fields = fields.take(kept)
        heads: Column = block_heads(messages, kept) if fields is None else fields.heads
        if fields is not None and fields.identities is not None:  # mostly distinct frames
            middle: list[Column] = [fields.identities, b",", each_message(batch, FrameTexts.record_tails)]
        else:
            middle = [each_message(batch, lambda parts: _joined_parts(messages, parts))]
        return join_rows([heads, *middle, *self._optional(batch, kept), b"}" + end], len(positions), reserved)

    def _optional(self, batch: AnnotatedBatch, kept: npt.NDArray[np.int64]) -> list[Column]:
        """The ``channel`` and ``uart_errors`` members, where the capture has them."""
        frames = batch.messages.frames
        return [*channel_column(frames, kept, self.channels), *uart_error_column(frames, kept)]


def _joined_parts(messages: MessageBatch, parts: FrameTexts) -> list[bytes]:
    """The records of ``parts``' frames from ``hex`` to the end of ``remarks``: spelt once per
    group of frames alike (the same bytes and role, so the same identity too)."""
    identities = identities_at(messages, parts.spelt_positions)
    return parts.each([b",".join((identity, tail))
                       for identity, tail in zip(identities, parts.spelt_record_tails(), strict=True)])


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

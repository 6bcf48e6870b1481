"""Plain reference implementations the tests hold the product's faster ones to.

Each is the rule written the obvious way; the product keeps one implementation of each thing
(the fast one), and these live here only as oracles.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import numpy.typing as npt
from fastcrc import crc16

from decoders.crc import CRC_TABLE, MIN_CHECKED
from decoders.frame import PROTOCOL_NAMES
from decoders.message import ROLE_NAMES, Decoding, Message, Role
from decoders.modbus.annotate import Annotator, answer_context
from decoders.modbus.codes import REGISTERS
from decoders.modbus.columnar import KEPT_REQUESTS
from decoders.profiles.apply import FrameFacts, ProfileApplier
from decoders.profiles.model import Profile
from decoders.profiles.naming import AddressNamer
from sniffer.encoding.frame_fields import NS_PER_S
from sniffer.encoding.param_text import PARAM_JSON, encode_json, param_record
from sniffer.encoding.records import channel_name, uart_error_records


def crc16_modbus_reference(data: bytes) -> int:
    """Table-driven pure-Python CRC-16/MODBUS; slow, obviously correct."""
    crc = 0xFFFF
    for byte in data:
        crc = (crc >> 8) ^ CRC_TABLE[(crc ^ byte) & 0xFF]
    return crc


def crc_ok_many_reference(data: bytes, offsets: npt.NDArray[np.int64]) -> npt.NDArray[np.bool_]:
    """:func:`decoders.crc.crc_ok_many` by one ``fastcrc`` call a frame: the plain path."""
    bounds = offsets.tolist()
    frames = map(data.__getitem__, map(slice, bounds[:-1], bounds[1:]))
    remainders = np.fromiter(map(crc16.modbus, frames), np.int64, len(bounds) - 1)
    valid: npt.NDArray[np.bool_] = (remainders == 0) & (np.diff(offsets) >= MIN_CHECKED)
    return valid


class AnewApplier(ProfileApplier):
    """:class:`ProfileApplier` naming every value anew: no namer, and so no named value, kept
    between frames."""

    def _kept_namers(self, profile: Profile, reported: bool,
                     table: int = REGISTERS) -> dict[int | tuple[int | None, int], AddressNamer]:
        return {}


def record_tail(decoding: Decoding, protocol: int) -> bytes:
    """A frame record's part from ``params`` to the end of ``remarks``, spelt from its decoding
    (the oracle of :meth:`sniffer.encoding.decoded_texts.FrameTexts.record_tails`)."""
    params = b",".join(PARAM_JSON.entry(param)[1] for param in decoding.params)
    remarks = encode_json(list(decoding.remarks)) if decoding.remarks else b"[]"
    return b"".join((b'"params":[', params, b'],"summary":', encode_json(decoding.summary), b',"protocol":"',
                     PROTOCOL_NAMES[protocol].encode(), b'","remarks":', remarks))


def log_parts(decoding: Decoding, role: int) -> tuple[bytes, bytes]:
    """A frame's MCAP log text after its index, and its ``/slave/N/params`` members (``b""``: no
    values), spelt from its decoding (the oracle of ``FrameTexts.log_heads`` and ``numeric_members``)."""
    values: dict[str, float | int] = {}
    for param in decoding.params:
        if param.raw is not None and param.available:
            key = param.code if param.code is not None else str(param.address)
            values[key] = param.value if isinstance(param.value, int | float) else param.raw
    return f" {ROLE_NAMES[role]}: {decoding.summary}".encode(), encode_json(values)[1:] if values else b""


def frame_record(message: Message, channels: tuple[str, ...] = ()) -> dict[str, Any]:
    """One frame record as the JSONL view writes it, spelt field by field from a message (the
    oracle of :class:`sniffer.encoding.records.FrameRecordEncoder`); ``channels``: the
    capture's line names (:attr:`CaptureInfo.channels`), for ``channel``."""
    frame = message.frame
    return {
        "kind": "frame",
        "index": frame.index,
        "t": frame.t_start_ns / NS_PER_S,
        "t_end": frame.t_end_ns / NS_PER_S,
        "t_ns": frame.t_start_ns,
        "t_end_ns": frame.t_end_ns,
        "hex": frame.data.hex(),
        "crc_ok": frame.crc_ok,
        "slave": message.slave,
        "function": message.function,
        "role": message.role.value,
        "exception_code": message.exception_code,
        "flags": message.flags.names,
        "request_index": message.request_index,
        "latency_s": None if message.latency_ns is None else message.latency_ns / NS_PER_S,
        "params": [param_record(p) for p in message.params],
        "summary": message.summary,
        "protocol": PROTOCOL_NAMES[frame.protocol],
        "remarks": list(message.remarks),
        **({"channel": channel_name(channels, frame.channel)} if frame.channel else {}),
        **({"uart_errors": uart_error_records(frame.uart_errors)} if frame.uart_errors else {}),
    }


class PlainAnnotator(Annotator):
    """:class:`Annotator` decoding one message at a time, with no memo and nothing in columns:
    the plain path the annotator's batches are held to."""

    def annotate(self, message: Message) -> Message:
        """``message`` decoded against the request it answers, if that is still kept."""
        request = None
        if message.request_index is not None:
            kept = self._requests.pop(message.request_index, None)
            if kept is not None and message.frame.index - message.request_index <= KEPT_REQUESTS:
                request = kept[1]
        frame = message.frame
        facts = FrameFacts(message.slave, message.role, message.function, frame.crc_ok)
        annotated = replace(message, decoding=self._decoding(frame.data, frame.protocol, facts, request))
        if annotated.role is Role.REQUEST and annotated.pdu is not None:
            self._requests[frame.index] = (answer_context(annotated.pdu), annotated.pdu)
            self._forget(frame.index + 1)
        return annotated

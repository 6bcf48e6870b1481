"""The commonest frames decoded a batch at a time: register reads (FC 3 and 4), request and answer.

A polling master reads registers and its slaves answer with values that change: each such frame
is new to the annotator's cache, and decoding it alone (:func:`decoders.modbus.pdu_parse.parse_pdu`,
its summary) is most of its cost. Here the reads and answers of a batch that carry a good CRC and
a shape Modbus allows are found with numpy and decoded into the same PDUs and summaries, with
little Python per frame, for every slave (a profile then names what they carry); the tests hold
them to ``parse_pdu`` and the PDUs' own summaries (the plain path).
"""

from __future__ import annotations

import struct

import numpy as np
import numpy.typing as npt

from decoders.message import ROLE_CODE, MessageBatch, Role
from decoders.modbus.codes import MAX_QUANTITY, TABLE_NAMES
from decoders.modbus.pdu import Pdu, ReadRequest, RegistersResponse
from decoders.modbus.pdu_text import hex_payload

_REQUEST, _RESPONSE = ROLE_CODE[Role.REQUEST], ROLE_CODE[Role.RESPONSE]
READ_REQUEST_BYTES = 8


#: Summary, PDU and answer context (:func:`decoders.modbus.annotate.answer_context`) of a frame.
QuickRead = tuple[str, Pdu, tuple[object, ...]]
_ANSWER_CONTEXT = (RegistersResponse, None)


def register_reads(batch: MessageBatch, eligible: npt.NDArray[np.bool_]) -> dict[int, QuickRead]:
    """Summary, PDU and answer context of each FC 3/4 read request and register answer of
    ``batch`` at an ``eligible`` position, by position."""
    frames = batch.frames
    starts, lengths = frames.offsets[:-1], np.diff(frames.offsets)
    raw = np.frombuffer(frames.data, np.uint8)
    function = batch.function
    reads = eligible & frames.crc_ok & ((function == 3) | (function == 4))
    requests = np.flatnonzero(reads & (batch.role == _REQUEST) & (lengths == READ_REQUEST_BYTES))
    answers = np.flatnonzero(reads & (batch.role == _RESPONSE) & (lengths >= 7))
    decoded: dict[int, QuickRead] = {}
    if len(requests):
        at = starts[requests]
        address = (raw[at + 2].astype(np.int64) << 8) | raw[at + 3]
        count = (raw[at + 4].astype(np.int64) << 8) | raw[at + 5]
        fine = (count >= 1) & (count <= MAX_QUANTITY[3])
        for position, code, first, number in zip(requests[fine].tolist(), function[requests][fine].tolist(),
                                                 address[fine].tolist(), count[fine].tolist(), strict=True):
            span = f"{first}" if number == 1 else f"{first}..{first + number - 1}"
            decoded[position] = (f"read {TABLE_NAMES[code]} {span} ({number})", ReadRequest(code, first, number),
                                 (ReadRequest, code, first, number))
    if len(answers):
        byte_count = raw[starts[answers] + 2].astype(np.int64)
        fine = (byte_count == lengths[answers] - 5) & (byte_count % 2 == 0) & (byte_count > 0)
        data = frames.data
        for position, code, start, size in zip(answers[fine].tolist(), function[answers][fine].tolist(),
                                               starts[answers][fine].tolist(), byte_count[fine].tolist(),
                                               strict=True):
            payload = data[start + 3 : start + 3 + size]
            words = size // 2
            values = struct.unpack(f">{words}H", payload)
            decoded[position] = (f"{TABLE_NAMES[code]} = {hex_payload(payload)} ({words} registers)",
                                 RegistersResponse(code, size, values), _ANSWER_CONTEXT)
    return decoded

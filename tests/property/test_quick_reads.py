"""Hypothesis: register reads decoded a batch at a time say what parse_pdu and the PDUs'
summaries say, frame by frame (the plain path)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.crc import crc_bytes, crc_ok
from decoders.frame import Frame, FrameFlag, frames_to_batch
from decoders.message import NONE, ROLE_CODE, MessageBatch, Role
from decoders.modbus.annotate import answer_context
from decoders.modbus.pdu_parse import parse_pdu
from decoders.modbus.quick import register_reads


@st.composite
def read_frames(draw: st.DrawFn) -> tuple[bytes, Role]:
    function = draw(st.sampled_from([3, 4, 3, 6]))
    if draw(st.booleans()):
        body = bytes([draw(st.integers(0, 247)), function]) + draw(st.binary(min_size=3, max_size=5))
        role = Role.REQUEST
    else:
        count = draw(st.integers(0, 40))
        payload = draw(st.binary(min_size=max(count - 2, 0), max_size=count + 2))
        body = bytes([draw(st.integers(0, 247)), function, count]) + payload
        role = Role.RESPONSE
    damaged = draw(st.integers(0, 9)) == 0
    return body + (b"\x00\x00" if damaged else crc_bytes(body)), role


@settings(max_examples=500, deadline=None)
@given(st.lists(read_frames(), min_size=1, max_size=30))
def test_quick_reads_are_parse_pdu(frames: list[tuple[bytes, Role]]) -> None:
    batch = frames_to_batch([Frame(i, i * 10, i * 10 + 5, data, crc_ok(data), FrameFlag.NONE)
                             for i, (data, _) in enumerate(frames)])
    count = len(frames)
    messages = MessageBatch(batch, np.array([ROLE_CODE[role] for _, role in frames], np.uint8),
                            np.array([data[0] for data, _ in frames], np.int16),
                            np.array([data[1] for data, _ in frames], np.int16), np.full(count, NONE, np.int16),
                            np.zeros(count, np.uint16), np.full(count, NONE, np.int64), np.full(count, NONE, np.int64))
    decoded = register_reads(messages, np.ones(count, np.bool_))
    for position, (summary, pdu, context) in decoded.items():
        data, role = frames[position]
        assert crc_ok(data)
        expected = parse_pdu(data, is_request=role is Role.REQUEST)
        assert pdu == expected and summary == expected.summary() and context == answer_context(expected)
    # What is left out is what the quick path does not cover, never a frame it could have read.
    for position, (data, role) in enumerate(frames):
        if position not in decoded and crc_ok(data) and data[1] in (3, 4):
            if role is Role.REQUEST and len(data) == 8:
                assert not 1 <= int.from_bytes(data[4:6], "big") <= 125
            elif role is Role.RESPONSE:
                assert data[2] != len(data) - 5 or data[2] % 2 or data[2] == 0

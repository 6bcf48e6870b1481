"""Hypothesis: decoding never raises on arbitrary bus data."""

from __future__ import annotations

import os

from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.crc import crc_bytes, crc_ok
from decoders.frame import Frame, FrameFlag, frames_to_batch
from decoders.modbus.codecs import parse_pdu
from decoders.modbus.matcher import Matcher
from tests.oracles import PlainAnnotator

#: RTUSNIFF_EXAMPLES raises the number of examples for a long run.
EXAMPLES = int(os.environ.get("RTUSNIFF_EXAMPLES", "0"))
FUNCTIONS = st.sampled_from([*range(1, 25), 43, 65, 100, 0x83, 0x90, 0xAB, 0, 127, 255])


@st.composite
def adus(draw: st.DrawFn) -> bytes:
    body = bytes([draw(st.integers(0, 255)), draw(FUNCTIONS)]) + draw(st.binary(max_size=60))
    return body + crc_bytes(body) if draw(st.booleans()) else body


@settings(max_examples=max(2000, EXAMPLES), deadline=None)
@given(adus(), st.booleans())
def test_parse_pdu_never_raises(adu: bytes, is_request: bool) -> None:
    pdu = parse_pdu(adu, is_request=is_request)
    assert isinstance(pdu.summary(), str)


@settings(max_examples=max(300, EXAMPLES), deadline=None)
@given(st.lists(st.tuples(adus(), st.integers(0, 200_000_000), st.booleans()), max_size=40))
def test_matcher_and_annotator_never_raise(items: list[tuple[bytes, int, bool]]) -> None:
    matcher, annotator, t = Matcher(), PlainAnnotator(), 0
    frames = []
    for index, (data, gap, noise) in enumerate(items):
        t += gap
        frames.append(Frame(index, t, t + 1000 * len(data), data, crc_ok(data) and not noise, FrameFlag.NONE, noise))
    messages = list(matcher.feed(frames_to_batch(frames))) + list(matcher.flush()) if frames else []
    assert [m.frame.index for m in messages] == list(range(len(frames)))
    for message in messages:
        annotated = annotator.annotate(message)
        assert isinstance(annotated.summary, str) and annotated.summary
        if annotated.request_index is not None:
            assert annotated.request_index < annotated.frame.index

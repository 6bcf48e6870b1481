"""Hypothesis: what :mod:`sniffer.encoding.decoded_texts` spells from the decoded form, of frames
left in columns and of frames decoded one by one, is, byte for byte, what the oracles write from
each frame's decoding: the JSONL record's part from ``params`` on, the MCAP log text and the
``/slave/N/params`` members; and a frame's identity (``hex`` to ``exception_code``) spelt for some
frames is what it is for all."""

from __future__ import annotations

import os
from itertools import pairwise
from unittest.mock import patch

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from decoders.decoded_batch import InColumns, OneByOne
from decoders.message import Decoding, MessageBatch, slice_messages
from decoders.modbus import alike as alike_module
from decoders.modbus.annotate import Annotator
from sniffer.encoding import decoded_texts
from sniffer.encoding.decoded_texts import FrameTexts
from sniffer.encoding.frame_fields import _identities, identities_at
from tests.oracles import log_parts, record_tail
from tests.property.test_annotation_cache import adu, matched
from tests.property.test_columnar import annotator, exchanges

#: RTUSNIFF_EXAMPLES raises the number of examples for a long run.
EXAMPLES = int(os.environ.get("RTUSNIFF_EXAMPLES", "0"))


def check_parts(columns: Annotator, plain: Annotator, batch: MessageBatch) -> int:
    """One batch through both annotators; how many frames were spelt from columns. The parts
    spelt frame by frame, and with alike frames spelt once (however few are alike); the parts of
    every frame decoded one by one (:class:`DecodedParts`), spelt once per decoding."""
    annotated = plain.annotate_batch(batch)
    expected = annotated.decodings
    check_texts(FrameTexts(OneByOne(annotated)), expected, batch)
    columnar = columns.annotate_columnar(batch).columnar
    if columnar is None:
        return 0
    with patch.object(alike_module, "DISTINCT_SHARE", 2.0):
        each_once = InColumns(columnar, batch)
    for decoded in (InColumns(columnar, data=batch.frames.data), each_once):
        check_texts(FrameTexts(decoded), expected, batch)
    positions = columnar.positions.tolist()
    assert list(identities_at(batch, columnar.positions)) == [_identities(batch)[p] for p in positions]
    return len(positions)


def check_texts(parts: FrameTexts, expected: list[Decoding], batch: MessageBatch) -> None:
    """Every text of ``parts`` is what the oracles spell from the frames' decodings."""
    positions = parts.positions.tolist()
    protocols = batch.frames.protocols()
    logged = [log_parts(expected[p], int(batch.role[p])) for p in positions]
    tails = parts.record_tails()
    assert list(tails) == [record_tail(expected[p], int(protocols[p])) for p in positions]
    assert tails.sizes.tolist() == list(map(len, tails))
    assert parts.log_heads(batch.role) == [head for head, _ in logged]
    members = parts.numeric_members()
    assert list(members) == [values for _, values in logged]
    assert members.sizes.tolist() == [len(values) for _, values in logged]
    assert parts.decoded.summaries() == [expected[p].summary for p in positions]


@settings(max_examples=max(80, EXAMPLES), deadline=None)
@given(st.lists(exchanges(), max_size=50), st.lists(st.integers(0, 120), max_size=4),
       st.sampled_from([decoded_texts.SLICE_PARAMS, 1, 7, 64]),
       st.sampled_from([None, [], ["atv71"], ["2=atv312", "7=xbt"]]))
@example([[adu(b"\x07", b"\x03", (65535).to_bytes(2, "big") + (3).to_bytes(2, "big")),
           adu(b"\x07", b"\x03\x06", bytes(range(6)))]], [], 2, None)
def test_parts_spelt_from_columns_are_what_decodings_write(traffic: list[list[bytes]], cuts: list[int],
                                                           slice_params: int, profiles: list[str] | None) -> None:
    """Batches cut anywhere, so that an answer's request may be in the batch before; the params
    spelt in slices of any size; slaves a profile names (:mod:`decoders.profiles.columns`) or not."""
    columns, plain = annotator(profiles), annotator(profiles)
    with patch.object(decoded_texts, "SLICE_PARAMS", slice_params):
        for batch in matched([data for exchange in traffic for data in exchange]):
            bounds = [0, *sorted(cut for cut in set(cuts) if 0 < cut < len(batch)), len(batch)]
            for start, stop in pairwise(bounds):
                check_parts(columns, plain, slice_messages(batch, start, stop))


def test_polling_and_coils_are_spelt_from_columns() -> None:
    """Not vacuous: reads of registers and coils and writes, answered, all spelt from columns;
    a register past 16 bits of address (none is on a wire) is named as the plain path names it."""
    reads = [
        adu(b"\x02", b"\x03\x00\x64\x00\x03"), adu(b"\x02", b"\x03\x06", bytes([0, 1, 0xFF, 0xFF, 0x12, 0x34])),
        adu(b"\x02", b"\x01\x00\x00\x00\x0a"), adu(b"\x02", b"\x01\x02\xa5\x03"),
        adu(b"\x02", b"\x10\x00\x10\x00\x02\x04\x00\x07\x00\x08"), adu(b"\x02", b"\x10\x00\x10\x00\x02"),
        adu(b"\x02", b"\x06\x00\x05\x01\x02"), adu(b"\x02", b"\x06\x00\x05\x01\x02"),
        adu(b"\x02", b"\x03\xff\xfe\x00\x03"), adu(b"\x02", b"\x03\x06", bytes(6)),
    ]
    columns, plain = Annotator(), Annotator()
    spelt = sum(check_parts(columns, plain, batch) for batch in matched(reads * 20))
    assert spelt >= 180
    batch = next(iter(matched(reads)))
    columnar = Annotator().annotate_columnar(batch).columnar
    assert columnar is not None
    members = FrameTexts(InColumns(columnar, data=batch.frames.data)).numeric_members()
    assert bytes(members[1]) == b'"100":1,"101":65535,"102":4660}' and bytes(members[0]) == b""
    assert np.array_equal(members.sizes, [len(member) for member in members])


def test_answers_alike_in_bytes_to_other_requests_are_told_apart() -> None:
    """Two reads answered with the same bytes: the answers name different registers, so they are
    not alike; each read and answer polled again is (``alike``), and mostly distinct frames are
    left to be spelt each (``None``)."""
    polled = [adu(b"\x05", b"\x03\x00\x64\x00\x02"), adu(b"\x05", b"\x03\x04\x00\x01\x00\x02"),
              adu(b"\x05", b"\x03\x00\xc8\x00\x02"), adu(b"\x05", b"\x03\x04\x00\x01\x00\x02")]
    batch = next(iter(matched(polled * 10)))
    columnar = Annotator().annotate_columnar(batch).columnar
    assert columnar is not None and len(columnar) == 40
    found = alike_module.alike(columnar, batch.frames.data, batch.frames.offsets, batch.role)
    assert found is not None
    assert len(found.firsts) == 4 and found.inverse.tolist() == [0, 1, 2, 3] * 10
    check_parts(Annotator(), Annotator(), batch)
    distinct = next(iter(matched([adu(b"\x05", b"\x03" + address.to_bytes(2, "big") + b"\x00\x01")
                                  for address in range(50)])))
    columnar = Annotator().annotate_columnar(distinct).columnar
    assert columnar is not None
    assert alike_module.alike(columnar, distinct.frames.data, distinct.frames.offsets, distinct.role) is None


def test_answers_whose_crc_agrees_are_compared_byte_for_byte() -> None:
    """Two answers of one slave, length and CRC but other values (a CRC collision, as a bus
    polled for a day has): grouped together at first sight, told apart by their bytes."""
    seen: dict[bytes, bytes] = {}
    for value in range(1 << 16):
        answer = adu(b"\x09", b"\x03\x04", (value * 2654435761 & 0xFFFFFFFF).to_bytes(4, "big"))
        if answer[-2:] in seen:
            break
        seen[answer[-2:]] = answer
    other = seen[answer[-2:]]
    assert other != answer
    request = adu(b"\x09", b"\x03\x00\x10\x00\x02")
    batch = next(iter(matched([request, answer, request, other] * 5)))
    columnar = Annotator().annotate_columnar(batch).columnar
    assert columnar is not None and len(columnar) == 20
    found = alike_module.alike(columnar, batch.frames.data, batch.frames.offsets, batch.role)
    assert found is not None
    assert len(found.firsts) == 3 and found.inverse.tolist() == [0, 1, 0, 2] * 5
    answers = next(iter(matched([request, answer, request, other, request, other, request, answer] * 3)))
    columnar = Annotator().annotate_columnar(answers).columnar
    assert columnar is not None
    found = alike_module.alike(columnar, answers.frames.data, answers.frames.offsets, answers.role)
    assert found is not None and found.inverse.tolist() == [0, 1, 0, 2, 0, 2, 0, 1] * 3
    check_parts(Annotator(), Annotator(), batch)

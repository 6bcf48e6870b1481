"""Hypothesis: the shortcuts of the hot path say exactly what the plain path says.

The annotator hands repeats a cached decoding and the profiles remember named params;
the JSONL view writes frame records from pieces. Each is checked against the path it
shortcuts, on traffic that repeats itself, teaches the profiles (scanner set-up,
identification) and answers the same addresses with different values.
"""

from __future__ import annotations

import json
import os
import struct
import tracemalloc
from dataclasses import astuple
from decimal import Decimal
from itertools import pairwise
from unittest.mock import patch

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.crc import crc_bytes, crc_ok
from decoders.decoded_batch import AnnotatedBatch
from decoders.frame import Frame, FrameFlag, flag_set, frames_to_batch
from decoders.message import Decoding, MessageBatch, ParamValue
from decoders.modbus.annotate import Annotator
from decoders.modbus.matcher import Matcher
from decoders.profiles import apply as apply_module
from decoders.profiles.apply import ProfileApplier
from sniffer.encoding import frame_fields as frame_fields_module
from sniffer.encoding import param_text
from sniffer.encoding.param_text import encode_record
from sniffer.encoding.records import FrameRecordEncoder
from sniffer.profiles_io import profile_book
from tests.oracles import AnewApplier, PlainAnnotator, frame_record

EXAMPLES = int(os.environ.get("RTUSNIFF_EXAMPLES", "0"))
SLAVES = st.sampled_from([1, 2, 7])
#: ETA, RFRD, the scanner's address and value registers, HSP, an unknown register.
ADDRESSES = st.sampled_from([3201, 8604, 12701, 12702, 12741, 12742, 12761, 3104, 5])
VALUES = st.sampled_from([0, 1, 0x8000, 0x8637, 3201, 8604, 8501, 1500, 0xFFFF])
PRODUCT = b"\x00\x0dTelemecanique\x01\x0bATV71HU15M3\x02\x040201"


def adu(*parts: bytes) -> bytes:
    body = b"".join(parts)
    return body + crc_bytes(body)


@st.composite
def exchanges(draw: st.DrawFn) -> list[bytes]:
    """A request and (mostly) its answer, from a small pool so that frames repeat."""
    s = bytes([draw(SLAVES)])
    address, count = draw(ADDRESSES), draw(st.one_of(st.integers(1, 3), st.just(14)))
    values = [draw(VALUES) for _ in range(count)]
    match draw(st.integers(0, 6)):
        case 0:
            request = adu(s, b"\x03", struct.pack(">HH", address, count))
            answer = adu(s, b"\x03", bytes([2 * count]), struct.pack(f">{count}H", *values))
        case 1:
            written = struct.pack(f">{count}H", *values)
            request = adu(s, b"\x10", struct.pack(">HHB", address, count, 2 * count), written)
            answer = adu(s, b"\x10", struct.pack(">HH", address, count))
        case 2:
            request = answer = adu(s, b"\x06", struct.pack(">HH", address, values[0]))
        case 3:
            request = adu(s, b"\x03", struct.pack(">HH", address, count))
            answer = adu(s, b"\x83", bytes([draw(st.sampled_from([2, 4]))]))
        case 4:
            request, answer = adu(s, b"\x2b\x0e\x01\x00"), adu(s, b"\x2b\x0e\x01\x02\x00\x00\x03", PRODUCT)
        case 5:  # FC 23: writes ``values`` at ``address``, reads the registers after them
            written = struct.pack(f">{count}H", *values)
            request = adu(s, b"\x17", struct.pack(">HHHHB", address + count, count, address, count, 2 * count), written)
            answer = adu(s, b"\x17", bytes([2 * count]), written[::-1])
        case _:
            request, answer = adu(s, b"\x10", struct.pack(">HHB", address, 1, 2), b"\x00"), b""
    if draw(st.booleans()) and len(answer) > 3:
        damaged = bytearray(answer)
        damaged[draw(st.integers(2, len(answer) - 1))] ^= 1
        answer = bytes(damaged)
    return [request, answer] if answer else [request]


def matched(adus: list[bytes], cuts: tuple[int, ...] = (), noise: frozenset[int] = frozenset()) -> list[MessageBatch]:
    """The frames paired by the matcher, fed to it in pieces ending at ``cuts``; those at
    ``noise`` framed as noise."""
    frames, t = [], 0
    for index, data in enumerate(adus):
        t += 5_000_000
        frames.append(Frame(index, t, t + 1000 * len(data), data, crc_ok(data), FrameFlag.NONE, index in noise))
    if not frames:
        return []
    matcher = Matcher()
    bounds = [0, *sorted(cut for cut in set(cuts) if 0 < cut < len(frames)), len(frames)]
    pieces = [frames[start:end] for start, end in pairwise(bounds)]
    return [matcher.feed(frames_to_batch(piece)) for piece in pieces] + [matcher.flush()]



def encoded(encoder: FrameRecordEncoder, batch: AnnotatedBatch) -> list[str]:
    """The JSONL records of the batch's kept messages, as text."""
    rows = encoder.rows(batch)
    return [rows.row(index).decode() for index in range(len(rows))]

def said(decoding: Decoding) -> tuple[object, ...]:
    return (decoding.summary, [astuple(p) for p in decoding.params], decoding.remarks, decoding.device,
            decoding.pdu, decoding.uss)


@settings(max_examples=max(80, EXAMPLES), deadline=None)
@given(st.lists(exchanges(), max_size=60), st.sampled_from([None, [], ["atv71"], ["2=atv312"], ["1=xbt", "7=atv71"]]),
       st.frozensets(st.integers(0, 120), max_size=12))
def test_cached_decodings_equal_decoding_each_frame(traffic: list[list[bytes]], profiles: list[str] | None,
                                                    noise: frozenset[int]) -> None:
    """Also the lean path: frames of slaves no profile speaks for (none at all: ``None``; the
    generic one: ``[]``), decoded without message objects, their params named when read; noise;
    and the profiles' kept namers and values against naming every value anew (:class:`tests.oracles.AnewApplier`)."""
    _check_cached_decodings(matched([data for exchange in traffic for data in exchange], noise=noise), profiles)


def _check_cached_decodings(batches: list[MessageBatch], profiles: list[str] | None) -> None:
    cached = Annotator(None if profiles is None else ProfileApplier(profile_book(profiles, [])))
    plain = PlainAnnotator(None if profiles is None else AnewApplier(profile_book(profiles, [])))
    for batch in batches:
        expected = [plain.annotate(message) for message in batch]
        got = list(cached.annotate_batch(batch))
        assert [said(m.decoding) for m in got] == [said(m.decoding) for m in expected]


def test_repeats_share_one_decoding() -> None:
    poll = [adu(b"\x02\x03", struct.pack(">HH", 3201, 1)), adu(b"\x02\x03\x02\x86\x37")]
    batches = matched(poll * 3)
    annotator = Annotator(ProfileApplier(profile_book(["atv71"], [])))
    messages = [m for batch in batches for m in annotator.annotate_batch(batch)]
    assert messages[0].decoding is messages[2].decoding is messages[4].decoding
    assert messages[1].decoding is messages[3].decoding
    assert messages[1].params[0].code == "ETA" and "operation enabled" in str(messages[1].params[0].value)


def test_what_the_profiles_learn_is_not_answered_from_the_cache() -> None:
    """NM1 means ETA until the master points NMA1 at RFRD; the same answer then says RFRD."""
    read_nm1 = [adu(b"\x02\x03", struct.pack(">HH", 12741, 1)), adu(b"\x02\x03\x02\x05\xdc")]
    point_at_rfrd = [adu(b"\x02\x06", struct.pack(">HH", 12701, 8604))] * 2
    batches = matched(read_nm1 + point_at_rfrd + read_nm1)
    annotator = Annotator(ProfileApplier(profile_book(["atv71"], [])))
    messages = [m for batch in batches for m in annotator.annotate_batch(batch)]
    assert messages[1].params[0].code == "NM1→ETA"
    assert messages[5].params[0].code == "NM1→RFRD" and messages[5].params[0].unit == "rpm"


def test_each_slave_reads_its_scanner_table_through_its_own_mapping() -> None:
    """Slaves share what a register's value is named, but not a scanner's value registers:
    slave 2 points NMA1 at RFRD, and slave 3's NM1 still means ETA (its factory mapping)."""
    point_at_rfrd = [adu(b"\x02\x06", struct.pack(">HH", 12701, 8604))] * 2
    reads = [adu(bytes([slave]), b"\x03", struct.pack(">HH", 12741, 1)) for slave in (2, 3)]
    answers = [adu(bytes([slave]), b"\x03\x02\x05\xdc") for slave in (2, 3)]
    batches = matched([*point_at_rfrd, reads[0], answers[0], reads[1], answers[1], reads[0], answers[0]])
    for fast in (True, False):
        annotator = Annotator((ProfileApplier if fast else AnewApplier)(profile_book(["atv71"], [])))
        messages = [m for batch in batches for m in annotator.annotate_batch(batch)]
        assert [messages[at].params[0].code for at in (3, 5, 7)] == ["NM1→RFRD", "NM1→ETA", "NM1→RFRD"]


def test_named_values_kept_stay_bounded(monkeypatch: pytest.MonkeyPatch) -> None:
    """A drive reporting ever new values fills the applier's memory up to its bound, not beyond."""
    monkeypatch.setattr(apply_module, "KEPT_NAMED_PARAMS", 50)
    polls = []
    for value in range(3):
        polls += [adu(b"\x02\x03", struct.pack(">HH", 3201, 1)), adu(b"\x02\x03\x02", struct.pack(">H", value))]
    for value in range(300):
        polls += [adu(b"\x02\x03", struct.pack(">HH", 8604, 1)), adu(b"\x02\x03\x02", struct.pack(">H", value))]
    applier = ProfileApplier(profile_book(["atv71"], []))
    annotator = Annotator(applier)
    messages = [m for batch in matched(polls) for m in annotator.annotate_batch(batch)]
    assert messages[-1].params[0].code == "RFRD" and messages[-1].params[0].raw == 299
    kept = sum(1 + len(namer.known) for namers in applier._namers.values() for namer in namers.values())
    assert 0 < kept <= 50 + 2  # checked before each frame, which adds a namer and a value at most


NUMBERS = st.one_of(st.none(), st.integers(-(2**40), 2**40), st.floats(allow_nan=False, allow_infinity=False),
                    st.text(max_size=8))


@st.composite
def decodings(draw: st.DrawFn) -> Decoding:
    params = tuple(
        ParamValue(draw(st.integers(0, 65535)), raw=draw(st.one_of(st.none(), st.integers(0, 65535))),
                   code=draw(st.one_of(st.none(), st.text(max_size=6))),
                   name=draw(st.one_of(st.none(), st.text(max_size=6))), value=draw(NUMBERS),
                   unit=draw(st.one_of(st.none(), st.text(max_size=3))))
        for _ in range(draw(st.integers(0, 3)))
    )
    return Decoding(draw(st.text()), params, remarks=tuple(draw(st.lists(st.text(max_size=10), max_size=2))))


@st.composite
def annotated_batches(draw: st.DrawFn) -> AnnotatedBatch:
    """Real message columns (framed, paired by the matcher) with arbitrary decodings."""
    frames, t = [], draw(st.integers(0, 2**61))
    for index in range(draw(st.integers(1, 12))):
        t += draw(st.integers(0, 10**9))
        data = draw(st.one_of(st.binary(min_size=1, max_size=12), exchanges().map(lambda pair: pair[0])))
        uss = len(data) >= 3 and draw(st.integers(0, 3)) == 0  # USS telegrams have STX, LGE, ADR at least
        frames.append(Frame(index, t, t + 1000 * len(data), data, crc_ok(data), flag_set(draw(st.integers(0, 15))),
                            protocol=int(uss)))
    batch = Matcher().feed(frames_to_batch(frames))
    annotated = AnnotatedBatch(batch, [draw(decodings()) for _ in range(len(batch))])
    return annotated.select(np.array(draw(st.lists(st.booleans(), min_size=len(batch), max_size=len(batch)))))


@settings(max_examples=max(80, EXAMPLES), deadline=None)
@given(annotated_batches(), st.booleans())
def test_frame_records_are_what_json_dumps_writes(batch: AnnotatedBatch, distinct: bool) -> None:
    """Both ways of writing who a frame is: from the batch's columns (``distinct``: a batch of
    mostly distinct frames) and once per decoding."""
    encoder = FrameRecordEncoder()
    expected = [json.dumps(frame_record(m), ensure_ascii=False, separators=(",", ":")) for m in batch]
    with patch.object(frame_fields_module, "mostly_distinct", lambda *_: distinct):
        assert encoded(encoder, batch) == expected
        assert encoded(encoder, batch) == expected  # again, from the encoder's cache


@settings(max_examples=max(80, EXAMPLES), deadline=None)
@given(annotated_batches(), st.integers(0, 40))
def test_fast_frame_records_say_what_the_exact_ones_say(batch: AnnotatedBatch, reserved: int) -> None:
    """The MCAP spelling: times as the exact decimals of their nanoseconds, a frame's own
    fields padded to one width; parsed, the same record."""
    rows = FrameRecordEncoder(exact=False).rows(batch, reserved=reserved)
    assert rows.reserved == reserved and len(rows) == len(batch)
    for row, message in enumerate(batch):
        assert bytes(rows.data[rows.offsets[row] : rows.offsets[row] + reserved]) == bytes(reserved)
        record = json.loads(rows.row(row), parse_float=Decimal)
        expected = json.loads(encode_record(frame_record(message)), parse_float=Decimal)
        for field, ns in (("t", message.frame.t_start_ns), ("t_end", message.frame.t_end_ns),
                          ("latency_s", message.latency_ns)):
            assert record.pop(field) == (None if ns is None else Decimal(ns).scaleb(-9))
            expected.pop(field)
        assert record == expected


def test_profiled_param_texts_kept_stay_bounded_and_right(monkeypatch: pytest.MonkeyPatch) -> None:
    """A param's JSON is kept by the param object (a namer hands one to every frame with that
    value), up to a bound; past it, what is written stays what ``json.dumps`` writes."""
    monkeypatch.setattr(param_text.PARAM_JSON, "most", 3)
    monkeypatch.setattr(param_text.PARAM_JSON, "kept", {})
    shared = ParamValue(3201, "ETA", "Status word", 0x8637, "ready", None)
    decodings = [Decoding(f"read {n}", (shared, ParamValue(8604, "RFRD", "Speed", n, n * 1e-5, "rpm")))
                 for n in range(8)]
    batch = AnnotatedBatch(matched([adu(b"\x02\x03\x04", struct.pack(">HH", 0x8637, n)) for n in range(8)])[0],
                           decodings)
    encoder = FrameRecordEncoder()
    expected = [json.dumps(frame_record(m), ensure_ascii=False, separators=(",", ":")) for m in batch]
    assert encoded(encoder, batch) == expected
    assert 0 < len(param_text.PARAM_JSON.kept) <= 3


def test_a_frame_of_no_bytes_is_written_too() -> None:
    """The JSONL encoder asks whether a batch's frames are distinct; a frame of no bytes (no
    framer makes one, the fuzzer did) is a frame like any other there."""
    batch = Matcher().feed(frames_to_batch([Frame(0, 0, 0, b"", False, FrameFlag.NONE)]))
    annotated = Annotator().annotate_batch(batch)
    assert encoded(FrameRecordEncoder(), annotated) == [
        json.dumps(frame_record(m), ensure_ascii=False, separators=(",", ":")) for m in annotated]


def test_kept_json_texts_hold_their_text_alone() -> None:
    """orjson's bytes keep the 4 KiB buffer they were written into; the encoder keeps tens of
    thousands of param texts, which must cost their size, not 4 KiB each (260 MB on 1 M frames)."""
    params = [ParamValue(8604, "RFRD", "Speed", n, n, "rpm") for n in range(2000)]
    tracemalloc.start()
    try:
        texts = [param_text.PARAM_JSON.entry(param)[1] for param in params]
        held = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert texts[7] == b'{"address":8604,"code":"RFRD","name":"Speed","raw":7,"value":7,"unit":"rpm"}'
    assert held < 400 * len(params)  # the text, its tuple and dict slot: about 200 bytes


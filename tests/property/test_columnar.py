"""Hypothesis: frames kept in columns (:meth:`Annotator.annotate_columnar`) say what the plain
annotator says of the same frames: the summaries, the values each carries (where the value rows'
rule finds them), the decodings of the rest, and what the annotator keeps for the next batch;
batches cut anywhere."""

from __future__ import annotations

import os
import struct
from dataclasses import astuple
from itertools import pairwise
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.frame import Frame, FrameFlag, frames_to_batch
from decoders.message import IN_COLUMNS, NONE, ROLE_CODE, Decoding, MessageBatch, Role, slice_messages
from decoders.modbus.annotate import Annotator
from decoders.modbus.columnar import KEPT_REQUESTS, NO_VALUE, ColumnarFrames
from decoders.modbus.columnar_text import READ_WRITE, WRITE
from decoders.modbus.param_runs import addressed_values
from decoders.profiles.apply import ProfileApplier
from sniffer.profiles_io import profile_book
from tests.property.test_annotation_cache import PRODUCT, adu, matched, said

#: RTUSNIFF_EXAMPLES raises the number of examples for a long run.
EXAMPLES = int(os.environ.get("RTUSNIFF_EXAMPLES", "0"))
#: A profile of register pairs (floats): frames naming them are decoded one by one.
FLOWMETER = Path(__file__).resolve().parents[1] / "data" / "flowmeter.toml"
#: A profile that names coils and discrete inputs (at 0, 3, 100 and 0, 101) besides a register.
PUMP = FLOWMETER.with_name("pump.toml")

SLAVES = st.sampled_from([1, 2, 7])
#: The ATV71's factory scanner mapping (NMA1-8, then NCA1-8) and more words: read back from
#: 12701, it teaches nothing new.
FACTORY_SCANNER = struct.pack(">16H", 3201, 8604, 0, 0, 0, 0, 0, 0, 8501, 8602, 0, 0, 0, 0, 0, 0) * 8


#: An identification's objects naming another profile than ``PRODUCT``'s (an ATV312).
OTHER_PRODUCT = b"\x00\x0dTelemecanique\x01\x0bATV312HU15M\x02\x040201"


@st.composite
def exchanges(draw: st.DrawFn) -> list[bytes]:
    """A read or a write and (mostly) its answer, or something else a bus carries between them;
    answers damaged, repeated or missing now and then, counts and byte counts off now and then."""
    s, function = bytes([draw(SLAVES)]), draw(st.sampled_from([1, 2, 3, 4, 3, 5, 6, 15, 16, 23]))
    # 3101 and 8400: registers scaled by a tenth, and enumerated (values with texts among plain numbers).
    # 2 and 13: a float of the flow meter's profile, and half of one.
    address = draw(st.sampled_from([0, 3201, 8604, 12741, 12701, 65535, 100, 3101, 8400, 2, 13]))
    count = draw(st.one_of(st.integers(1, 20), st.sampled_from([0, 123, 124, 125, 126, 1968, 1969, 2000, 2001])))
    off = draw(st.sampled_from([0, 0, 0, -1, 1]))
    if function <= 4:
        request = adu(s, bytes([function]), struct.pack(">HH", address, count))
        size = min(max(((count + 7) // 8 if function <= 2 else 2 * count) + off, 0), 250)
        answer = adu(s, bytes([function, size]), draw(st.one_of(st.binary(min_size=size, max_size=size),
                                                                 st.just(FACTORY_SCANNER[:size]))))
    elif function <= 6:
        value = draw(st.sampled_from([0xFF00, 0, 1, 0x8000, 1500, 3201]))  # 3201: the ATV71's factory NMA1
        request = answer = adu(s, bytes([function]), struct.pack(">HH", address, value))
    elif function == 23:  # read ``count`` registers, write some (the scanner's: 12741 read, 12761 written)
        written = draw(st.one_of(st.integers(1, 10), st.sampled_from([0, 121, 122])))
        write_to = draw(st.sampled_from([12761, 12741, 12721, 8501, 0]))
        size = min(max(2 * written + off, 0), 240)
        request = adu(s, b"\x17", struct.pack(">HHHHB", address, min(count, 65535), write_to, written, size),
                      draw(st.binary(min_size=size, max_size=size)))
        size = min(max(2 * min(count, 125) + draw(st.sampled_from([0, 0, 0, -2, 1])), 0), 250)
        answer = adu(s, bytes([function, size]), draw(st.binary(min_size=size, max_size=size)))
    else:
        count = min(count, 240)
        size = min(max(((count + 7) // 8 if function == 15 else 2 * count) + off, 0), 246)
        request = adu(s, bytes([function]), struct.pack(">HHB", address, count, size),
                      draw(st.binary(min_size=size, max_size=size)))
        answer = adu(s, bytes([function]), struct.pack(">HH", address, count + draw(st.sampled_from([0, 0, 1]))))
    match draw(st.integers(0, 9)):
        case 0:
            return [request]  # no answer
        case 1:
            return [request, answer, answer]  # answered twice
        case 2:
            return [request, adu(s, bytes([function | 0x80, 2]))]  # an exception
        case 3:
            damaged = bytearray(answer)
            damaged[draw(st.integers(2, len(answer) - 1))] ^= 1
            return [request, bytes(damaged)]
        case 4:  # an identification: as the same drive again, or as another
            product = draw(st.sampled_from([PRODUCT, PRODUCT, OTHER_PRODUCT]))
            return [adu(s, b"\x2b\x0e\x01\x00"), adu(s, b"\x2b\x0e\x01\x02\x00\x00\x03", product)]
        case 5:
            return [adu(b"\x00", request[1:-2])]  # a broadcast
        case 6:  # a frame of that function of any length, and another
            return [adu(s, bytes([function]), draw(st.binary(max_size=9))) for _ in range(2)]
    return [request, answer]


def annotator(profiles: list[str] | None) -> Annotator:
    return Annotator(None if profiles is None else ProfileApplier(profile_book(profiles, [str(FLOWMETER), str(PUMP)])))


def expected_values(batch: MessageBatch, decodings: list[Decoding],
                    columnar: ColumnarFrames) -> list[tuple[int, ...]]:
    """The value rows' rule, from the plain path's decodings: an answer reports its values where
    it is; a write's values are written where its answer is, before that answer's own."""
    first, request = batch.frames.first_index, batch.request_index.tolist()
    rows = []
    for position, kind in zip(columnar.positions.tolist(), columnar.kind.tolist(), strict=True):
        written = kind in (WRITE, READ_WRITE)
        found = request.index(first + position) if written else position
        if written or request[position] != NONE:
            # A value over several registers is a row of its first register's word.
            for address, raw in ((p.address, p.raw if p.words is None else p.words[0])
                                 for p in decodings[position].params):
                if raw is not None:
                    rows.append((found, not written, position, written, address, raw,
                                 -1 if written else request[position]))
    rows.sort(key=lambda row: row[:2])
    return [(frame, found, written, address, raw, asked) for found, _, frame, written, address, raw, asked in rows]


def check_names(reads: ColumnarFrames, data: bytes, expected: list[Decoding]) -> None:
    """Each frame's params as its profile names them (``reads.names``) are the plain path's;
    none named where no profile names them."""
    params, names = reads.params(data), reads.names
    ends = np.cumsum(params.sizes).tolist()
    for frame, position in enumerate(reads.positions.tolist()):
        rows = range(ends[frame] - int(params.sizes[frame]), ends[frame])
        decoding = expected[position]
        if names is None or all(params.name[row] < 0 for row in rows):  # each param its address and raw word
            assert [(param.address, param.raw, param.value, param.code) for param in decoding.params] == [
                (int(params.address[row]), *[None if params.value[row] == NO_VALUE else int(params.value[row])] * 2,
                 None) for row in rows]
        else:
            assert names is not None
            entries = names.table
            assert params.name is not None
            assert [entries[params.name[row]][0] for row in rows] == list(decoding.params)


def check_batch(columns: Annotator, plain: Annotator, batch: MessageBatch) -> int:
    """One batch through both annotators; how many frames were kept in columns."""
    expected = plain.annotate_batch(batch).decodings
    got = columns.annotate_columnar(batch)
    reads = got.columnar
    kept = set() if reads is None else set(reads.positions.tolist())
    assert got.positions() == list(range(len(batch)))
    assert got.decoded_positions() == [position for position in range(len(batch)) if position not in kept]
    for position in got.decoded_positions():
        assert said(got.decoded[position]) == said(expected[position])
    # Frames in columns too: their decodings, built when read, are the plain path's.
    assert [said(decoding) for decoding in got.decodings] == [said(decoding) for decoding in expected]
    # The decoded form's params of every message are the plain path's, without a decoding built.
    assert [list(map(astuple, params)) for params in got.message_params()] == [
        list(map(astuple, decoding.params)) for decoding in expected]
    if reads is not None:
        data = batch.frames.data
        assert all(got.decoded[position] is IN_COLUMNS for position in kept)
        said_by_pdus = [expected[position].summary for position in reads.positions.tolist()]
        assert reads.summaries(data) == said_by_pdus
        values = reads.values(data)
        each = values.each
        assert values.address.dtype == values.raw.dtype == np.int32
        assert list(zip(*(each(values.frame), each(values.found), each(values.written), values.address, values.raw,
                          each(values.request)), strict=True)) == expected_values(batch, expected, reads)
        check_names(reads, data, expected)
        if values.name is not None:  # a named value is named as its param is
            assert reads.names is not None
            table = reads.names.table
            for name, address, raw in zip(*(column.tolist() for column in (values.name, values.address, values.raw)),
                                          strict=True):
                if name >= 0:
                    param = table[name][0]
                    assert (param.address, param.raw if param.words is None else param.words[0]) == (address, raw)
        for position in kept:  # what a plain frame's decoding says besides: nothing
            assert expected[position].remarks == () and expected[position].device is None
    assert columns._requests == plain._requests
    return len(kept)


@settings(max_examples=max(60, EXAMPLES), deadline=None)
@given(st.lists(exchanges(), max_size=50), st.lists(st.integers(0, 120), max_size=4),
       st.sampled_from([None, [], ["atv71"], ["2=atv312"], ["1=atv71", "7=atv312"], ["2=xbt"],
                        ["1=flowmeter", "2=atv71"], ["1=pump", "7=flowmeter"]]))
def test_reads_in_columns_say_what_the_plain_path_says(traffic: list[list[bytes]], cuts: list[int],
                                                       profiles: list[str] | None) -> None:
    """The matcher's batches, cut again anywhere (between a request and its answer too)."""
    columns, plain = annotator(profiles), annotator(profiles)
    for batch in matched([data for exchange in traffic for data in exchange]):
        bounds = [0, *sorted(cut for cut in set(cuts) if 0 < cut < len(batch)), len(batch)]
        for start, stop in pairwise(bounds):
            check_batch(columns, plain, slice_messages(batch, start, stop))


def test_polling_is_kept_in_columns_and_answers_read_requests_of_the_batch_before() -> None:
    """Not vacuous: polling is all in columns, across a cut between request and answer; a slave
    a profile names too, its values named, each frame polled again named as the first."""
    poll = []
    for slave in (1, 2):
        poll += [adu(bytes([slave]), b"\x03", struct.pack(">HH", 3201, 2)),
                 adu(bytes([slave]), b"\x03\x04\x00\x07\x86\x37")]
    columns, plain = annotator(["2=atv71"]), annotator(["2=atv71"])
    (batch,) = [batch for batch in matched(poll * 3) if len(batch)]
    # Cut between a request and its answer (the matcher holds requests back; a pipeline may not).
    pieces = (slice_messages(batch, 0, 5), slice_messages(batch, 5, len(batch)))
    assert [check_batch(columns, plain, piece) for piece in pieces] == [5, 7]
    reads = columns.annotate_columnar(batch).columnar
    assert reads is not None and reads.names is not None
    # Named once per distinct frame (each slave's request and answer), the groups kept for writers.
    assert reads.groups is not None and reads.groups.firsts.tolist() == [0, 1, 2, 3]
    assert reads.summaries(batch.frames.data)[1:4] == [
        "HR = 0007 8637 (2 registers)", "read HR 3201..3202 (2): ETA",
        "HR = 0007 8637 (2 registers): ETA = 16#0007 quick stop active, forward"]
    assert [(param.code, param.raw) for param, _ in reads.names.table] == [
        ("ETA", None), (None, None), ("ETA", 7), (None, 0x8637)]


def test_a_named_slave_s_scanner_registers_and_remarked_requests_are_not_kept_in_columns() -> None:
    """Reading a scanner table's address registers may teach the table (here: zeros where the
    factory mapping stood), and a read past the profile's limit gets a remark: those frames go
    the plain path. The batch is cut after the answer that teaches, so that the value registers
    read after it (12740-12741, 12741-12742) stay in columns, named after the mapping learnt."""
    slave = b"\x02"
    traffic = []
    for address, count in ((12701, 2), (12741, 2), (12740, 2), (3201, 64), (3201, 2)):
        traffic += [adu(slave, b"\x03", struct.pack(">HH", address, count)),
                    adu(slave, b"\x03", bytes([2 * count]), bytes(2 * count))]
    columns, plain = annotator(["2=atv71"]), annotator(["2=atv71"])
    (batch,) = [batch for batch in matched(traffic) if len(batch)]
    assert check_batch(columns, plain, batch) == 6
    reads = annotator(["2=atv71"]).annotate_columnar(batch).columnar
    assert reads is not None and reads.positions.tolist() == [2, 3, 4, 5, 8, 9]
    assert reads.names is not None and reads.groups is not None


def _read(slave: int, address: int, values: tuple[int, ...]) -> list[bytes]:
    """A read of ``values`` at ``address`` and its answer."""
    s = bytes([slave])
    return [adu(s, b"\x03", struct.pack(">HH", address, len(values))),
            adu(s, b"\x03", bytes([2 * len(values)]), struct.pack(f">{len(values)}H", *values))]


def _names(annotator_: Annotator, batch: MessageBatch) -> list[str]:
    """The summaries of the frames ``annotator_`` keeps in columns of ``batch``."""
    reads = annotator_.annotate_columnar(batch).columnar
    return [] if reads is None else reads.summaries(batch.frames.data)


def test_scanner_value_registers_are_named_in_columns_by_each_slave_s_own_mapping() -> None:
    """Slave 1 points NM1 at RFRD (8604) in one batch (writing NMA1, which stays out of columns);
    in the next both slaves read NM1, in columns: slave 1's is NM1→RFRD, slave 2's the factory
    NM1→ETA, as the plain path names them."""
    columns, plain = annotator(["atv71"]), annotator(["atv71"])
    teach = [adu(b"\x01\x06", struct.pack(">HH", 12701, 8604)), adu(b"\x01\x06", struct.pack(">HH", 12701, 8604))]
    (first,) = [batch for batch in matched(teach) if len(batch)]
    assert check_batch(columns, plain, first) == 0
    (batch,) = [batch for batch in matched(_read(1, 12741, (1500,)) + _read(2, 12741, (0x0637,))) if len(batch)]
    assert check_batch(columns, plain, batch) == 4
    assert _names(columns, batch) == [
        "read HR 12741 (1): NM1→RFRD", "HR = 05DC (1 register): NM1→RFRD = 1500 rpm", "read HR 12741 (1): NM1→ETA",
        "HR = 0637 (1 register): NM1→ETA = 16#0637 operation enabled, reference reached, forward"]


def test_a_scanner_value_register_pointed_elsewhere_is_named_anew() -> None:
    """Slave 1 points NM1 at RFRD (a plain number), reads it, points it
    back at ETA (a state word) and reads it again: the second read is named after ETA, as the
    plain path names it, not after what NM1 was named in the batch before."""
    columns, plain, shown = annotator(["atv71"]), annotator(["atv71"]), annotator(["atv71"])
    said = []
    for target, value in ((8604, 1500), (3201, 0x0637)):
        teach = [adu(b"\x01\x06", struct.pack(">HH", 12701, target))] * 2
        for traffic in (teach, _read(1, 12741, (value,))):
            (batch,) = [batch for batch in matched(traffic) if len(batch)]
            check_batch(columns, plain, batch)
            reads = shown.annotate_columnar(batch).columnar
            said += [] if reads is None else reads.summaries(batch.frames.data)
    assert said == ["read HR 12741 (1): NM1→RFRD", "HR = 05DC (1 register): NM1→RFRD = 1500 rpm",
                    "read HR 12741 (1): NM1→ETA",
                    "HR = 0637 (1 register): NM1→ETA = 16#0637 operation enabled, reference reached, forward"]


def test_the_scanner_s_fc_23_exchange_is_kept_in_columns_named_by_the_mapping() -> None:
    """Not vacuous: a PLC's scanner exchange (FC 23: write NC1-2, read NM1-2) stays in columns,
    named after the factory mapping where the slave has the ATV71 profile, by address where it
    has none; its written values are found at its answer, before the answer's own. A request
    whose answer is an exception goes the plain path."""
    def exchange(slave: int, speed: int) -> list[bytes]:
        s = bytes([slave])
        return [adu(s, b"\x17", struct.pack(">HHHHBHH", 12741, 2, 12761, 2, 4, 0x000F, speed)),
                adu(s, b"\x17\x04", struct.pack(">HH", 0x8637, speed))]
    refused = [exchange(3, 5)[0], adu(b"\x03\x97\x02")]
    columns, plain = annotator(["1=atv71"]), annotator(["1=atv71"])
    (batch,) = [batch for batch in matched(exchange(1, 346) + exchange(2, 393) + refused) if len(batch)]
    assert check_batch(columns, plain, batch) == 4
    reads = columns.annotate_columnar(batch).columnar
    assert reads is not None and reads.positions.tolist() == [0, 1, 2, 3]
    assert reads.summaries(batch.frames.data) == [
        "read HR 12741..12742 (2), write HR 12761..12762 = 000F 015A: NC1→CMD = 16#000F enable operation, forward, "
        "NC2→LFRD = 346 rpm, NM1→ETA, NM2→RFRD",
        "HR = 8637 015A (2 registers): NM1→ETA = 16#8637 operation enabled, reference reached, reverse, "
        "NM2→RFRD = 346 rpm",
        "read HR 12741..12742 (2), write HR 12761..12762 = 000F 0189", "HR = 8637 0189 (2 registers)"]
    values = reads.values(batch.frames.data)
    assert list(zip(values.each(values.found).tolist(), values.each(values.written).tolist(), values.address.tolist(),
                    strict=True)) == [
        (1, True, 12761), (1, True, 12762), (1, False, 12741), (1, False, 12742),
        (3, True, 12761), (3, True, 12762), (3, False, 12741), (3, False, 12742)]


def test_a_batch_that_teaches_a_slave_s_scanner_is_cut_after_the_frame_that_teaches() -> None:
    """Slave 1 reads NM1, points NMA1 at RFRD and reads NM1 again, in one batch: the two reads
    say different things. The batch is cut after the frame that teaches, so each read stays in
    columns, named after the mapping as it stands then, as is slave 2's read of NM1. So too
    after an answer to a read of NMA1 from the batch before (which teaches)."""
    write = adu(b"\x01\x06", struct.pack(">HH", 12701, 8604))
    read_write = adu(b"\x01\x17", struct.pack(">HHHHBH", 3201, 1, 12701, 1, 2, 8604))  # FC 23 writes NMA1
    for teach in ([write, write], [read_write, adu(b"\x01\x17\x02\x06\x37")]):
        columns, plain = annotator(["atv71"]), annotator(["atv71"])
        traffic = _read(1, 12741, (1500,)) + teach + _read(1, 12741, (1500,)) + _read(2, 12741, (1500,))
        (batch,) = [batch for batch in matched(traffic) if len(batch)]
        assert check_batch(columns, plain, batch) == 6
        reads = annotator(["atv71"]).annotate_columnar(batch).columnar
        assert reads is not None and reads.names is not None
        named = [reads.names.table[row][0].code for row in reads.names.row.tolist() if row >= 0]
        assert named == ["NM1→ETA"] * 2 + ["NM1→RFRD"] * 2 + ["NM1→ETA"] * 2
    columns, plain = annotator(["atv71"]), annotator(["atv71"])
    (batch,) = [batch for batch in matched(_read(1, 12701, (8604,)) + _read(1, 12741, (1500,))) if len(batch)]
    pieces = (slice_messages(batch, 0, 1), slice_messages(batch, 1, len(batch)))
    assert [check_batch(columns, plain, piece) for piece in pieces] == [0, 2]


def test_a_scanner_mapping_read_back_or_written_again_keeps_value_registers_in_columns() -> None:
    """A PLC reads back the mapping it set, or writes it again (FC 3, FC 6, FC 16, FC 23), in
    the same batch as its reads of NM1: that teaches nothing new, so the reads of NM1 stay in
    columns, named after the mapping, as the plain path names them (only the frames naming
    NMA1 go the plain path). After the batch that changes NMA1, the same traffic does too."""
    def refreshed(target: int) -> list[list[bytes]]:
        words = struct.pack(">H", target)
        return [_read(1, 12701, (target, 8604)),
                [adu(b"\x01\x06", struct.pack(">H", 12701), words)] * 2,
                [adu(b"\x01\x10", struct.pack(">HHB", 12701, 1, 2), words),
                 adu(b"\x01\x10", struct.pack(">HH", 12701, 1))],
                [adu(b"\x01\x17", struct.pack(">HHHHB", 3201, 1, 12701, 1, 2), words), adu(b"\x01\x17\x02\x06\x37")]]
    for refresh in refreshed(3201):
        columns, plain = annotator(["atv71"]), annotator(["atv71"])
        traffic = _read(1, 12741, (0x0637,)) + refresh + _read(1, 12741, (0x0637,))
        (batch,) = [batch for batch in matched(traffic) if len(batch)]
        assert check_batch(columns, plain, batch) == 4
        assert _names(annotator(["atv71"]), batch)[1::2] == [
            "HR = 0637 (1 register): NM1→ETA = 16#0637 operation enabled, reference reached, forward"] * 2
    for refresh in refreshed(8604):
        # In the batch that changes NMA1 the reads of NM1 say different things: the batch is cut
        # after the change, each read named after the mapping of its part; in the next, the same
        # traffic teaches nothing new, and is one part, named after the new mapping.
        columns, plain = annotator(["atv71"]), annotator(["atv71"])
        traffic = _read(1, 12741, (1500,)) + refresh + _read(1, 12741, (1500,))
        changing, again = [batch for batch in matched(traffic * 2, (len(traffic),)) if len(batch)]
        assert check_batch(columns, plain, changing) == 4
        assert check_batch(columns, plain, again) == 4


def test_a_slave_s_frames_after_its_identification_are_named_by_its_new_profile() -> None:
    """An FC 43 answer may give its slave a profile (here slave 1 says it is an ATV71): its
    frames after it stay in columns, named after that profile, as the plain path names them
    once it has read the answer; the same bytes before it, unnamed. Saying again what it is
    changes nothing; saying it is another drive (an ATV312) names the frames after by that one.
    A second identification in the batch that gives it yet another profile cuts the batch again:
    every poll stays in columns, named by the profile of its part."""
    poll = []
    for slave in (1, 2):
        poll += [adu(bytes([slave]), b"\x03", struct.pack(">HH", 3201, 2)),
                 adu(bytes([slave]), b"\x03\x04\x00\x07\x86\x37")]
    identify = [adu(b"\x01\x2b\x0e\x01\x00"), adu(b"\x01\x2b\x0e\x01\x02\x00\x00\x03", PRODUCT)]
    other = [identify[0], adu(b"\x01\x2b\x0e\x01\x02\x00\x00\x03", OTHER_PRODUCT)]
    columns, plain = annotator([]), annotator([])
    (batch,) = [batch for batch in matched(poll * 2 + identify + poll * 2) if len(batch)]
    assert check_batch(columns, plain, batch) == 16
    assert _names(annotator([]), batch)[1::8] == [  # slave 1's answers before and after
        "HR = 0007 8637 (2 registers)", "HR = 0007 8637 (2 registers): ETA = 16#0007 quick stop active, forward"]
    # The next batch alike: slave 1 has its profile now, and saying again what it is changes nothing.
    assert check_batch(columns, plain, batch) == 16
    (batch,) = [batch for batch in matched(poll * 2 + other + poll * 2) if len(batch)]
    assert check_batch(columns, plain, batch) == 16
    # A slave still generic says it is an ATV71, then an ATV312: three parts, each in columns.
    columns, plain = annotator([]), annotator([])
    (batch,) = [batch for batch in matched(poll + identify + poll + other + poll) if len(batch)]
    assert check_batch(columns, plain, batch) == 12
    reads = annotator([]).annotate_columnar(batch).columnar
    assert reads is not None and reads.positions.tolist() == [0, 1, 2, 3, 6, 7, 8, 9, 12, 13, 14, 15]


def paired_by_hand(adus: list[bytes], answered: dict[int, int]) -> MessageBatch:
    """``adus`` as one batch, requests but the frames ``answered`` maps to their request."""
    frames = frames_to_batch([Frame(i, i * 10, i * 10 + 5, data, True, FrameFlag.NONE)
                              for i, data in enumerate(adus)])
    count = len(adus)
    role = np.full(count, ROLE_CODE[Role.REQUEST], np.uint8)
    paired = np.full(count, NONE, np.int64)
    for answer, request in answered.items():
        role[answer], paired[answer] = ROLE_CODE[Role.RESPONSE], request
    return MessageBatch(frames, role, np.array([data[0] for data in adus], np.int16),
                        np.array([data[1] for data in adus], np.int16), np.full(count, NONE, np.int16),
                        np.zeros(count, np.uint16), paired, np.full(count, NONE, np.int64))


def test_an_answer_too_long_after_its_request_is_read_against_nothing() -> None:
    """Past ``KEPT_REQUESTS`` frames, in both paths alike (the plain path's rule); paired by
    hand, as no matcher waits so long."""
    request = adu(b"\x01\x03", struct.pack(">HH", 10, 1))
    filler = [adu(b"\x05\x06", struct.pack(">HH", 1, n % 65536)) for n in range(KEPT_REQUESTS)]
    answer = adu(b"\x01\x03\x02\x00\x2a")
    for late in (0, 1):
        batch = paired_by_hand([request, *filler[: KEPT_REQUESTS - 1 + late], answer], {KEPT_REQUESTS + late: 0})
        assert check_batch(annotator(None), annotator(None), batch) == (1 if late else 2)
        said_last = addressed_values(annotator(None).annotate_batch(batch).decodings[-1])
        assert said_last == ([] if late else [(10, 42)])


def test_only_the_first_answer_to_a_request_reads_it() -> None:
    """Two answers paired with one request (no matcher here does so; the annotator allows it):
    the second reads against nothing, in both paths."""
    request = adu(b"\x01\x03", struct.pack(">HH", 10, 1))
    answer = adu(b"\x01\x03\x02\x00\x2a")
    batch = paired_by_hand([request, answer, answer], {1: 0, 2: 0})
    assert check_batch(annotator(None), annotator(None), batch) == 2


def test_values_of_coils_are_bits_least_significant_first() -> None:
    traffic = [adu(b"\x01\x01", struct.pack(">HH", 20, 10)), adu(b"\x01\x01\x02\x05\x02")]
    batch = matched(traffic)[0]
    reads = annotator(None).annotate_columnar(batch).columnar
    assert reads is not None
    values = reads.values(batch.frames.data)
    assert values.address.tolist() == list(range(20, 30))
    assert values.raw.tolist() == [1, 0, 1, 0, 0, 0, 0, 0, 0, 1]
    assert values.frame.tolist() == [1] and values.counts.tolist() == [10]


def test_writes_at_the_edges_say_what_the_plain_path_says() -> None:
    """Counts at Modbus's limits and a confirmation past them, a coil written with neither ON
    nor OFF, more coils than a summary shows."""
    traffic = []
    for function, count, confirmed in ((16, 123, 123), (16, 123, 124), (15, 1968, 1969), (15, 33, 33)):
        size = (count + 7) // 8 if function == 15 else 2 * count
        request = adu(b"\x01", bytes([function]), struct.pack(">HHB", 40, count, size), bytes(range(size)))
        traffic += [request, adu(b"\x01", bytes([function]), struct.pack(">HH", 40, confirmed))]
    traffic += [adu(b"\x01\x05", struct.pack(">HH", 7, 0x1234))] * 2
    # Paired by hand: the matcher pairs no confirmation that differs from its write.
    batch = paired_by_hand(traffic, {answer: answer - 1 for answer in range(1, len(traffic), 2)})
    assert check_batch(annotator(None), annotator(None), batch) == 6  # not the confirmations past the limit


def test_register_reads_around_the_words_a_summary_shows_say_what_the_plain_path_says() -> None:
    """Answers of one to eight registers are written by the quick path, longer ones by the
    plain one ("… (+1)"): both sides of the edge, and reads of one value and of many."""
    traffic = []
    for function, count in ((3, 1), (3, 2), (4, 7), (3, 8), (3, 9), (4, 10), (3, 125)):
        traffic += [adu(b"\x01", bytes([function]), struct.pack(">HH", 3201, count)),
                    adu(b"\x01", bytes([function, 2 * count]), bytes(range(2 * count)))]
    batch = paired_by_hand(traffic, {answer: answer - 1 for answer in range(1, len(traffic), 2)})
    assert check_batch(annotator(None), annotator(None), batch) == len(traffic)


def test_register_writes_around_the_words_a_summary_shows_say_what_the_plain_path_says() -> None:
    """FC 16 writes of one to eight registers are written by the quick path, longer ones by the
    plain one ("… (+1)"): both sides of the edge, with their confirmations."""
    traffic = []
    for count in (1, 2, 8, 9, 10):
        traffic += [adu(b"\x01\x10", struct.pack(">HHB", 8501, count, 2 * count), bytes(range(2 * count))),
                    adu(b"\x01\x10", struct.pack(">HH", 8501, count))]
    batch = paired_by_hand(traffic, {answer: answer - 1 for answer in range(1, len(traffic), 2)})
    assert check_batch(annotator(None), annotator(None), batch) == len(traffic)


def test_short_frames_of_every_function_are_left_to_the_plain_path() -> None:
    """Frames too short for their function's layout, alone at the end of a batch (where reading
    past them would leave the batch's bytes)."""
    shorts = [adu(b"\x01")] + [adu(b"\x01", bytes([function]), bytes(range(size)))  # 3 to 7 bytes
                                for function in (1, 3, 5, 6, 15, 16) for size in range(4)]
    for short in shorts:
        for answered in ({}, {1: 0}):
            batch = paired_by_hand([short, short], answered)
            assert check_batch(annotator(None), annotator(None), batch) == 0


def test_a_profile_names_no_coil() -> None:
    """A profile names registers: a coil read or write at a register's address (3201 is the
    ATV71's ETA and the NORD's STW, 8501 the ATV71's CMD, 12701 its NMA1) is shown by address and
    teaches no scanner table, on the plain path and in columns alike (the ATV71 remarks that it
    has no coils: those frames go the plain path; the NORD's stay in columns)."""
    coils = [adu(b"\x01\x01", struct.pack(">HH", 3201, 2)), adu(b"\x01\x01\x01\x03"),
             adu(b"\x01\x05", struct.pack(">HH", 8501, 0xFF00)), adu(b"\x01\x05", struct.pack(">HH", 8501, 0xFF00))]
    traffic = [*coils, adu(b"\x01\x01", struct.pack(">HH", 12701, 1)), adu(b"\x01\x01\x01\x01"),
               *_read(1, 12741, (1500,))]
    for profile, kept in (["atv71"], 2), (["nord-sk"], 8):
        columns, plain = annotator(profile), annotator(profile)
        (batch,) = [batch for batch in matched(traffic) if len(batch)]
        assert check_batch(columns, plain, batch) == kept
        assert [decoding.summary for decoding in annotator(profile).annotate_batch(batch).decodings][:6] == [
            "read coils 3201..3202 (2)", "coils = 11000000 (1 bytes)", "write coil 8501 = ON",
            "write coil 8501 = ON", "read coils 12701 (1)", "coils = 10000000 (1 bytes)"]
    atv71 = annotator(["atv71"]).annotate_batch(batch).decodings
    assert atv71[7].summary == "HR = 05DC (1 register): NM1→ETA = 16#05DC warning, reference reached, forward"



def test_a_value_over_two_registers_is_named_in_columns_unless_a_frame_carries_half_of_it() -> None:
    """A float over two registers carried whole stays in columns, one param named by both words
    (its other register no param of its own); a frame carrying half of it goes the plain path,
    which remarks on it; the slave's other frames stay in columns."""
    traffic = [*_read(1, 2, (0x41B7, 0x7DC0)), *_read(1, 14, (5,)), *_read(1, 13, (0,)), *_read(1, 14, (6,))]
    columns, plain = annotator(["1=flowmeter"]), annotator(["1=flowmeter"])
    (batch,) = [batch for batch in matched(traffic) if len(batch)]
    assert check_batch(columns, plain, batch) == 6
    reads = annotator(["1=flowmeter"]).annotate_columnar(batch).columnar
    assert reads is not None and reads.positions.tolist() == [0, 1, 2, 3, 6, 7]
    assert reads.summaries(batch.frames.data)[:2] == ["read HR 2..3 (2): FLOW",
                                                      "HR = 41B7 7DC0 (2 registers): FLOW = 22.9364 l/min"]
    params = reads.params(batch.frames.data)
    assert params.sizes.tolist() == [1, 1, 1, 1, 1, 1]
    said = [decoding.summary for decoding in annotator(["1=flowmeter"]).annotate_batch(batch).decodings]
    assert said[5] == "HR = 0000 (1 register): F12 = 16#0000 (word 2 of 2)"

"""Hypothesis: the Parquet ``values`` table, which takes a decoding's params apart once and lets
repeats refer to it, holds the rows the value rows' rule gives param by param (the ``values``
command's path), on traffic that repeats writes answered well, with an exception or damaged."""

from __future__ import annotations

import struct
from itertools import pairwise
from typing import Any
from unittest.mock import patch

import pyarrow as pa
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.message import MessageBatch, slice_messages
from decoders.modbus.annotate import Annotator
from decoders.profiles.apply import ProfileApplier
from decoders.stats import Statistics
from sniffer.encoding import value_rows
from sniffer.encoding.value_rows import KEPT_WRITES, ValueRow, ValueRows
from sniffer.exports.parquet_value_columns import value_columns
from sniffer.exports.parquet_values import ValueCollector
from sniffer.profiles_io import profile_book
from tests.property.test_annotation_cache import adu, matched
from tests.property.test_columnar import exchanges, paired_by_hand


class Recorder(ValueRows):
    """The rule param by param: a row per value, as ``values`` lists them."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[tuple[Any, ...]] = []

    def output(self, row: ValueRow) -> None:
        for param, valid in zip(row.params, row.valid, strict=True):
            text = param.value if isinstance(param.value, str) else None
            number = None if text is not None or param.value is None else float(param.value)
            self.rows.append((row.t_ns, row.index, row.slave, row.kind, param.address, param.code, param.name,
                              param.raw, number, text, param.unit, row.request_index, valid))


@settings(max_examples=150, deadline=None)
@given(st.lists(exchanges(), max_size=40), st.integers(1, 4), st.lists(st.integers(0, 300), max_size=4),
       st.sampled_from([KEPT_WRITES, 1, 3]))
def test_value_blocks_hold_the_rows_param_by_param(traffic: list[list[bytes]], repeats: int, cuts: list[int],
                                                   kept_writes: int) -> None:
    """Batches cut anywhere (a write and its answer in two), each taken as the export takes it;
    with few writes allowed to wait, some batches go frame by frame (a write may be pushed out)."""
    annotator = Annotator(ProfileApplier(profile_book(["1=atv71", "2=atv71", "7=atv312"], [])))
    collector, recorder = ValueCollector(), Recorder()
    taken = []
    with patch.object(value_rows, "KEPT_WRITES", kept_writes):
        for batch in matched([data for exchange in traffic * repeats for data in exchange]):
            bounds = [0, *sorted(cut for cut in set(cuts) if 0 < cut < len(batch)), len(batch)]
            for start, stop in pairwise(bounds):
                annotated = annotator.annotate_batch(slice_messages(batch, start, stop))
                collector.messages(annotated)
                recorder.messages(annotated)
                taken.append(value_columns(collector.take())[1])
        collector.finish(Statistics())
        recorder.finish(Statistics())
    taken.append(value_columns(collector.take())[1])
    names = ["t", "index", "slave", "kind", "address", "code", "name", "raw", "value", "text", "unit",
             "request_index", "valid"]
    got = []
    for columns in taken:
        assert columns["t"].cast(pa.int64()).to_pylist() == [t // 1000 for t in columns["t_ns"].to_pylist()]
        columns["t"] = columns["t_ns"]  # nanoseconds, as the rows have them
        got += list(zip(*(columns[name].to_pylist() for name in names), strict=True))
    assert got == recorder.rows
    assert collector.shown == recorder.shown


def rows_both_ways(batches: list[MessageBatch]) -> tuple[list[tuple[Any, ...]], list[tuple[Any, ...]]]:
    """The values table's rows, and the rule's, of ``batches`` (each taken as the export takes it)."""
    annotator = Annotator(ProfileApplier(profile_book(["1=atv71"], [])))
    collector, recorder = ValueCollector(), Recorder()
    got = []
    for batch in batches:
        annotated = annotator.annotate_batch(batch)
        collector.messages(annotated)
        recorder.messages(annotated)
        columns = value_columns(collector.take())[1]
        got += list(zip(*(columns[name].to_pylist() for name in ("index", "kind", "address", "raw", "valid")),
                        strict=True))
    return got, [(row[1], row[3], row[4], row[7], row[12]) for row in recorder.rows]


def test_a_write_pushed_out_before_its_answer_is_not_valid() -> None:
    """Three writes waiting where two may: the first is pushed out (not valid), and its answer
    finds nothing to accept. Paired by hand (a pipelining master; no RTU matcher pairs so)."""
    writes = [adu(b"\x01\x06", struct.pack(">HH", 8501, value)) for value in (1, 2, 3)]
    batch = paired_by_hand([*writes, *writes], {3: 0, 4: 1, 5: 2})
    with patch.object(value_rows, "KEPT_WRITES", 2):
        got, expected = rows_both_ways([batch])
    assert got == expected
    assert [(index, valid) for index, kind, _, _, valid in got if kind == "written"] == [(0, False), (1, True),
                                                                                          (2, True)]

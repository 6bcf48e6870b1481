"""Hypothesis: the Parquet ``values`` table, which takes a decoding's params apart once and lets
repeats refer to it, holds the rows the value rows' rule gives param by param (the ``values``
command's path), on traffic that repeats writes answered well, with an exception or damaged."""

from __future__ import annotations

from typing import Any

import pyarrow as pa
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.modbus.annotate import Annotator
from decoders.profiles.apply import ProfileApplier
from decoders.stats import Statistics
from sniffer.encoding.value_rows import ValueRow, ValueRows
from sniffer.exports.parquet_values import ValueCollector, value_columns
from sniffer.profiles_io import profile_book
from tests.property.test_annotation_cache import matched
from tests.property.test_columnar import exchanges


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


@settings(max_examples=300, deadline=None)
@given(st.lists(exchanges(), max_size=40), st.integers(1, 4))
def test_value_blocks_hold_the_rows_param_by_param(traffic: list[list[bytes]], repeats: int) -> None:
    annotator = Annotator(ProfileApplier(profile_book(["1=atv71", "2=atv71", "7=atv312"], [])))
    collector, recorder = ValueCollector(), Recorder()
    for batch in matched([data for exchange in traffic * repeats for data in exchange]):
        annotated = annotator.annotate_batch(batch)
        collector.messages(annotated)
        recorder.messages(annotated)
    collector.finish(Statistics())
    recorder.finish(Statistics())
    _, columns = value_columns(collector.take())
    names = ["t", "index", "slave", "kind", "address", "code", "name", "raw", "value", "text", "unit",
             "request_index", "valid"]
    columns["t"] = columns["t"].cast(pa.int64())  # nanoseconds, as the rows have them
    got = list(zip(*(columns[name].to_pylist() for name in names), strict=True))
    assert got == recorder.rows
    assert collector.shown == recorder.shown

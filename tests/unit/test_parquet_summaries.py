"""The summary column's lines taken for the frames table (every message, in order) and for the
anomalies (a message once per anomaly it shows: some twice, some never)."""

from __future__ import annotations

import numpy as np

from sniffer.exports.parquet_summaries import Summaries

LINES = ["read HR 3201 (1)", "HR = 0007 (1 register): ETA = 16#0007", "exception 02"]


def test_lines_are_taken_by_row_whatever_the_number_of_rows() -> None:
    summaries = Summaries(np.array(LINES, object))
    assert summaries.of().to_pylist() == LINES
    # As many rows as messages, but not every message once: the first has two anomalies.
    assert summaries.of(np.array([0, 0, 1])).to_pylist() == [LINES[0], LINES[0], LINES[1]]
    assert summaries.of(np.array([2], np.int64)).to_pylist() == [LINES[2]]
    assert summaries.of(np.zeros(0, np.int64)).to_pylist() == []

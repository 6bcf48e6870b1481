"""Hypothesis: the Parquet ``bytes`` column (``_binary`` of :mod:`sniffer.exports.parquet_export`)
holds each frame's bytes, for frames taken in any order, any number of times, as for all of a
batch's frames in order."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from sniffer.exports.parquet_export import _binary


@given(st.lists(st.binary(max_size=12), min_size=1, max_size=20), st.data())
def test_each_frame_s_bytes_whichever_frames_are_taken(frames: list[bytes], data: st.DataObject) -> None:
    offsets = np.cumsum([0] + [len(frame) for frame in frames])
    picked = data.draw(st.one_of(st.just(list(range(len(frames)))),
                                 st.lists(st.integers(0, len(frames) - 1), max_size=30)))
    positions = np.array(picked, np.int64)
    column = _binary(b"".join(frames), offsets[:-1][positions], offsets[1:][positions])
    assert column.to_pylist() == [frames[position] for position in picked]

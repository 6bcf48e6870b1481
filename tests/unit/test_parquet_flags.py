"""The ``frames`` table's ``flags`` column: each frame's flags as the list of their names, in
their order, as JSONL writes them (``flag_names_of``), laid out without ``pyarrow.compute``."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from decoders.frame import FrameFlag, flag_names_of
from sniffer.exports.parquet_export import _flag_lists
from tests.conftest import CAPTURES

EVERY_FLAG = int(sum(FrameFlag))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(min_value=0, max_value=EVERY_FLAG), max_size=60))
def test_each_frame_s_flags_are_their_names_in_order(masks: list[int]) -> None:
    flags = np.array(masks, np.int64)
    expected = pa.array([flag_names_of(mask) for mask in masks], pa.list_(pa.string()))
    assert _flag_lists(flags).equals(expected)


@pytest.mark.parametrize("capture", [["xbt-hmi.log"], ["atv71-plc-poll.mcap", "--profile", "atv71"]],
                         ids=["unnamed", "named"])
def test_an_export_needs_no_compute_module(tmp_path: Path, capture: list[str]) -> None:
    """An export never imports ``pyarrow.compute`` (40 ms at its start): the flags need no
    compute function, the summaries call theirs by name (:mod:`sniffer.exports.arrow_compute`),
    where profiles name frames too; nor pandas (0.5 s), installed beside it in the tests."""
    name, *options = capture
    argv = ["export", str(CAPTURES / name), *options, "--parquet", str(tmp_path / "set"), "--jobs", "1"]
    program = textwrap.dedent(f"""
        import atexit, sys
        atexit.register(lambda: print("pyarrow.compute" in sys.modules, "pandas" in sys.modules and
                                      sys.modules["pandas"] is not None))
        sys.argv = ["rtusniff", *{argv!r}]
        from sniffer.cli import entry_point
        entry_point()
    """)
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, check=False, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[-2:] == ["False", "False"]  # nor pandas, which pyarrow would import

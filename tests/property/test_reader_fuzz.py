"""Fuzzing: damaged capture files end in a CaptureFormatError or read cleanly, never anything else.

Inputs are mutations of the shipped samples (bytes flipped, inserted, deleted, the file cut)
and arbitrary bytes. ``RTUSNIFF_EXAMPLES`` scales the run (see README, "Fuzzing").
"""

from __future__ import annotations

import io
import os
import tempfile
from contextlib import redirect_stderr, redirect_stdout
from functools import cache
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from decoders.line import LineSettings
from sniffer.cli import main
from sniffer.errors import CaptureFormatError, ErrorKind, RtuSniffError
from sniffer.io.base import ReaderOptions
from sniffer.io.registry import all_formats, formats_for, open_reader, open_writer
from tests.conftest import SAMPLE_LOG, SAMPLE_MCAP
from tests.real_recordings import REAL

#: A real logic analyzer's session (3.7 kB), from ../shared/real.
SIGROK_SAMPLE = REAL / "sigrok" / "uart" / "modbus_rtu" / "flowmeter" / "flowmeter_graph_tool.sr"
#: sigrok-cli's own UART annotations of a real recording (sigrok-test).
SIGROK_CLI_SAMPLE = REAL / "sigrok-test" / "uart" / "hello_world_8e1_115200.output"

EXAMPLES = int(os.environ.get("RTUSNIFF_EXAMPLES", "150"))
FUZZ = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
SCRATCH = Path(tempfile.mkdtemp(prefix="rtusniff-fuzz-"))
FILE_EXIT_CODES = {kind.exit_code for kind in ErrorKind} - {ErrorKind.USAGE.exit_code, ErrorKind.RUNTIME.exit_code}


@st.composite
def mutated(draw: st.DrawFn, original: bytes) -> bytes:
    data = bytearray(original)
    for _ in range(draw(st.integers(1, 8))):
        if not data:
            break
        at = draw(st.integers(0, len(data) - 1))
        action = draw(st.sampled_from(["flip", "insert", "delete", "cut"]))
        if action == "flip":
            data[at] ^= draw(st.integers(1, 255))
        elif action == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=16))
        elif action == "delete":
            del data[at : at + draw(st.integers(1, 16))]
        else:
            del data[at:]
    return bytes(data)


def read_all(data: bytes, suffix: str) -> int:
    """Chunks read, or -1 for a clean one-line error naming the file."""
    path = SCRATCH / f"fuzz{suffix}"
    path.write_bytes(data)
    try:
        # A sigrok session and a pcap do not say their line (the other readers ignore this).
        reader = open_reader(str(path), options=ReaderOptions(line=LineSettings.parse("9600 8N1")))
        try:
            return sum(len(batch) for batch in reader.batches())
        finally:
            reader.close()
    except (CaptureFormatError, RtuSniffError) as error:
        assert "\n" not in str(error) and str(path) in str(error)
        return -1


@cache
def sample_of(name: str) -> bytes:
    """The shipped sample in format ``name``: as shipped, or written by that format's writer."""
    shipped = {"text": SAMPLE_LOG, "mcap": SAMPLE_MCAP, "sigrok": SIGROK_SAMPLE, "sigrok-cli": SIGROK_CLI_SAMPLE}
    if name in shipped:
        return shipped[name].read_bytes()
    if name == "saleae":  # read only: the sample's characters as a Logic 2 data table
        from tests.test_saleae_input import logic2

        return logic2(SCRATCH / "sample.csv").read_bytes()
    if name == "pcap":  # read only here: rtusniff's export writes it
        target = SCRATCH / "sample.pcap"
        assert main(["export", str(SAMPLE_LOG), "--pcap", str(target), "--force", "-q"]) == 0
        return target.read_bytes()
    target = SCRATCH / f"sample{all_formats()[name].suffixes[0]}"
    reader = open_reader(str(SAMPLE_LOG))
    writer = open_writer(str(target), reader.info, name)
    for batch in reader.batches():
        writer.write_batch(batch)
    writer.close()
    reader.close()
    return target.read_bytes()


@pytest.mark.parametrize("name", sorted(formats_for("read")))
@FUZZ
@given(data=st.data())
def test_reader_on_damaged_captures(name: str, data: st.DataObject) -> None:
    """Every registered reader, on mutations of a capture in its own format."""
    if name in ("sigrok", "sigrok-cli") and not SIGROK_SAMPLE.exists():
        pytest.skip("../shared/real is not beside the checkout")
    read_all(data.draw(mutated(sample_of(name))), all_formats()[name].suffixes[0])


@FUZZ
@given(st.binary(max_size=512),
       st.sampled_from([".bin", *(s for fmt in formats_for("read").values() for s in fmt.suffixes)]))
def test_readers_on_arbitrary_bytes(data: bytes, suffix: str) -> None:
    read_all(data, suffix)


@FUZZ
@given(st.one_of(mutated(SAMPLE_LOG.read_bytes()), mutated(SAMPLE_MCAP.read_bytes())),
       st.sampled_from([".log", ".mcap"]))
def test_whole_command_on_damaged_captures(data: bytes, suffix: str) -> None:
    """Reading, framing, decoding and profiles together: success or one known exit code."""
    path = SCRATCH / f"whole{suffix}"
    path.write_bytes(data)
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        try:
            code = main(["analyze", str(path), "--format", "jsonl", "--line", "19200", "8E1"])
        except RtuSniffError as error:  # pragma: no cover - main turns these into exit codes
            raise AssertionError(error) from None
    assert code == 0 or code in FILE_EXIT_CODES, err.getvalue()
    said = err.getvalue().splitlines()
    assert all(line.startswith(("error: ", "warning: ")) for line in said), said
    assert sum(line.startswith("error: ") for line in said) == (code != 0)


@cache
def extended_sample(name: str) -> bytes:
    """The shipped sample with rtusniff's extensions: UART errors and two channels (text, MCAP)."""
    import numpy as np

    from decoders.capture import ChunkBatch

    reader = open_reader(str(SAMPLE_LOG))
    batch = ChunkBatch.concat(list(reader.batches()))
    reader.close()
    kinds = np.zeros(len(batch.data), np.uint8)
    kinds[::37] = 1
    kinds[5::53] = 2
    channels = (np.arange(len(batch)) % 2 + 1).astype(np.uint8)
    from dataclasses import replace

    info = replace(reader.info, channels=("TX", "RX"))
    target = SCRATCH / f"extended{all_formats()[name].suffixes[0]}"
    writer = open_writer(str(target), info, name)
    writer.write_batch(ChunkBatch(batch.data, batch.ends, batch.t_end_ns, kinds, channels))
    writer.close()
    return target.read_bytes()


@pytest.mark.parametrize("name", ["text", "mcap"])
@FUZZ
@given(data=st.data())
def test_readers_on_damaged_extended_captures(name: str, data: st.DataObject) -> None:
    """The capture formats' extensions (``# uart-errors:``, ``# channel:``; MCAP side topics),
    damaged: read, or one line naming the file."""
    sample = extended_sample(name)
    assert read_all(sample, all_formats()[name].suffixes[0]) > 0
    read_all(data.draw(mutated(sample)), all_formats()[name].suffixes[0])

"""Every reader/writer pair of the registry round-trips a capture losslessly; every
format is found by its suffix and by sniffing its first bytes; heavy dependencies load
only when their format is used."""

from __future__ import annotations

from itertools import product
from pathlib import Path

import pytest

from decoders.capture import Chunk
from sniffer.io.registry import all_formats, find_format, formats_for, open_reader, open_writer
from tests.conftest import SAMPLE_LOG

FORMATS = sorted(set(formats_for("read")) & set(formats_for("write")))


def read_all(path: Path) -> tuple[object, list[Chunk], list[str]]:
    reader = open_reader(str(path))
    chunks = [c for b in reader.batches() for c in b.chunks()]
    reader.close()
    return reader.info, chunks, reader.late_notes


@pytest.mark.parametrize(("via", "to"), list(product(FORMATS, FORMATS)))
def test_round_trip(tmp_path: Path, via: str, to: str) -> None:
    original_info, original_chunks, _ = read_all(SAMPLE_LOG)
    paths = []
    source = SAMPLE_LOG
    for step, name in enumerate((via, to)):
        fmt = all_formats()[name]
        target = tmp_path / f"step{step}{fmt.suffixes[0]}"
        reader = open_reader(str(source))
        writer = open_writer(str(target), reader.info)
        for batch in reader.batches():
            writer.write_batch(batch)
        writer.close()
        reader.close()
        paths.append(target)
        source = target
    info, chunks, _ = read_all(paths[-1])
    assert info == original_info
    assert chunks == original_chunks


def test_text_round_trip_is_byte_identical(tmp_path: Path) -> None:
    reader = open_reader(str(SAMPLE_LOG))
    target = tmp_path / "copy.log"
    writer = open_writer(str(target), reader.info)
    for batch in reader.batches():
        writer.write_batch(batch)
    writer.close()
    assert target.read_bytes() == SAMPLE_LOG.read_bytes()


@pytest.mark.parametrize("name", FORMATS)
def test_every_format_is_found_by_suffix_and_by_sniffing(tmp_path: Path, name: str) -> None:
    fmt = all_formats()[name]
    reader = open_reader(str(SAMPLE_LOG))
    target = tmp_path / f"capture{fmt.suffixes[0]}"
    writer = open_writer(str(target), reader.info, name)
    for batch in reader.batches():
        writer.write_batch(batch)
    writer.close()
    reader.close()
    nameless = tmp_path / "capture"
    nameless.write_bytes(target.read_bytes())
    assert find_format(str(target)) is fmt
    assert open_reader(str(nameless)).info == open_reader(str(target)).info
    others = [f for f in all_formats().values() if f is not fmt]
    assert not any(other.sniff(target.read_bytes()[:64]) for other in others)


def test_listing_the_formats_imports_no_heavy_dependency() -> None:
    """Building the argument parser lists the formats; mcap and zstandard load only for MCAP."""
    import subprocess
    import sys

    code = ("import sys; from sniffer.io.registry import all_formats; all_formats(); "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('mcap', 'zstandard')))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"


def test_a_read_only_format_plugs_in_and_its_reader_sees_the_options(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A format with a reader and no writer: chosen by sniffing, offered to --input-format and
    refused to --output-format, and its reader gets --line and --timing from the command."""
    from decoders.capture import CaptureInfo, TimingQuality
    from sniffer.cli import main
    from sniffer.io import registry
    from sniffer.io.base import CaptureFormat, ReaderOptions

    seen: list[ReaderOptions] = []

    class FakeReader:
        def __init__(self, path: str, options: ReaderOptions) -> None:
            seen.append(options)
            self.info = CaptureInfo(options.line, options.timing or TimingQuality.HOST)
            self.late_notes: list[str] = []
            self.warnings: list[str] = []
            self._inner = open_reader(str(SAMPLE_LOG))

        def batches(self) -> object:
            return self._inner.batches()

        def close(self) -> None:
            self._inner.close()

    fake = CaptureFormat("fake", (".fake",), "a read-only test format", sniff=lambda head: head.startswith(b"FAKE"),
                         open_reader=FakeReader)
    formats = {**all_formats(), "fake": fake}
    monkeypatch.setattr(registry, "all_formats", lambda: formats)
    capture = tmp_path / "recording"
    capture.write_bytes(b"FAKE capture")
    assert main(["analyze", str(capture), "--line", "19200", "8E1", "--timing", "exact", "--format", "jsonl",
                 "-o", str(tmp_path / "out.jsonl")]) == 0
    assert seen[-1].line is not None and seen[-1].line.format() == "19200 8E1"
    assert seen[-1].timing is TimingQuality.EXACT
    assert "fake" in formats_for("read") and "fake" not in formats_for("write")
    with pytest.raises(SystemExit) as refused:  # argparse: not a choice for --output-format
        main(["convert", str(SAMPLE_LOG), str(tmp_path / "x.fake"), "--output-format", "fake"])
    assert refused.value.code == 2

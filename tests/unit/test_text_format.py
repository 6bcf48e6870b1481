"""The rtu-capture v1 text format: what it reads, and the one-line errors for what it refuses."""

from __future__ import annotations

from pathlib import Path

import pytest

from decoders.capture import CaptureInfo, Chunk, ChunkBatch, TimingQuality
from decoders.line import LineSettings
from sniffer.errors import CaptureFormatError, ErrorKind
from sniffer.io.formats.text import TextCaptureReader, parse_time_ns
from sniffer.io.text_writer import format_time_ns

GOOD = """# rtu-capture v1
# line: 19200 8E1
# timing: exact
# any other comment line
1700000000.011173964 02 03 0C 1E 00 04 27 6C
1700000000.022376060 02 03 08 00 28 02 58 01 F4 00 00 52 B0
"""


def read(tmp_path: Path, text: str | bytes) -> tuple[CaptureInfo, list[ChunkBatch]]:
    path = tmp_path / "capture.log"
    if isinstance(text, str):
        path.write_text(text)
    else:
        path.write_bytes(text)
    reader = TextCaptureReader(str(path))
    try:
        return reader.info, list(reader.batches())
    finally:
        reader.close()


def test_reads_the_specification_example(tmp_path: Path) -> None:
    info, batches = read(tmp_path, GOOD)
    assert info == CaptureInfo(LineSettings.parse("19200 8E1"), TimingQuality.EXACT, ("any other comment line",))
    chunks = [c for b in batches for c in b.chunks()]
    assert [c.t_end_ns for c in chunks] == [1700000000011173964, 1700000000022376060]
    assert chunks[0].data == bytes.fromhex("02030C1E0004276C")


@pytest.mark.parametrize("hex_text", ["02 03 0c 1e", "02030C1E", "02030c1E", "02 030C 1e", "02\t03 0C\t1E"])
def test_hex_case_and_spacing(tmp_path: Path, hex_text: str) -> None:
    _, batches = read(tmp_path, f"# rtu-capture v1\n# line: 9600 8N1\n1.5 {hex_text}\n")
    assert batches[0].data == bytes.fromhex("02030C1E")


def test_times_keep_nanoseconds_exactly() -> None:
    assert parse_time_ns("1700000000.000000001") == 1_700_000_000_000_000_001
    assert parse_time_ns("1700000000.5") == 1_700_000_000_500_000_000
    assert parse_time_ns("12") == 12_000_000_000
    assert format_time_ns(1_700_000_000_000_000_001) == "1700000000.000000001"
    for bad in ("1.0000000001", "-1.0", "1e9", "1.", ".5", "abc"):
        assert parse_time_ns(bad) is None


def test_equal_times_are_allowed(tmp_path: Path) -> None:
    _, batches = read(tmp_path, "# rtu-capture v1\n1.0 01\n1.0 02\n")
    assert batches[0].t_end_ns.tolist() == [1_000_000_000, 1_000_000_000]


def test_missing_line_and_timing_headers(tmp_path: Path) -> None:
    info, _ = read(tmp_path, "# rtu-capture v1\n1.0 01\n")
    assert info.line is None
    assert info.timing is TimingQuality.HOST


def test_blank_lines_and_late_comments(tmp_path: Path) -> None:
    path = tmp_path / "c.log"
    path.write_text("# rtu-capture v1\n\n# first\n1.0 01\n\n# later\n2.0 02\n")
    reader = TextCaptureReader(str(path))
    chunks = [c for b in reader.batches() for c in b.chunks()]
    assert len(chunks) == 2
    assert reader.info.notes == ("first",)
    assert reader.late_notes == ["later"]


ERRORS = [
    ("", ErrorKind.BAD_HEADER, 1, "empty file"),
    ("1.0 01 02\n", ErrorKind.BAD_HEADER, 1, "missing header"),
    ("# rtu-capture v2\n1.0 01\n", ErrorKind.UNKNOWN_FORMAT, 1, "unknown format version v2"),
    ("# rtu-capture v1\n# line: 19200 8X1\n", ErrorKind.BAD_HEADER, 2, "'19200 8X1'"),
    ("# rtu-capture v1\n# line: 19200 8E1\n# line: 9600 8E1\n", ErrorKind.BAD_HEADER, 3, "second '# line:'"),
    ("# rtu-capture v1\n# timing: roughly\n", ErrorKind.BAD_HEADER, 2, "neither 'exact' nor 'host'"),
    ("# rtu-capture v1\n1.0 01 0G\n", ErrorKind.BAD_DATA, 2, "bad hex digit 'G'"),
    ("# rtu-capture v1\n1.0 01 0\n", ErrorKind.BAD_DATA, 2, "odd number of hex digits (3)"),
    ("# rtu-capture v1\n1.0 010 2\n", ErrorKind.BAD_DATA, 2, "two digits each"),
    ("# rtu-capture v1\n1.0\n", ErrorKind.BAD_DATA, 2, "at least one byte"),
    ("# rtu-capture v1\n1,5 01\n", ErrorKind.BAD_DATA, 2, "bad time '1,5'"),
    ("# rtu-capture v1\n# uart-errors: 0 framing\n1.0 01\n", ErrorKind.BAD_DATA, 2, "must follow the data line"),
    ("# rtu-capture v1\n1.0 01 02\n# uart-errors: 2 framing\n", ErrorKind.BAD_DATA, 3, "byte 2 of a line of 2 bytes"),
    ("# rtu-capture v1\n1.0 01\n# uart-errors: 0 overrun\n", ErrorKind.BAD_DATA, 3, "bad UART error '0 overrun'"),
    ("# rtu-capture v1\n# channels: RX TX\n1.0 01\n# channel: MISO\n", ErrorKind.BAD_DATA, 4,
     "channel 'MISO' is not one of the header's: RX TX"),
    ("# rtu-capture v1\n# channel: RX\n1.0 01\n", ErrorKind.BAD_DATA, 2, "none (no '# channels:' header)"),
    ("# rtu-capture v1\n# channels: RX RX\n", ErrorKind.BAD_HEADER, 2, "must name up to 255 different"),
    ("# rtu-capture v1\n# channels: RX\n# channels: TX\n", ErrorKind.BAD_HEADER, 3, "second '# channels:'"),
    (
        "# rtu-capture v1\n2.0 01\n\n1.999999999 02\n",
        ErrorKind.DECREASING_TIME,
        4,
        "before the previous line's 2.000000000",
    ),
]


@pytest.mark.parametrize(("text", "kind", "line_number", "words"), ERRORS)
def test_errors_name_file_line_and_fault(
    tmp_path: Path, text: str, kind: ErrorKind, line_number: int, words: str
) -> None:
    with pytest.raises(CaptureFormatError) as caught:
        read(tmp_path, text)
    message = str(caught.value)
    assert caught.value.kind is kind
    assert message.startswith(f"{tmp_path / 'capture.log'}:line {line_number}: ")
    assert words in message
    assert "\n" not in message


def test_binary_garbage(tmp_path: Path) -> None:
    with pytest.raises(CaptureFormatError) as caught:
        read(tmp_path, b"# rtu-capture v1\n1.0 01\n\x89PNG\x00\xff\n")
    assert caught.value.kind is ErrorKind.BAD_DATA
    assert "line 3: not text: byte 0x89" in str(caught.value)


def test_reads_nothing_after_an_error(tmp_path: Path) -> None:
    path = tmp_path / "c.log"
    path.write_text("# rtu-capture v1\n" + "1.0 01\n" * 10 + "x\n" + "2.0 02\n")
    reader = TextCaptureReader(str(path))
    with pytest.raises(CaptureFormatError):
        list(reader.batches())


MARKED = """# rtu-capture v1
# line: 19200 8E1
# timing: exact
1700000000.011173964 02 03 0C 1E 00 04 27 6C
# uart-errors: 0 framing, 7 framing+parity
# a note between
1700000000.022376060 02 03
# uart-errors: 1 Parity
"""


def test_uart_errors_mark_the_line_above(tmp_path: Path) -> None:
    info, batches = read(tmp_path, MARKED)
    [batch] = batches
    assert [c.uart_errors for c in batch.chunks()] == [((0, 1), (7, 3)), ((1, 2),)]
    assert info.notes == ()


def test_uart_errors_round_trip_and_plain_files_stay_plain(tmp_path: Path) -> None:
    from sniffer.io.text_writer import TextCaptureWriter

    _, [batch] = read(tmp_path, MARKED)
    out = tmp_path / "out.log"
    writer = TextCaptureWriter(str(out), CaptureInfo(LineSettings.parse("19200 8E1"), TimingQuality.EXACT))
    writer.write_batch(batch)
    writer.close()
    assert out.read_text() == MARKED.replace("# a note between\n", "").replace("Parity", "parity")
    plain = tmp_path / "plain.log"
    writer = TextCaptureWriter(str(plain), CaptureInfo(LineSettings.parse("19200 8E1"), TimingQuality.EXACT))
    _, [good] = read(tmp_path, GOOD)
    writer.write_batch(good)
    writer.close()
    assert "uart-errors" not in plain.read_text()


def test_a_batch_boundary_keeps_the_mark_with_its_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from sniffer.io.formats import text

    monkeypatch.setattr(text, "BATCH_CHUNKS", 1)
    _, batches = read(tmp_path, MARKED)
    assert [c.uart_errors for b in batches for c in b.chunks()] == [((0, 1), (7, 3)), ((1, 2),)]


CHANNELS = """# rtu-capture v1
# line: 19200 8E1
# timing: exact
# channels: TX RX
1700000000.000000000 00
# channel: TX
1700000000.011173964 02 03 0C 1E 00 04 27 6C
1700000000.015000000 05
# channel: RX
1700000000.022376060 02 03
# channel: -
1700000000.032376060 04
"""


def test_channels_name_the_lines_that_follow_and_round_trip(tmp_path: Path) -> None:
    from sniffer.io.text_writer import TextCaptureWriter

    info, [batch] = read(tmp_path, CHANNELS)
    assert info.channels == ("TX", "RX") and info.notes == ()
    assert [c.channel for c in batch.chunks()] == [0, 1, 1, 2, 0]
    out = tmp_path / "out.log"
    writer = TextCaptureWriter(str(out), info)
    writer.write_batch(batch)
    writer.close()
    assert out.read_text() == CHANNELS


@pytest.mark.parametrize(("note", "lines"), [
    ("site: Grüße", ["# site: Gr\\xfc\\xdfe"]),
    ("two\n1700000000.0 01 03 00 00 00 01 84 0A", ["# two", "# 1700000000.0 01 03 00 00 00 01 84 0A"]),
    ("line: 9600 8N1", ["# (note) line: 9600 8N1"]),
    ("uart-errors: 0 framing", ["# (note) uart-errors: 0 framing"]),
    ("tab\there", ["# tab\\x09here"]),
    ("", ["#"]),
])
def test_notes_never_become_data_or_headers(tmp_path: Path, note: str, lines: list[str]) -> None:
    """A note from another capture (an MCAP's, anything) is written as comment lines only: a
    newline cannot start a data line, a note cannot pass for a header or an extension line, and
    what is not ASCII is escaped (the format is ASCII)."""
    from sniffer.io.text_writer import TextCaptureWriter, comment_lines

    assert comment_lines(note) == lines
    path = tmp_path / "notes.log"
    writer = TextCaptureWriter(str(path), CaptureInfo(LineSettings.parse("19200 8E1"), TimingQuality.EXACT, (note,)))
    writer.write_batch(ChunkBatch.from_chunks([Chunk(1_700_000_000_000_000_000, b"\x01")]))
    writer.add_notes([note])
    writer.close()
    info, [batch] = read(tmp_path, path.read_text())
    assert batch.data == b"\x01" and info.line == LineSettings.parse("19200 8E1")


def test_comment_lines_beyond_the_limit_are_counted_not_kept(tmp_path: Path) -> None:
    """A stream of comments (stdin from a chatty tool) must not grow memory without end."""
    from sniffer.io.formats import text

    path = tmp_path / "chatty.log"
    header = [f"# header note {i}" for i in range(600)]
    body = [f"1700000000.{i:09d} 01" if i % 3 == 0 else f"# late note {i}" for i in range(3000)]
    path.write_text("\n".join(["# rtu-capture v1", "# line: 19200 8E1", *header, *body]) + "\n")
    reader = TextCaptureReader(str(path))
    data = b"".join(batch.data for batch in reader.batches())
    assert data == bytes([1]) * 1000  # every byte read
    assert len(reader.info.notes) == 600 and len(reader.late_notes) == text.MAX_NOTES - 600
    assert len(reader.warnings) == 1 and "the first 1,000" in reader.warnings[0]


def test_a_line_longer_than_a_read_can_be_is_refused_before_it_is_held(tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """A 100 MB line cost gigabytes: a line is read only up to what one read of the limit takes."""
    path = tmp_path / "long-line.log"
    path.write_text("# rtu-capture v1\n# timing: host\n1700000000.0 " + "ab" * (2 * 2**20) + "\n1700000001.0 01\n")
    with pytest.raises(CaptureFormatError, match="RTUSNIFF_MAX_READ_MB=N") as error:
        list(TextCaptureReader(str(path)).batches())
    assert error.value.location == "line 3"
    monkeypatch.setenv("RTUSNIFF_MAX_READ_MB", "2")
    assert sum(len(b.data) for b in TextCaptureReader(str(path)).batches()) == 2 * 2**20 + 1

"""Hostile inputs at the entrances added last (issue 69): names that would forge lines, metadata
that would pass altered, outputs that would destroy inputs. Each test failed before its fix."""

from __future__ import annotations

import json
import re
import shutil
import zipfile
from collections.abc import Callable
from pathlib import Path

import pytest

from benchmarks.hostile_inputs import (
    DEVICE,
    FORGED,
    HOSTILE_ANNOTATION_LINES,
    HOSTILE_NAMES,
    HOSTILE_SESSION_METADATA,
    hostile_pcaps,
    many_registers,
    pcapng_of,
    sigrok_session,
    two_line_mcap,
)
from decoders.capture import CaptureInfo, Chunk, ChunkBatch, TimingQuality
from decoders.line import LineSettings
from sniffer.io.registry import open_reader, open_writer
from tests.conftest import CliResult
from tests.real_recordings import REAL

Cli = Callable[..., CliResult]
LINE = LineSettings.parse("19200 8E1")
#: A write of HR 1 = 3 to slave 1 that never happened, as a data line.



@pytest.mark.parametrize("names", HOSTILE_NAMES, ids=[repr(n)[:24] for n in HOSTILE_NAMES])
def test_line_names_round_trip_through_text_and_forge_nothing(cli: Cli, tmp_path: Path,
                                                               names: tuple[str, ...]) -> None:
    source = two_line_mcap(tmp_path / "in.mcap", names)
    text, back = tmp_path / "out.log", tmp_path / "back.mcap"
    assert cli("convert", str(source), str(text)).code == 0
    written = text.read_text(encoding="ascii")
    assert all(line.startswith("#") or line[:10].isdigit() for line in written.splitlines())
    assert FORGED not in written
    reader = open_reader(str(text))
    assert reader.info.channels == names
    reader.close()
    assert cli("convert", str(text), str(back)).code == 0
    frames = [r for r in cli("analyze", str(back), "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    assert [(f["channel"], f["function"]) for f in frames] == [(names[0], 3), (names[-1], 3)]


def test_two_lines_of_one_name_are_refused_by_the_text_writer(cli: Cli, tmp_path: Path) -> None:
    source = two_line_mcap(tmp_path / "in.mcap", ("RX", "RX"))
    result = cli("convert", str(source), str(tmp_path / "out.log"))
    assert result.code == 11 and "two of the capture's lines are named 'RX'" in result.err
    assert not (tmp_path / "out.log").exists()


def test_a_bad_escape_in_a_channel_line_is_one_line(cli: Cli, tmp_path: Path) -> None:
    path = tmp_path / "bad.log"
    path.write_text("# rtu-capture v1\n# line: 19200 8E1\n# channels: A%zz B\n1.0 01\n")
    result = cli("stats", str(path))
    assert result.code == 6 and "'%zz' is not an escape" in result.err


@pytest.mark.skipif(not (REAL / "sigrok").exists(), reason="../shared/real is not beside the checkout")
def test_a_sigrok_probe_name_with_a_continuation_line_forges_nothing(cli: Cli, tmp_path: Path) -> None:
    session = REAL / "sigrok" / "uart" / "modbus_rtu" / "brainchild_io_16do" / "brainchild-io-16do.sr"
    copy = tmp_path / "named.sr"
    with zipfile.ZipFile(session) as original, zipfile.ZipFile(copy, "w") as target:
        for entry in original.infolist():
            data = original.read(entry)
            if entry.filename == "metadata":  # an INI continuation line carries a data line into the name
                data = data.replace(b"probe1=0\n", f"probe1=RX\n  {FORGED}\n".encode()).replace(b"probe2=1\n",
                                                                                                  b"probe2=TX\n")
            target.writestr(entry, data)
    text = tmp_path / "out.log"
    result = cli("convert", str(copy), str(text), "--line", "19200 8E1", "--channel", "1", "--channel", "TX")
    assert result.code == 0, result.err
    data_lines = [line for line in text.read_text().splitlines() if not line.startswith("#")]
    assert FORGED not in data_lines and open_reader(str(text)).info.channels[0] == f"RX\n{FORGED}"
    frames = [r for r in cli("analyze", str(text), "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    assert not any(str(f["t"]).startswith("1700000000") for f in frames)
    assert len(frames) == len([r for r in cli("analyze", str(copy), "--line", "19200 8E1", "--channel", "1",
                                              "--channel", "TX", "--format", "jsonl").jsonl()
                               if r["kind"] == "frame"])


@pytest.mark.parametrize("notes", ["[" * 100_000, '["\\ud800"]', '["a", "\\udfff b"]'])
def test_mcap_notes_that_are_no_text_are_one_line_in_every_output(cli: Cli, tmp_path: Path, notes: str) -> None:
    from benchmarks.hostile_inputs import FIELDS, T0, block_at, crafted_mcap

    path = crafted_mcap(tmp_path / "notes.mcap", {**FIELDS, "notes": notes}, [block_at(T0)])
    for argv in (["analyze", "--format", "jsonl"], ["stats"], ["report", "-o", str(tmp_path / "r.md")]):
        result = cli(argv[0], str(path), *argv[1:])
        assert result.code == 9 and "Traceback" not in result.err, result.err
        assert len(result.err.strip().splitlines()) == 1 and "notes" in result.err


def test_a_chunk_without_bytes_round_trips_through_text(cli: Cli, tmp_path: Path) -> None:
    """A chunk without bytes (the moment a live capture last heard the line) was a traceback in
    convert and cut to text: it is a ``# heard-until:`` line there, read back as the same chunk."""
    source = tmp_path / "empty-chunk.mcap"
    chunks = [Chunk(1_700_000_000_000_000_000, bytes.fromhex("010300000001840A")),
              Chunk(1_700_000_000_001_000_000, b""),
              Chunk(1_700_000_000_010_000_000, bytes.fromhex("01030200056B87")),
              Chunk(1_700_000_002_000_000_000, b"")]
    writer = open_writer(str(source), CaptureInfo(LINE, TimingQuality.EXACT, ()), "mcap")
    writer.write_batch(ChunkBatch.from_chunks(chunks))
    writer.close()
    text, back = tmp_path / "out.log", tmp_path / "back.mcap"
    assert cli("convert", str(source), str(text)).code == 0
    assert "# heard-until: 1700000000.001000000\n" in text.read_text()
    assert cli("convert", str(text), str(back)).code == 0
    reader = open_reader(str(back))
    read = [(c.t_end_ns, c.data) for b in reader.batches() for c in b.chunks()]
    assert read == [(c.t_end_ns, c.data) for c in chunks]
    reader.close()
    cut = cli("cut", str(source), "-o", str(tmp_path / "cut.log"), "--limit", "2")
    assert cut.code == 0, cut.err
    bad = tmp_path / "bad.log"
    bad.write_text("# rtu-capture v1\n# line: 19200 8E1\n1.0 01\n# heard-until: soon\n")
    result = cli("stats", str(bad))
    assert result.code == 7 and "'# heard-until:' 'soon' is not a time" in result.err
    # In order with the data lines, both ways: times never decrease.
    for text in ("2.0 01\n# heard-until: 1.0\n", "# heard-until: 5.0\n3.0 01\n"):
        bad.write_text("# rtu-capture v1\n# line: 19200 8E1\n1.0 01\n" + text)
        result = cli("stats", str(bad))
        assert result.code == 8 and "is before the previous line's" in result.err, result.err


def test_every_shipped_capture_reads_the_same_through_text(cli: Cli, tmp_path: Path) -> None:
    """The escaping leaves plain names as they were: the shipped samples convert byte for byte."""
    from tests.conftest import ROOT

    for sample in sorted((ROOT / "captures").glob("*.log")):
        out = tmp_path / sample.name
        shutil.copy(sample, tmp_path / "in.log")
        assert cli("convert", str(tmp_path / "in.log"), str(out), "--force").code == 0
        assert out.read_text() == sample.read_text().replace("\r\n", "\n") or sample.name.endswith("-crlf.log")


HOSTILE_TEXT = "<img src=http://evil.example/p.png> ![x](http://evil.example/q.png) [ticket](http://evil.example) " \
               "# Heading *bold* _under_ `code` | cell | $x$ &lt;b&gt;"


#: Short enough to arrive within the sample's 41 ms between a request and the next.
HOSTILE_PRODUCT = "<b>![i](//e.x/q)</b>`c`|#"


def _identification_answer(vendor: str, product: str) -> str:
    from decoders.crc import crc_bytes

    objects = bytes([0, len(vendor)]) + vendor.encode() + bytes([1, len(product)]) + product.encode()
    body = bytes([2, 0x2B, 0x0E, 1, 2, 0, 0, 2]) + objects
    return (body + crc_bytes(body)).hex(" ").upper()


def test_the_markdown_report_renders_only_what_rtusniff_wrote(cli: Cli, tmp_path: Path) -> None:
    """Notes, a file name and FC 43 identification strings with HTML, images, links, headings
    and backticks: rendered by a CommonMark renderer with tables (markdown-it, which rich brings),
    the report holds no tag, image or link and no heading but its own."""
    from markdown_it import MarkdownIt

    from tests.conftest import ROOT

    source = (ROOT / "captures" / "atv312-setup.log").read_text()
    capture = tmp_path / "site `x` ![a](evil.example) #1.log"
    answer = next(line for line in source.splitlines() if line.startswith("1700000000.049829671 02 2B 0E"))
    source = source.replace("# timing: exact\n", f"# timing: exact\n# {HOSTILE_TEXT}\n", 1)
    forged = f"1700000000.049829671 {_identification_answer('V', HOSTILE_PRODUCT)}"
    capture.write_text(source.replace(answer, forged, 1))
    result = cli("report", str(capture), "--format", "md")
    assert result.code == 0, result.err
    assert "evil.example/p.png" in result.out and "e.x/q" in result.out  # said, as text
    tokens = MarkdownIt("commonmark").enable("table").parse(result.out)
    children = [child for token in tokens for child in (token.children or [])]
    kinds = {child.type for child in children} | {t.type for t in tokens}
    assert not kinds & {"html_inline", "html_block", "image", "em_open"}, kinds
    # The only links are rtusniff's own, from a finding to its anomalies' heading in the report.
    links = [str(child.attrs["href"]) for child in children if child.type == "link_open"]
    assert links and all(re.fullmatch(r"#[a-z0-9-]+", link) for link in links), links
    headings = [tokens[i + 1].content for i, t in enumerate(tokens) if t.type == "heading_open"]
    assert all(not h.startswith("Heading") for h in headings) and len(headings) >= 3
    rendered = MarkdownIt("commonmark").enable("table").render(result.out)
    assert "<img" not in rendered and "&lt;img src=http://evil.example/p.png&gt;" in rendered
    assert re.findall(r"<a [^>]*>", rendered) == [f'<a href="{link}">' for link in links]


BAD_METADATA = HOSTILE_SESSION_METADATA


@pytest.mark.parametrize(("metadata", "words"), BAD_METADATA, ids=range(len(BAD_METADATA)))
def test_bad_session_metadata_is_one_line(cli: Cli, tmp_path: Path, metadata: str, words: str | None) -> None:
    path = sigrok_session(tmp_path / "s.sr", metadata)
    result = cli("stats", str(path), "--line", "9600 8N1", "--channel", "RX")
    assert "Traceback" not in result.err
    if words is None:
        assert result.code == 14, result.err  # an idle line: no bytes
        return
    assert result.code == 6 and len(result.err.strip().splitlines()) == 1 and words in result.err, result.err


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads the peak memory from /proc")
def test_session_bombs_are_read_in_bounded_memory(tmp_path: Path) -> None:
    """A 512 MiB metadata is refused by its declared size; a sample file of 256 MiB (a quarter
    of a megabyte zipped) is read in pieces: the run ends with one line, in well under the bomb's
    size (before, it was read whole)."""
    import subprocess
    import sys

    metadata_bomb = sigrok_session(tmp_path / "m.sr", DEVICE, comment_mib=512)
    # An idle line: nothing to decode, a quarter of a gigabyte to go through.
    sample_bomb = sigrok_session(tmp_path / "b.sr", DEVICE, bytes([0xFF]) * 2**20, repeats=2**8)
    assert metadata_bomb.stat().st_size < 2**20 * 2 and sample_bomb.stat().st_size < 2**20 * 2
    for path, code, words in ((metadata_bomb, 6, "metadata of 536,871,"), (sample_bomb, 14, "holds no bytes")):
        # VmHWM: the peak of this process's own memory (ru_maxrss counts the forking parent's too)
        done = subprocess.run([sys.executable, "-c", "import re, sys\nfrom sniffer.cli import main\n"
                               "code = main(sys.argv[1:])\nstatus = open('/proc/self/status').read()\n"
                               "print(re.search(r'VmHWM:\\s*(\\d+)', status)[1])\nsys.exit(code)",
                               "stats", str(path), "--line", "9600 8N1", "--channel", "RX"],
                              capture_output=True, text=True, timeout=120, check=False)
        assert done.returncode == code and words in done.stderr, done.stderr
        assert int(done.stdout.split()[-1]) < 200 * 1024, done.stdout  # KiB: well under the bomb


PCAPS = hostile_pcaps()


@pytest.mark.parametrize("case", PCAPS, ids=[case[0] for case in PCAPS])
def test_hostile_pcaps_are_one_line_in_bounded_memory(cli: Cli, tmp_path: Path,
                                                     case: tuple[str, str, bytes, int, str]) -> None:
    _, name, content, code, words = case
    path = tmp_path / name
    path.write_bytes(content)
    result = cli("stats", str(path), "--line", "19200 8E1")
    assert result.code == code and words in result.err and "Traceback" not in result.err, result.err
    if code:
        assert len(result.err.strip().splitlines()) == 1


def test_a_pcapng_of_a_fine_resolution_gives_exact_times(cli: Cli, tmp_path: Path) -> None:
    path = tmp_path / "ps.pcapng"
    path.write_bytes(pcapng_of(10, 17_000_000_001_234_567_891))  # tenths of nanoseconds
    frames = [r for r in cli("analyze", str(path), "--line", "19200 8E1", "--format", "jsonl").jsonl()
              if r["kind"] == "frame"]
    assert frames[0]["t_end_ns"] == 1_700_000_000_123_456_789


def test_classic_pcap_refuses_times_it_cannot_hold(cli: Cli, tmp_path: Path) -> None:
    source = tmp_path / "late.log"
    source.write_text("# rtu-capture v1\n# line: 19200 8E1\n# timing: exact\n"
                      "4300000000.000000000 01 03 00 00 00 01 84 0A\n")
    result = cli("export", str(source), "--pcap", str(tmp_path / "late.pcap"))
    assert result.code == 11 and "write .pcapng" in result.err and not (tmp_path / "late.pcap").exists()
    assert cli("export", str(source), "--pcap", str(tmp_path / "late.pcapng")).code == 0
    frames = [r for r in cli("analyze", str(tmp_path / "late.pcapng"), "--line", "19200 8E1", "--format",
                             "jsonl").jsonl() if r["kind"] == "frame"]
    assert frames[0]["t_ns"] // 10**9 == 4_299_999_999


@pytest.mark.parametrize("value", ["0x1_2", "0o17", "0b1_01", "٧٢", "1_0", " 0x", "0x100", "256", "0b111111111"])
def test_saleae_values_are_logic_s_radixes_only(cli: Cli, tmp_path: Path, value: str) -> None:
    path = tmp_path / "a.csv"
    path.write_text(f'name,type,start_time,duration,data\n"Async Serial","data",0.001,0.0005,{value}\n',
                    encoding="utf-8")
    result = cli("stats", str(path), "--line", "19200 8E1")
    assert result.code == 7 and "is not a byte" in result.err, result.err


def test_saleae_radixes_read_as_before(cli: Cli, tmp_path: Path) -> None:
    path = tmp_path / "a.csv"
    rows = [f'"Async Serial","data",{0.001 + i * 0.0006:.4f},0.0005,{v}' for i, v in
            enumerate(["0x01", "03", "0b00000000", "0X00", "0x00", "0x01", "0x84", "0x0A"])]
    path.write_text("name,type,start_time,duration,data\n" + "\n".join(rows) + "\n")
    frames = [r for r in cli("analyze", str(path), "--line", "19200 8E1", "--format", "jsonl").jsonl()
              if r["kind"] == "frame"]
    assert [f["hex"] for f in frames] == ["010300000001840a"]


@pytest.mark.parametrize("time", ["nan", "inf", "-inf", "1e300"])
def test_saleae_digital_times_that_are_no_times_are_one_line(cli: Cli, tmp_path: Path, time: str) -> None:
    path = tmp_path / "d.csv"
    path.write_text(f"Time [s],Channel 0\n0.000000000,1\n0.001,0\n{time},1\n")
    result = cli("stats", str(path), "--line", "9600 8N1")
    assert result.code == 7 and "not a time in seconds" in result.err and "Traceback" not in result.err


@pytest.mark.parametrize(("line", "words"), HOSTILE_ANNOTATION_LINES)
def test_sigrok_cli_text_that_is_none_of_sigrok_s_is_one_line(cli: Cli, tmp_path: Path, line: str, words: str) -> None:
    path = tmp_path / "a.txt"
    path.write_text('10-20 uart-1: rx-data: "02"\n' + line + "\n", encoding="utf-8")
    result = cli("stats", str(path), "--line", "9600 8N1", "--input-format", "sigrok-cli")
    assert result.code == 7 and words in result.err and len(result.err) < 400, result.err


def test_three_hundred_directions_are_refused(cli: Cli, tmp_path: Path) -> None:
    path = tmp_path / "a.txt"
    path.write_text("".join(f'{10 * i}-{10 * i + 9} uart-1: d{i}-data: "02"\n' for i in range(300)))
    result = cli("stats", str(path), "--line", "9600 8N1", "--input-format", "sigrok-cli")
    assert result.code == 7 and "neither rx-data nor tx-data" in result.err and "Traceback" not in result.err


def _sample_copy(folder: Path, name: str = "a.log") -> Path:
    from tests.conftest import ROOT

    folder.mkdir(exist_ok=True)
    target = folder / name
    shutil.copy(ROOT / "captures" / "atv71-plc-poll.log", target)
    return target


def test_each_never_writes_over_a_capture_of_its_folder(cli: Cli, tmp_path: Path) -> None:
    folder = tmp_path / "site"
    capture = _sample_copy(folder, "x.log")
    before = capture.read_bytes()
    for command in (["stats", "--each"], ["report", "--each", "--format", "md"]):
        result = cli(command[0], str(folder), *command[1:], "-o", str(capture), "--force")
        assert result.code == 2 and "is the input" in result.err and capture.read_bytes() == before, result.err


@pytest.mark.parametrize("command", [["analyze"], ["stats"], ["values"], ["report", "--format", "md"],
                                     ["export", "--mcap"]])
def test_standard_input_is_never_written_over(tmp_path: Path, command: list[str]) -> None:
    import subprocess
    import sys

    capture = _sample_copy(tmp_path)
    before = capture.read_bytes()
    argv = [*command, str(capture)] if command[-1] == "--mcap" else [*command, "-o", str(capture)]
    with capture.open("rb") as stdin:
        done = subprocess.run([sys.executable, "-m", "sniffer", argv[0], "-", *argv[1:], "--force"], stdin=stdin,
                              capture_output=True, text=True, check=False)
    assert done.returncode == 2 and "is the input on standard input" in done.stderr, done.stderr
    assert capture.read_bytes() == before


def test_follow_never_writes_over_a_file_of_its_rotation(cli: Cli, tmp_path: Path) -> None:
    capture = _sample_copy(tmp_path, "site.log")
    rotated = _sample_copy(tmp_path, "site-0002.log")
    before = rotated.read_bytes()
    for name in ("site-0002.log", "site-0003.log"):
        result = cli("analyze", "--follow", str(capture), "-o", str(tmp_path / name), "--force")
        assert result.code == 2 and "is a file of the rotation --follow" in result.err, result.err
    assert rotated.read_bytes() == before and not (tmp_path / "site-0003.log").exists()


@pytest.mark.parametrize("command", ["analyze", "stats", "values"])
def test_a_failed_run_leaves_no_output_file(cli: Cli, tmp_path: Path, command: str) -> None:
    broken = tmp_path / "broken.log"
    broken.write_text("# rtu-capture v1\n# line: 19200 8E1\n1.0 01 03 00 00 00 01 84 0A\n2.0 01 ZZ\n")
    out = tmp_path / "out.txt"
    result = cli(command, str(broken), "-o", str(out))
    assert result.code == 7 and not out.exists() and not list(tmp_path.glob(".out*")), result.err


@pytest.mark.parametrize("kind", ["zstd", "zstd-unsized", "lz4"])
def test_a_chunk_inflates_no_further_than_it_declares(cli: Cli, tmp_path: Path, kind: str) -> None:
    """256 MiB inside a chunk that declares 100 bytes (a zstd frame header claiming it, a zstd
    frame or an lz4 one that claims nothing): one line, exit 9, without inflating it (was
    gigabytes and minutes)."""
    if kind == "lz4":
        pytest.importorskip("lz4")
    from benchmarks.hostile_inputs import inflate_bomb

    path = inflate_bomb(tmp_path / "bomb.mcap", kind)
    result = cli("stats", str(path))
    assert result.code == 9 and "the 100 bytes it declares" in result.err, result.err


def _metadata_span(data: bytes) -> tuple[int, int]:
    """Where the 'rtusniff.capture' metadata record lies in an MCAP file."""
    name = b"rtusniff.capture"
    at = data.index(name) - 4 - 9  # opcode, length, then the name's own length
    assert data[at] == 0x0C
    return at, at + 9 + int.from_bytes(data[at + 1 : at + 9], "little")


def test_a_bit_flipped_in_the_capture_metadata_is_said_never_read_as_truth(cli: Cli, tmp_path: Path) -> None:
    """Every bit flip inside the metadata record either gives an error (exit 9, or 5 for a
    version it cannot read) or reads the very same capture: never 39200 Bd for 19200, parity M
    for E, or notes changed (85 of 559 flips did before the record was sealed)."""
    import random

    from tests.conftest import ROOT

    original = (ROOT / "captures" / "atv71-plc-poll.mcap").read_bytes()
    start, end = _metadata_span(original)
    whole = tmp_path / "whole.log"
    assert cli("convert", str(ROOT / "captures" / "atv71-plc-poll.mcap"), str(whole)).code == 0
    flipped, back = tmp_path / "flipped.mcap", tmp_path / "back.log"
    rng = random.Random(69)
    errors = 0
    for position in rng.sample(range(start, end), 60):
        data = bytearray(original)
        data[position] ^= 1 << rng.randrange(8)
        flipped.write_bytes(bytes(data))
        back.unlink(missing_ok=True)
        result = cli("convert", str(flipped), str(back))
        assert "Traceback" not in result.err
        if result.code == 0:
            assert back.read_text() == whole.read_text(), (position, result.err)
        else:
            errors += 1
            assert result.code in (5, 9) and len(result.err.strip().splitlines()) == 1, result.err
    assert errors >= 55
    # With --line, the data of a damaged record is still read, and the user told.
    data = bytearray(original)
    data[original.index(b"19200 8E1")] ^= 0x02  # 19200 → 39200
    flipped.write_bytes(bytes(data))
    refused = cli("stats", str(flipped))
    assert refused.code == 9 and "does not match its sha256 digest" in refused.err, refused.err
    given = cli("stats", str(flipped), "--line", "19200 8E1")
    assert given.code == 0 and "metadata is damaged" in given.err


def test_a_record_without_a_seal_reads_as_before_unless_a_key_is_unknown(cli: Cli, tmp_path: Path) -> None:
    from benchmarks.hostile_inputs import FIELDS, T0, block_at, crafted_mcap

    old = crafted_mcap(tmp_path / "old.mcap", FIELDS, [block_at(T0, data=bytes.fromhex("010300000001840A"))])
    assert cli("stats", str(old)).code == 0
    flipped_key = crafted_mcap(tmp_path / "key.mcap", {**FIELDS, "lime": "39200 8E1"}, [block_at(T0)])
    result = cli("stats", str(flipped_key))
    assert result.code == 9 and "holds a field 'lime' rtusniff never writes" in result.err, result.err


def test_a_dataset_holds_a_capture_once_whatever_its_bus_or_name(cli: Cli, tmp_path: Path) -> None:
    """12 exports of one capture (other --bus, copied names) gave 624 rows for its 52 frames."""
    import pyarrow.dataset as ds

    capture = _sample_copy(tmp_path)
    copy = _sample_copy(tmp_path, "copy-of-a.log")
    dataset = tmp_path / "plant"
    assert cli("export", str(capture), "--parquet", str(dataset)).code == 0
    for argv in ([str(capture), "--bus", "line-2"], [str(copy)], [str(copy), "--bus", "a"]):
        result = cli("export", *argv, "--parquet", str(dataset))
        assert result.code == 11 and "in the dataset already, as bus 'a'" in result.err, result.err
    assert ds.dataset(dataset / "frames", partitioning="hive").count_rows() == 52


@pytest.mark.parametrize("bus", ["..", ".", "a/b", "a\nb", "a\x1bb", " a", "a:b", "x" * 101, "a\u2028b"])
def test_bus_names_that_are_no_folder_names_are_refused(cli: Cli, tmp_path: Path, bus: str) -> None:
    capture = _sample_copy(tmp_path)
    result = cli("export", str(capture), "--parquet", str(tmp_path / "plant"), "--bus", bus)
    assert result.code == 2 and "--bus" in result.err and len(result.err.strip().splitlines()) == 1, result.err
    assert not (tmp_path / "plant").exists() or not any((tmp_path / "plant").rglob("*.parquet"))


def test_a_capture_file_named_as_no_bus_is_told_to_give_one(cli: Cli, tmp_path: Path) -> None:
    capture = _sample_copy(tmp_path, "..log")
    result = cli("export", str(capture), "--parquet", str(tmp_path / "plant"))
    assert result.code == 2 and "give --bus NAME" in result.err, result.err
    assert cli("export", str(capture), "--parquet", str(tmp_path / "plant"), "--bus", "line-1").code == 0


FOLLOW_HEAD = "# rtu-capture v1\n# line: 19200 8E1\n# timing: exact\n"
POLL = "1700000000.{:03d}000000 01 03 00 00 00 01 84 0A\n"


@pytest.mark.parametrize("change", ["truncated", "replaced", "removed", "rewritten"])
def test_following_a_file_that_is_changed_under_it_stops_and_says_so(tmp_path: Path, change: str) -> None:
    """``stats --follow`` of a text recording that is truncated, replaced by a rename, removed
    or rewritten: it stops within a moment (a text recording is otherwise followed until
    Ctrl-C), prints the statistics of what it read and a warning naming the change, exit 0."""
    import os
    import subprocess
    import sys
    import time

    path = tmp_path / "site.log"
    path.write_text(FOLLOW_HEAD + "".join(POLL.format(i * 20) for i in range(10)))
    follower = subprocess.Popen([sys.executable, "-m", "sniffer", "stats", "--follow", str(path), "--format", "json"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(2.0)  # read to its end, waiting
    if change == "truncated":
        with path.open("r+") as f:
            f.truncate(len(FOLLOW_HEAD) + 10)
    elif change == "replaced":
        other = tmp_path / "other.log"
        other.write_text(FOLLOW_HEAD + POLL.format(900))
        os.replace(other, path)
    elif change == "removed":
        path.unlink()
    else:  # in place, the same length: no moment where it is shorter
        with path.open("r+") as f:
            f.seek(path.stat().st_size - len("84 0A\n"))
            f.write("84 39\n")
    try:
        out, err = follower.communicate(timeout=15)
    finally:
        follower.kill()
    assert follower.returncode == 0, err
    assert json.loads(out)["frames"] == 10
    words = {"truncated": "truncated to", "replaced": "replaced by another file", "removed": "removed or renamed",
             "rewritten": "rewritten while followed"}[change]
    assert f"{path}: {words}" in err and "following stopped at byte" in err, err


def test_wide_values_are_bounded_with_the_figures(cli: Cli, tmp_path: Path) -> None:
    """Columns that grow with the capture (a read of its own addresses each time): 400 reads
    would be 400 rows × 50 000 columns; over the bound it is refused, naming the figures."""
    from sniffer.views import values

    capture = many_registers(tmp_path / "many.log", 400)
    out = tmp_path / "wide.csv"
    original = values.MAX_WIDE_CELLS
    values.MAX_WIDE_CELLS = 1_000_000
    try:
        result = cli("values", str(capture), "--wide", "-o", str(out))
    finally:
        values.MAX_WIDE_CELLS = original
    assert result.code == 2 and "--wide would write 400 rows of 50,000 parameters" in result.err, result.err
    assert not out.exists()
    assert cli("values", str(capture), "--wide", "--format", "jsonl", "-o", str(out)).code == 0  # no empty cells


def test_wide_values_held_are_bounded(cli: Cli, tmp_path: Path) -> None:
    from sniffer.views import values

    capture = many_registers(tmp_path / "many.log", 40)
    original = values.MAX_WIDE_VALUES
    values.MAX_WIDE_VALUES = 1_000
    try:
        result = cli("values", str(capture), "--wide")
    finally:
        values.MAX_WIDE_VALUES = original
    assert result.code == 2 and "--wide holds every value until the end" in result.err and result.out == ""


def test_a_cleared_tally_keeps_only_what_it_must() -> None:
    """``clear`` resets the pairs counted since the last one and leaves the others as they are
    (zero): it no longer sweeps every pair the bus ever had (minutes on 6 000 pairs)."""
    import numpy as np

    from decoders.stats_tally import FunctionTally

    tally = FunctionTally(counters=2, bins=8)
    everything = tally.rows(np.arange(1, 5001, dtype=np.int64))
    tally.count(everything, [np.ones(5000, np.bool_), np.zeros(5000, np.bool_)])
    tally.drain()
    tally.clear()
    some = tally.rows(np.array([7, 9, 7], np.int64))
    tally.count(some, [np.ones(3, np.bool_), np.ones(3, np.bool_)])
    tally.add(0, some, np.array([1, 2, 1]), np.array([10, 20, 30], np.int64))
    drained = tally.drain()
    assert [(t.function, t.counters) for t in drained] == [(7, [2, 2]), (9, [1, 1])]
    tally.clear()
    assert tally.drain() == []
    again = tally.rows(np.array([7], np.int64))
    tally.count(again, [np.ones(1, np.bool_), np.zeros(1, np.bool_)])
    assert [(t.function, t.counters, t.histograms) for t in tally.drain()] == [(7, [1, 0], (None, None))]


def test_what_the_fuzz_targets_found_is_one_line(cli: Cli, tmp_path: Path) -> None:
    """Found by the new atheris targets: a digest field outside ASCII (a TypeError in the seal's
    comparison), and a pcapng if_tsresol option cut short by its block (an IndexError)."""
    import struct

    from benchmarks.hostile_inputs import FIELDS, T0, block_at, crafted_mcap

    digest = crafted_mcap(tmp_path / "d.mcap", {**FIELDS, "sha256": "é"}, [block_at(T0)])
    result = cli("stats", str(digest))
    assert result.code == 9 and "does not match its sha256 digest" in result.err, result.err
    section = pcapng_of(6, 1)[:28]
    body = struct.pack("<HHI", 147, 0, 65535) + struct.pack("<HH", 9, 1)  # the option's value is missing
    interface = struct.pack("<II", 1, len(body) + 12) + body + struct.pack("<I", len(body) + 12)
    path = tmp_path / "cut.pcapng"
    path.write_bytes(section + interface)
    result = cli("stats", str(path), "--line", "19200 8E1")
    assert result.code == 14 and "Traceback" not in result.err, result.err


def test_numbers_in_files_are_ascii_digits(cli: Cli, tmp_path: Path) -> None:
    """Line settings in an MCAP's metadata of Arabic-Indic digits read as 19200 before (int()
    takes any digits): now they are no line settings."""
    from benchmarks.hostile_inputs import FIELDS, T0, block_at, crafted_mcap
    from sniffer.io.formats.text import parse_time_ns

    path = crafted_mcap(tmp_path / "digits.mcap", {**FIELDS, "line": "١٩٢٠٠ 8E1"}, [block_at(T0)])
    assert cli("stats", str(path)).code == 9
    assert parse_time_ns("١٧٠٠٠٠٠٠٠٠.5") is None and parse_time_ns("1700000000.5") == 1_700_000_000_500_000_000


@pytest.mark.skipif(not (REAL / "sigrok").exists(), reason="../shared/real is not beside the checkout")
def test_saleae_column_names_round_trip_and_forge_nothing(cli: Cli, tmp_path: Path) -> None:
    """Saleae's own default names ("Channel 1"), and a quoted column name holding a newline and a
    data line, through convert to text and back."""
    from tests.test_saleae_input import digital_export

    session = REAL / "sigrok" / "uart" / "modbus_rtu" / "brainchild_io_16do" / "brainchild-io-16do.sr"
    names = ["Channel 1", f"TX\n{FORGED}"]
    csv_path = digital_export(session, tmp_path / "digital.csv", [1, 2], ['"Channel 1"', f'"TX\n{FORGED}"'])
    text = tmp_path / "out.log"
    options = ["--line", "19200", "8E1", "--channel", "1", "--channel", "2"]
    result = cli("convert", str(csv_path), str(text), *options)
    assert result.code == 0, result.err
    assert FORGED not in [line for line in text.read_text().splitlines() if not line.startswith("#")]
    assert open_reader(str(text)).info.channels == tuple(names)
    direct = [r for r in cli("analyze", str(csv_path), *options, "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    back = [r for r in cli("analyze", str(text), "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    assert [(r["hex"], r.get("channel")) for r in back] == [(r["hex"], r.get("channel")) for r in direct]
    assert len(back) > 10

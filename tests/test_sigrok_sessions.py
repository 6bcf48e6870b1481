"""sigrok sessions (.sr) read as captures: the UART decoded from the samples is what sigrok's own
test suite expects (../shared/real/sigrok-test/uart: every character's value, first sample, end
and error state, per test.conf's decoder options), and the Modbus recordings give the frames of
their sigrok-cli text conversions (../shared/real/sigrok-cli-text)."""

from __future__ import annotations

import ast
import configparser
import json
import re
import shutil
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from decoders.line import LineSettings
from decoders.uart import CharacterFormat, UartDecoder, pulse_baud
from sniffer.io.base import ReaderOptions
from sniffer.io.sigrok_session import SigrokSessionReader
from tests.conftest import ROOT, CliResult
from tests.real_recordings import REAL as SHARED_REAL

SIGROK = SHARED_REAL / "sigrok"
EXPECTED = SHARED_REAL / "sigrok-test" / "uart"
TEXT = SHARED_REAL / "sigrok-cli-text"
Cli = Callable[..., CliResult]
PARITY = {"none": "N", "even": "E", "odd": "O", "mark": "M", "space": "S"}
#: sigrok's UART decoder options rtusniff's capture model has no room for (9 data bits: the
#: decoder alone, test_nine_data_bits_decode_as_sigrok_expects).
UNSUPPORTED = {"parity=ignore", "data_bits=9", "invert_rx=yes", "invert_tx=yes"}

pytestmark = pytest.mark.skipif(not SIGROK.exists(), reason="../shared/real is not beside the checkout")


def uart_tests() -> list[tuple[str, str, int, str, dict[str, str]]]:
    """(name, input, sigrok channel index, expected .python, options) of each single-line UART
    test in sigrok-test's test.conf whose recording is here."""
    tests, current = [], None
    for line in (EXPECTED / "test.conf").read_text().splitlines():
        if line.startswith("test "):
            current = {"name": line.split()[1], "python": None}
            tests.append(current)
        elif current is not None and "protocol-decoder uart" in line:
            current["channels"] = re.findall(r"channel (\w+)=(\d+)", line)
            current["options"] = dict(re.findall(r"option (\w+)=(\S+)", line))
            current["flags"] = set(re.findall(r"option (\w+=\S+)", line))
        elif current is not None and line.strip().startswith("input "):
            current["input"] = line.split()[1]
        elif current is not None and "output uart python match" in line:
            current["python"] = line.split()[-1]
        elif current is not None and line.strip().startswith("output uart annotation match"):
            current["annotations"] = line.split()[-1]
    found = []
    for test in tests:
        source = SIGROK / str(test.get("input", ""))
        if not source.is_file() or test["python"] is None or len(test.get("channels", [])) != 1:
            continue
        if test["flags"] & UNSUPPORTED:
            continue
        found.append((str(test["name"]), str(source), int(test["channels"][0][1]), str(test["python"]),
                      dict(test["options"])))
        ANNOTATIONS[(str(test["name"]), test["options"].get("format", "hex"))] = str(test.get("annotations", ""))
    return found


#: The sigrok-cli annotation text each test expects (its .output file), by test name and format
#: (sigrok-test runs some recordings once per format under one name).
ANNOTATIONS: dict[tuple[str, str], str] = {}


def expected_frames(python: str) -> list[tuple[int, int, int, bool]]:
    """(first sample, end sample, value, valid) of each FRAME sigrok expects."""
    frames = []
    for line in (EXPECTED / python).read_text().splitlines():
        match = re.match(r"(\d+)-(\d+) uart: \['FRAME', \d+, (.*)\]$", line)
        if match:
            value, valid = ast.literal_eval(match[3])
            frames.append((int(match[1]), int(match[2]), value, valid))
    return frames


def probe_name(session: str, index: int) -> str:
    parser = configparser.ConfigParser(interpolation=None, strict=False)
    parser.read_string(zipfile.ZipFile(session).read("metadata").decode())
    return parser["device 1"][f"probe{index + 1}"]


TESTS = uart_tests() if (EXPECTED / "test.conf").exists() else []  # skipped without ../shared


def test_the_suite_is_here() -> None:
    names = {name for name, *_ in TESTS}
    assert len(TESTS) >= 17, names
    assert {"hello_world_8n1_1200", "hello_world_8n1_921600", "hello_world_7e1_115200", "hello_world_8o1_115200",
            "hello_world_7o1_115200_parity_err"} <= names


@pytest.mark.parametrize(("name", "session", "channel", "python", "options"), TESTS, ids=[t[0] for t in TESTS])
def test_uart_decodes_as_sigrok_expects(name: str, session: str, channel: int, python: str,
                                        options: dict[str, str]) -> None:
    line = LineSettings.parse(f"{options.get('baudrate', '115200')} {options.get('data_bits', '8')}"
                              f"{PARITY[options.get('parity', 'none')]}{int(float(options.get('stop_bits', '1')))}")
    reader = SigrokSessionReader(session, ReaderOptions(line=line, channels=(probe_name(session, channel),)))
    values, ends, kinds = [], [], []
    for batch in reader.batches():
        values += list(batch.data)
        ends += batch.t_end_ns.tolist()
        kinds += batch.error_kinds().tolist()
    reader.close()
    expected = expected_frames(python)
    assert values == [value for _, _, value, _ in expected], name
    # Each character sigrok calls invalid (parity or stop bit wrong) carries its error in the capture.
    assert [kind != 0 for kind in kinds] == [not valid for *_, valid in expected], name
    rate = reader._rate
    t0 = reader._t0_ns
    # Each character ends where sigrok's frame ends, to a sample and a half (sigrok rounds the
    # frame's end to a whole sample after its own rounding of the start bit's).
    got_ends = (np.array(ends) - t0) * rate / 1e9
    assert np.all(np.abs(got_ends - np.array([end for _, end, _, _ in expected])) <= 1.5)
    errors = sum(1 for *_, valid in expected if not valid)
    said = " ".join(reader.warnings)
    assert (errors == 0) == (said == ""), said
    if errors:
        assert re.search(r"(\d+) characters with a framing error, (\d+) with a parity error", said)
        framing, parity = map(int, re.search(r"(\d+) characters with a framing error, (\d+)", said).groups())
        assert framing + parity >= errors


MODBUS = [("flowmeter/flowmeter_target0_val0.sr", "9600 8N1", [], "sr_flowmeter_target0_val0.log"),
          ("flowmeter/flowmeter_graph_tool.sr", "9600 8N1", [], "sr_flowmeter_graph_tool.log"),
          *((f"flowmeter/flowmeter_target_{rate}.sr", "9600 8N1", [], f"sr_flowmeter_target_{rate}.log")
            for rate in ("0liter_per_min", "15liter_per_min", "20liter_per_min")),
          ("brainchild_io_16do/brainchild-io-16do.sr", "19200 8E1", ["0", "1"], "sr_brainchild-io-16do.log")]


@pytest.mark.parametrize(("session", "line", "channels", "text"), MODBUS, ids=[m[0] for m in MODBUS])
def test_modbus_sessions_give_the_frames_of_their_text_conversions(cli: Cli, session: str, line: str,
                                                                    channels: list[str], text: str) -> None:
    options = [a for channel in channels for a in ("--channel", channel)]
    got = cli("analyze", str(SIGROK / "uart" / "modbus_rtu" / session), "--line", line, *options, "--format", "jsonl")
    want = cli("analyze", str(TEXT / text), "--format", "jsonl")
    assert got.code == 0 and want.code == 0, got.err + want.err
    frames = [json.loads(r) for r in got.out.splitlines() if '"kind":"frame"' in r]
    expected = [json.loads(r) for r in want.out.splitlines() if '"kind":"frame"' in r]
    said = [(f["hex"], f["role"], f["crc_ok"]) for f in frames]
    assert said == [(f["hex"], f["role"], f["crc_ok"]) for f in expected]
    assert len(frames) >= 18
    # The same times from the first frame on, to a sample (sigrok-cli's stamps are rounded).
    for f, e in zip(frames, expected, strict=True):
        assert abs((f["t_end_ns"] - frames[0]["t_end_ns"]) - (e["t_end_ns"] - expected[0]["t_end_ns"])) < 1000
    if channels:  # RX and TX on two probes: the master's requests on one, the answers on the other
        by_role = {(f["role"], f["channel"]) for f in frames}
        assert by_role == {("request", "1"), ("response", "0")}, by_role
        assert got.jsonl()[0]["channels"] == ["0", "1"]
    else:
        assert all("channel" not in f for f in frames)


def test_two_probe_sessions_convert_with_their_channels(cli: Cli, tmp_path: Path) -> None:
    session = SIGROK / "uart" / "modbus_rtu" / "brainchild_io_16do" / "brainchild-io-16do.sr"
    text, mcap, back = tmp_path / "io.log", tmp_path / "io.mcap", tmp_path / "back.log"
    probes = ["--channel", "0", "--channel", "1"]
    assert cli("convert", str(session), str(text), "--line", "19200 8E1", *probes).code == 0
    lines = text.read_text().splitlines()
    assert "# channels: 0 1" in lines and lines.count("# channel: 1") == 15
    assert cli("convert", str(text), str(mcap)).code == 0 and cli("convert", str(mcap), str(back)).code == 0
    assert back.read_text() == text.read_text()
    direct = cli("analyze", str(session), "--line", "19200 8E1", *probes, "--format", "jsonl").jsonl()[1:]
    for capture in (text, mcap):
        assert cli("analyze", str(capture), "--format", "jsonl").jsonl()[1:] == direct


def test_session_errors_are_one_line(cli: Cli, tmp_path: Path) -> None:
    flowmeter = SIGROK / "uart" / "modbus_rtu" / "flowmeter" / "flowmeter_target0_val0.sr"
    idle = cli("analyze", str(flowmeter), "--channel", "0")  # a probe on nothing
    assert idle.code == 10 and "give --line" in idle.err
    wrong = cli("analyze", str(flowmeter), "--line", "9600 8N1", "--channel", "MOSI")
    assert wrong.code == 2 and "--channel MOSI: no such probe" in wrong.err
    both = cli("analyze", str(SIGROK / "uart" / "modbus_rtu" / "brainchild_io_16do" / "brainchild-io-16do.sr"),
               "--line", "19200 8E1")
    assert both.code == 2 and "several probes change" in both.err
    truncated = tmp_path / "cut.sr"
    truncated.write_bytes(flowmeter.read_bytes()[:4000])
    cut = cli("analyze", str(truncated), "--line", "9600 8N1")
    assert cut.code in (6, 7) and str(truncated) in cut.err and len(cut.err.strip().splitlines()) == 1
    analog = tmp_path / "analog.sr"
    with zipfile.ZipFile(analog, "w") as session:
        session.writestr("version", "2")
        session.writestr("metadata", "[device 1]\nsamplerate=1 MHz\ntotal analog=2\nanalog1=A0\n")
    only_analog = cli("analyze", str(analog), "--line", "9600 8N1")
    assert only_analog.code == 5 and "analog channels only" in only_analog.err


def test_a_session_zipped_without_a_date_decodes_from_1980(cli: Cli, tmp_path: Path) -> None:
    """Zip writers that leave the date zero (month 0, found by the reader fuzz test): the frames
    as with the date, their times from 1980-01-01 UTC, and the user told; no traceback."""
    flowmeter = SIGROK / "uart" / "modbus_rtu" / "flowmeter" / "flowmeter_target0_val0.sr"
    undated = tmp_path / "undated.sr"
    with zipfile.ZipFile(flowmeter) as original, zipfile.ZipFile(undated, "w") as copy:
        for entry in original.infolist():
            info = zipfile.ZipInfo(entry.filename, (1980, 0, 0, 0, 0, 0) if entry.filename == "metadata"
                                   else entry.date_time)
            copy.writestr(info, original.read(entry.filename))
    got = cli("analyze", str(undated), "--line", "9600 8N1", "--format", "jsonl")
    want = cli("analyze", str(flowmeter), "--line", "9600 8N1", "--format", "jsonl")
    assert got.code == 0 and want.code == 0, got.err
    assert "no valid date for its metadata (1980-0-0): times count from 1980-01-01 00:00 UTC" in got.err
    frames = [r for r in got.jsonl() if r["kind"] == "frame"]
    expected = [r for r in want.jsonl() if r["kind"] == "frame"]
    assert [f["hex"] for f in frames] == [f["hex"] for f in expected] and frames
    assert frames[0]["t_ns"] // 10**9 - 315_532_800 < 3600  # an hour into 1980-01-01 at most
    shift = expected[0]["t_ns"] - frames[0]["t_ns"]
    assert all(e["t_ns"] - f["t_ns"] == shift for f, e in zip(frames, expected, strict=True))


def test_line_settings_told_by_the_samples(cli: Cli) -> None:
    """Without --line: the baud rate of the shortest pulses, the format that reads best."""
    for session, line, channels in [("flowmeter/flowmeter_target0_val0.sr", "9600 8N1", []),
                                    ("brainchild_io_16do/brainchild-io-16do.sr", "19200 8E1", ["0", "1"])]:
        path = str(SIGROK / "uart" / "modbus_rtu" / session)
        options = [a for channel in channels for a in ("--channel", channel)]
        told = cli("analyze", path, *options, "--format", "jsonl")
        given = cli("analyze", path, *options, "--line", line, "--format", "jsonl")
        assert told.code == 0 and f"read best as {line}" in told.err and "give --line to be sure" in told.err
        # The same records, but that the capture's notes say the settings were guessed.
        told_records, given_records = told.jsonl(), given.jsonl()
        assert told_records[1:] == given_records[1:]
        extra = [note for note in told_records[0]["notes"] if note not in given_records[0]["notes"]]
        assert len(extra) == 1 and extra[0].startswith(f"line settings guessed: the samples read best as {line}")


def test_sessions_are_sniffed_without_their_suffix(cli: Cli, tmp_path: Path) -> None:
    copy = tmp_path / "recording.bin"
    shutil.copy(SIGROK / "uart" / "modbus_rtu" / "flowmeter" / "flowmeter_graph_tool.sr", copy)
    assert cli("analyze", str(copy), "--line", "9600 8N1").code == 0
    assert ROOT.exists()


ANNOTATED = [test for test in TESTS if test[4].get("format", "hex") in ("hex", "ascii")
             and ANNOTATIONS.get((test[0], test[4].get("format", "hex")))]


@pytest.mark.parametrize(("name", "session", "channel", "python", "options"), ANNOTATED,
                         ids=[f"{t[0]}-{t[4].get('format', 'hex')}" for t in ANNOTATED])
def test_sigrok_cli_annotations_read_as_captures(cli: Cli, tmp_path: Path, *, name: str, session: str,
                                                 channel: int, python: str, options: dict[str, str]) -> None:
    """sigrok-cli's own annotation output of each recording (sigrok-test's .output), saved as
    .txt: the characters sigrok decoded, at its frames' ends to about a sample."""
    text = tmp_path / f"{name}.txt"
    shutil.copy(EXPECTED / ANNOTATIONS[(name, options.get("format", "hex"))], text)
    line = f"{options.get('baudrate', '115200')} {options.get('data_bits', '8')}" \
        f"{PARITY[options.get('parity', 'none')]}{int(float(options.get('stop_bits', '1')))}"
    result = cli("analyze", str(text), "--line", *line.split(), "--format", "jsonl")
    assert result.code == 0, result.err
    frames = [record for record in result.jsonl() if record["kind"] == "frame"]
    expected = expected_frames(python)
    assert bytes.fromhex("".join(str(f["hex"]) for f in frames)) == bytes(v & 0xFF for _, _, v, _ in expected)
    errors = sum(1 for *_, valid in expected if not valid)
    assert (errors > 0) == ("error annotations" in result.err)
    # Each invalid character is marked where sigrok's annotations say it failed.
    assert sum(len(f.get("uart_errors", [])) for f in frames) == errors


def test_nine_data_bits_decode_as_sigrok_expects(cli: Cli) -> None:
    """9 data bits: the decoder reads what sigrok expects; a capture of bytes cannot hold them,
    which --line says in one line."""
    session = SIGROK / "uart" / "counter" / "uart_count_19200_9n1.sr"
    with zipfile.ZipFile(session) as archive:
        parts = sorted((n for n in archive.namelist() if n.startswith("logic-1")),
                       key=lambda n: int(n.rsplit("-", 1)[1]))
        samples = np.concatenate([np.frombuffer(archive.read(n), "<u2") for n in parts])  # unitsize=2
        assert "samplerate=500 kHz" in archive.read("metadata").decode()
    decoder = UartDecoder(CharacterFormat(19200, 9), 500e3)
    characters = decoder.feed((samples & 1).astype(np.bool_))
    expected = expected_frames("uart_count_19200_9n1.python")
    assert characters.values.tolist() == [value for _, _, value, _ in expected]
    assert max(characters.values) > 0xFF
    assert np.all(np.abs(characters.end_samples - [end for _, end, _, _ in expected]) <= 1.5)
    refused = cli("analyze", str(session), "--line", "19200 9N1")
    assert refused.code == 2 and refused.err.count("\n") == 1 and "9 data bits" in refused.err


FRAME_ERRORS = SIGROK / "uart" / "errors" / "ampel64_4800_8n1_frame_errors.sr"


def test_framing_errors_reach_frames_stats_and_captures(cli: Cli, tmp_path: Path) -> None:
    """A real line with framing errors: each character with one marks its frame (flag, byte
    position), stats count them, and the text and MCAP captures carry them both ways."""
    reader = SigrokSessionReader(str(FRAME_ERRORS), ReaderOptions(line=LineSettings.parse("4800 8N1")))
    kinds = np.concatenate([batch.error_kinds() for batch in reader.batches()])
    reader.close()
    assert int(np.count_nonzero(kinds)) == 3
    analyzed = cli("analyze", str(FRAME_ERRORS), "--line", "4800 8N1", "--format", "jsonl")
    frames = [r for r in analyzed.jsonl() if r["kind"] == "frame"]
    marks = [(f["index"], m["at"], m["error"]) for f in frames for m in f.get("uart_errors", [])]
    assert len(marks) == 3 and {error for *_, error in marks} == {"framing"}
    assert all("uart_error" in f["flags"] for f in frames if f.get("uart_errors"))
    assert all("uart_error" not in f["flags"] for f in frames if not f.get("uart_errors"))
    # The marked bytes are the ones the session marks, wherever the framer put them.
    joined = bytes.fromhex("".join(f["hex"] for f in frames))
    offsets = np.cumsum([0] + [len(f["hex"]) // 2 for f in frames])
    assert sorted(int(offsets[i]) + at for i, at, _ in marks) == np.flatnonzero(kinds).tolist()
    assert len(joined) == len(kinds)
    summary = analyzed.jsonl()[-1]
    assert summary["uart_errors"] == {"framing": 3, "parity": 0} and summary["flags"]["uart_error"] >= 1
    table = cli("analyze", str(FRAME_ERRORS), "--line", "4800 8N1")
    assert "UART framing error at byte" in table.out
    stats = cli("stats", str(FRAME_ERRORS), "--line", "4800 8N1")
    assert re.search(r"uart_framing_errors\s+3", stats.out)
    text, mcap, back = tmp_path / "errors.log", tmp_path / "errors.mcap", tmp_path / "back.log"
    assert cli("convert", str(FRAME_ERRORS), str(text), "--line", "4800 8N1").code == 0
    assert text.read_text().count("# uart-errors: ") == 3
    assert cli("convert", str(text), str(mcap)).code == 0
    assert cli("convert", str(mcap), str(back)).code == 0
    assert back.read_text().splitlines()[3:] == text.read_text().splitlines()[3:]
    exported = tmp_path / "exported.mcap"
    assert cli("export", str(FRAME_ERRORS), "--line", "4800 8N1", "--mcap", str(exported)).code == 0
    for capture in (text, mcap, exported):
        again = cli("analyze", str(capture), "--format", "jsonl")
        assert [f.get("uart_errors") for f in again.jsonl() if f["kind"] == "frame"] == \
            [f.get("uart_errors") for f in frames]


GLITCHES = sorted((SIGROK / "uart" / "errors").glob("glitch_*.sr"))


@pytest.mark.parametrize("session", GLITCHES, ids=[g.stem for g in GLITCHES])
def test_a_glitch_recording_told_no_line_says_so_in_one_line(cli: Cli, session: Path) -> None:
    """Told no --line, these recordings of a few characters have too few pulses to measure a bit
    by: one error line (exit 10), never a numpy warning. glitch_0x4f_0x4b_0x0a's 21 pulses once
    put its shortest between a 1-sample spike and a 9-sample one, averaged no pulse and said
    "measure nan Bd" after two RuntimeWarnings."""
    said = cli("stats", str(session))
    assert said.code == 10, said.err
    assert said.err.startswith(f"error: {session}:session: ") and len(said.err.strip().splitlines()) == 1, said.err
    assert "give --line" in said.err and "nan" not in said.err


def test_pulses_that_agree_on_no_bit_measure_nothing() -> None:
    """The shortest pulses (the 2nd percentile) fall between a spike and a half bit, with no
    pulse near them: no rate, rather than the mean of none."""
    runs = [1, 9, *[17] * 13, 24, 34, 34, 34, 68, 68]
    level = np.repeat(np.arange(len(runs) + 1) % 2 == 0, [5, *runs])
    assert pulse_baud(level, 2_000_000.0) is None
    assert pulse_baud(np.repeat(np.arange(30) % 2 == 0, 17), 2_000_000.0) == pytest.approx(2_000_000 / 17)


@pytest.mark.parametrize("session", GLITCHES, ids=[g.stem for g in GLITCHES])
def test_glitches_on_a_real_line_leave_the_characters(cli: Cli, session: Path) -> None:
    """Recordings of characters (named in the file) with spikes on the line, at 115200 Bd: a
    spike before a start bit starts nothing; one at a bit's middle sample flips that bit, as
    in any UART that samples once per bit (two of the sixteen)."""
    result = cli("analyze", str(session), "--line", "115200 8N1", "--format", "jsonl")
    assert result.code == 0, result.err
    got = bytes.fromhex("".join(r["hex"] for r in result.jsonl() if r["kind"] == "frame"))
    named = bytes(int(part, 16) for part in re.findall(r"0x([0-9a-f]{2})", session.stem))
    assert len(got) == len(named)
    flipped = [bin(a ^ b).count("1") for a, b in zip(got, named, strict=True)]
    assert all(bits <= 1 for bits in flipped)
    assert (sum(flipped) == 1) == (session.stem in ("glitch_0x4f_2", "glitch_0x53"))


def test_a_probe_named_twice_is_refused_and_a_name_before_a_number_is_said(cli: Cli) -> None:
    """The Brainchild recording's probes are named "0" and "1" (numbers 1 and 2): ``--channel 1
    --channel 2`` named probe 2 twice (by its name, then by its number) and read the same line
    as RX and TX, which gave noise and exit 0; it is one error line naming both. ``--channel 1``
    alone is the probe named "1", which a warning says."""
    session = SIGROK / "uart" / "modbus_rtu" / "brainchild_io_16do" / "brainchild-io-16do.sr"
    twice = cli("analyze", str(session), "--line", "19200 8E1", "--channel", "1", "--channel", "2")
    assert twice.code == 2 and twice.out == "", twice.err
    assert twice.err.count("\n") == 1 and "--channel 1 and --channel 2 both name probe 2" in twice.err
    alone = cli("stats", str(session), "--line", "19200 8E1", "--channel", "1")
    assert alone.code == 0, alone.err
    assert "--channel 1 is probe 2, named '1'" in alone.err and "probe 1 is named '0'" in alone.err
    by_name = cli("stats", str(session), "--line", "19200 8E1", "--channel", "0", "--channel", "1")
    assert by_name.code == 0 and "--channel" not in by_name.err, by_name.err


@pytest.mark.parametrize("output", sorted((SHARED_REAL / "sigrok-test" / "modbus").glob("*.output")),
                         ids=lambda path: path.name)
def test_the_modbus_decoder_s_annotations_are_told_apart_from_the_uart_s(cli: Cli, tmp_path: Path,
                                                                        output: Path) -> None:
    """sigrok's own Modbus decoder output (sigrok-test's expected decodes) given as input read as
    UART characters until its first data annotation, '0x8200 / 33280' is not a byte (exit 7). It
    is one line naming the decoder and the command that exports the UART's annotations; beside
    the UART's own lines, it is left out with a warning."""
    said = cli("analyze", str(output), "--input-format", "sigrok-cli", "--line", "9600 8N1")
    assert said.code == 7 and said.out == "", said.err
    assert said.err.count("\n") == 1 and "the annotations of sigrok's 'modbus' decoder" in said.err
    assert "-A uart --protocol-decoder-samplenum --protocol-decoder-ann-class" in said.err
    uart = EXPECTED / "hello_world_8n1_115200.output"
    stacked = tmp_path / "stacked.txt"
    stacked.write_text(uart.read_text() + output.read_text())
    alone = cli("analyze", str(uart), "--input-format", "sigrok-cli", "--line", "115200 8N1", "--format", "jsonl")
    both = cli("analyze", str(stacked), "--input-format", "sigrok-cli", "--line", "115200 8N1", "--format", "jsonl")
    assert both.code == 0 and "'modbus' decoder left out" in both.err
    assert both.jsonl()[1:] == alone.jsonl()[1:]


def _held_low_at_start(session: Path, copy: Path, probe_bit: int, samples: int) -> None:
    """``session`` with its probe ``probe_bit`` (0-based) held low for its first ``samples``
    samples: a line low when the analyzer started (a break, a driver's enable, a character under
    way), the rest of the real recording as it is."""
    with zipfile.ZipFile(session) as source, zipfile.ZipFile(copy, "w", zipfile.ZIP_DEFLATED) as target:
        for item in source.infolist():
            data = source.read(item.filename)
            if item.filename == "logic-1-1":
                words = np.frombuffer(data, np.uint8).copy()
                words[:samples] &= ~np.uint8(1 << probe_bit)
                data = words.tobytes()
            target.writestr(item, data)


def test_a_line_low_where_the_recording_starts_reads_as_its_characters_say(cli: Cli, tmp_path: Path) -> None:
    """The real flow-meter recording, its bus probe held low for its first 2 ms: read inverted by
    the level of the first sample, the clean bus became noise and framing errors. Its characters
    decide now: the frames are the recording's own, a warning says the line starts low yet reads
    as it is, and ``--invert`` still forces the other way."""
    session = SIGROK / "uart" / "modbus_rtu" / "flowmeter" / "flowmeter_graph_tool.sr"
    low = tmp_path / "starts-low.sr"
    _held_low_at_start(session, low, probe_bit=2, samples=8_000)  # probe3 = RXTX, 4 MHz
    line = ("--line", "9600 8N1")
    original = [f for f in cli("analyze", str(session), *line, "--format", "jsonl").jsonl() if f["kind"] == "frame"]
    read = cli("analyze", str(low), *line, "--format", "jsonl")
    assert read.code == 0, read.err
    frames = [f for f in read.jsonl() if f["kind"] == "frame"]
    assert [f["hex"] for f in frames if f["role"] != "noise"] == [f["hex"] for f in original if f["role"] != "noise"]
    assert "probe RXTX is low where the recording starts, yet reads as it is" in read.err
    as_is = json.loads(cli("stats", str(low), *line, "--format", "json").out)
    forced = cli("stats", str(low), *line, "--invert", "--format", "json")
    assert forced.code == 0 and "reads it inverted" not in forced.err
    assert json.loads(forced.out)["noise_bytes"] > 10 * max(as_is["noise_bytes"], 1)


@pytest.mark.parametrize("session", sorted((SIGROK / "uart" / "hello_world").glob("*/hello_world_8*.sr")),
                         ids=lambda path: path.stem)
def test_the_line_s_settings_are_read_from_every_real_recording(cli: Cli, session: Path) -> None:
    """sigrok's hello-world recordings at every rate from 1 200 to 921 600 Bd, told no --line:
    460 800 Bd read as 500 000 8O1 and 921 600 as 1 000 000 (one-bit pulses a few samples long,
    measured by the shortest alone), 115 200 Bd at 1 MHz was refused ("too few pulses"). Each
    reads as its own rate and format now, and a setting that reads as well is named."""
    rate, spelled = session.stem.split("_")[-1], session.stem.split("_")[-2].upper()
    said = cli("stats", str(session))
    assert said.code == 0, said.err
    found = re.search(r"read best as (\d+) (\w+) \((\d+) of (\d+) characters with an error", said.err)
    assert found is not None, said.err
    assert (found[1], found[2]) == (rate, spelled) and found[3] == "0"
    if spelled == "8N1":
        assert f"; {rate} 8N2 read as well" in said.err

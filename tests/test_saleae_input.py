"""Saleae Logic Async Serial exports (CSV) read as captures: the Logic 2 data table and the Logic
1.x serial export of the shipped sample's characters give the sample's frames, flags and all."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from sniffer.io.registry import open_reader
from tests.conftest import SAMPLE_LOG, CliResult
from tests.real_recordings import REAL

Cli = Callable[..., CliResult]
LINE = ["--line", "19200", "8E1"]
CHAR_S = 11 / 19200


def characters() -> list[tuple[float, int]]:
    """(end in seconds from the first chunk's second, value) of every character of the sample
    (a chunk's bytes ending a character time apart)."""
    reader = open_reader(str(SAMPLE_LOG))
    out = []
    for batch in reader.batches():
        start = 0
        for end, stop in zip(batch.t_end_ns.tolist(), batch.ends.tolist(), strict=True):
            chunk = batch.data[start:stop]
            out += [((end - 1_700_000_000 * 10**9) / 1e9 - (len(chunk) - 1 - k) * CHAR_S, value)
                    for k, value in enumerate(chunk)]
            start = stop
    reader.close()
    return out


def logic2(path: Path, rows: list[str] | None = None) -> Path:
    body = rows if rows is not None else [f'"Async Serial","data",{end - CHAR_S:.9f},{CHAR_S:.9f},0x{value:02X}'
                                          for end, value in characters()]
    path.write_text("\n".join(["name,type,start_time,duration,data", *body]) + "\n")
    return path


def logic1(path: Path) -> Path:
    rows = [f"{end - CHAR_S:.9f},0x{value:02X},," for end, value in characters()]
    path.write_text("\n".join(["Time [s],Value,Parity Error,Framing Error", *rows]) + "\n")
    return path


def said(cli: Cli, *argv: str) -> list[tuple[object, ...]]:
    result = cli("analyze", *argv, "--format", "jsonl")
    assert result.code == 0, result.err
    return [(r["hex"], r["role"], tuple(r["flags"]), r["crc_ok"]) for r in result.jsonl() if r["kind"] == "frame"]


@pytest.mark.parametrize("layout", [logic2, logic1], ids=["logic2", "logic1"])
def test_exports_give_the_sample_frames(cli: Cli, tmp_path: Path, layout: Callable[[Path], Path]) -> None:
    csv = layout(tmp_path / "export.csv")
    got = said(cli, str(csv), *LINE)
    assert got == said(cli, str(SAMPLE_LOG))
    assert any("gap_1_5" in flags for _, _, flags, _ in got)  # exact timing: gaps inside frames show
    capture = cli("analyze", str(csv), *LINE, "--format", "jsonl").jsonl()[0]
    assert capture["timing"] == "exact" and "no date" in capture["notes"][0]


def test_ascii_values_errors_and_other_rows(cli: Cli, tmp_path: Path) -> None:
    csv = logic2(tmp_path / "ascii.csv", ['"Async Serial","data",0.001,0.0005,H',
                                          '"Async Serial","data",0.0015,0.0005,\\r',
                                          '"Async Serial","framing error",0.002,0.0005,',
                                          '"Async Serial","data",0.0025,0.0005,0x41'])
    csv.write_text(csv.read_text().replace("start_time,duration,data", "start_time,duration,data,error")
                   .replace(",0x41", ",0x41,framing"))
    result = cli("analyze", str(csv), *LINE, "--format", "jsonl")
    assert result.code == 0, result.err
    frames = [r for r in result.jsonl() if r["kind"] == "frame"]
    assert "".join(f["hex"] for f in frames) == "480d41"
    assert "1 characters with a framing or parity error" in result.err
    marked = [(f["hex"], f["uart_errors"]) for f in frames if "uart_errors" in f]
    assert marked and marked[-1][1][-1] == {"at": len(marked[-1][0]) // 2 - 1, "error": "framing"}


def test_logic1_error_columns_mark_their_characters(cli: Cli, tmp_path: Path) -> None:
    csv = tmp_path / "logic1.csv"
    csv.write_text("Time [s],Value,Parity Error,Framing Error\n0.001,0x01,,\n0.0016,0x03,1,\n"
                   "0.0022,0x00,,1\n0.0028,0x01,1,1\n")
    frames = [r for r in cli("analyze", str(csv), *LINE, "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    marks = [m["error"] for f in frames for m in f.get("uart_errors", [])]
    assert marks == ["parity", "framing", "framing+parity"]


@pytest.mark.parametrize(("rows", "code", "words"), [
    (['"Async Serial","data",0.001,0.0005'], 7, "4 columns where the header has 5"),
    (['"Async Serial","data",0.001,0.0005,0x1FF'], 7, "'0x1FF' is not a byte"),
    (['"Async Serial","data",soon,0.0005,0x01'], 7, "'soon' is not a time"),
    (['"Async Serial","data",0.002,0.0005,0x01', '"Async Serial","data",0.001,0.0005,0x02'], 8, "goes back in time"),
])
def test_bad_rows_are_one_line(cli: Cli, tmp_path: Path, rows: list[str], code: int, words: str) -> None:
    csv = logic2(tmp_path / "bad.csv", rows)
    result = cli("analyze", str(csv), *LINE)
    assert result.code == code and words in result.err and f"{csv}:line" in result.err


def test_other_csv_and_no_line(cli: Cli, tmp_path: Path) -> None:
    other = tmp_path / "other.csv"
    other.write_text("a,b,c\n1,2,3\n")
    assert cli("analyze", str(other), *LINE).code in (5, 6)
    assert cli("analyze", str(logic1(tmp_path / "l1.csv"))).code == 10


def digital_export(session: Path, path: Path, probes: list[int], names: list[str]) -> Path:
    """A real sigrok session's samples as Saleae's raw digital export: a row per change."""
    import zipfile

    import numpy as np

    with zipfile.ZipFile(session) as archive:
        chunks = sorted((n for n in archive.namelist() if n.startswith("logic-1-")), key=lambda n: int(n[8:]))
        unit = "<u2" if "unitsize=2" in archive.read("metadata").decode() else np.uint8
        words = np.concatenate([np.frombuffer(archive.read(n), unit) for n in chunks])
    rate = 4e6 if "flowmeter" in session.name else 1e6
    levels = np.stack([(words >> (probe - 1)) & 1 for probe in probes], axis=1)
    changes = np.concatenate([[0], np.flatnonzero(np.any(levels[1:] != levels[:-1], axis=1)) + 1])
    rows = [f"{index / rate:.9f}," + ",".join(map(str, levels[index])) for index in changes.tolist()]
    path.write_text("\n".join(["Time [s]," + ",".join(names), *rows]) + "\n")
    return path


@pytest.mark.skipif(not (REAL / "sigrok").exists(), reason="../shared/real is not beside the checkout")
def test_raw_digital_export_decodes_as_the_session(cli: Cli, tmp_path: Path) -> None:
    session = REAL / "sigrok" / "uart" / "modbus_rtu" / "flowmeter" / "flowmeter_target0_val0.sr"
    csv = digital_export(session, tmp_path / "digital.csv", [2, 3], ["Channel 1", "RXTX"])
    from_csv = said(cli, str(csv), "--line", "9600", "8N1", "--channel", "RXTX")
    assert from_csv == said(cli, str(session), "--line", "9600", "8N1") and len(from_csv) == 74
    # The only channel that changes is found without --channel; a wrong one is one line.
    alone = digital_export(session, tmp_path / "one.csv", [3], ["Channel 0"])
    assert said(cli, str(alone), "--line", "9600", "8N1") == from_csv
    wrong = cli("analyze", str(csv), "--line", "9600", "8N1", "--channel", "Channel 7")
    assert wrong.code == 2 and "no such channel" in wrong.err
    csv.write_text(csv.read_text().replace("\n0.", "\nlater,", 1))
    bad = cli("analyze", str(csv), "--line", "9600", "8N1", "--channel", "RXTX")
    assert bad.code == 7 and f"{csv}:line 2" in bad.err


@pytest.mark.skipif(not (REAL / "sigrok").exists(), reason="../shared/real is not beside the checkout")
def test_raw_digital_export_with_rx_and_tx(cli: Cli, tmp_path: Path) -> None:
    """Two channels (a real two-probe session's RX and TX): merged in time order, each frame on
    its channel, the same frames as the session read with both probes."""
    session = REAL / "sigrok" / "uart" / "modbus_rtu" / "brainchild_io_16do" / "brainchild-io-16do.sr"
    csv = digital_export(session, tmp_path / "two.csv", [1, 2], ["RX", "TX"])
    line = ["--line", "19200", "8E1"]
    from_csv = cli("analyze", str(csv), *line, "--channel", "RX", "--channel", "TX", "--format", "jsonl").jsonl()
    from_session = cli("analyze", str(session), *line, "--channel", "0", "--channel", "1", "--format",
                       "jsonl").jsonl()
    frames = [(r["hex"], r["role"], r["channel"]) for r in from_csv if r["kind"] == "frame"]
    assert frames == [(r["hex"], r["role"], {"0": "RX", "1": "TX"}[r["channel"]]) for r in from_session
                      if r["kind"] == "frame"]
    assert len(frames) == 30 and from_csv[0]["channels"] == ["RX", "TX"]
    three = cli("analyze", str(csv), *line, "--channel", "RX", "--channel", "TX", "--channel", "1")
    assert three.code == 2 and "a bus has one line, or two" in three.err

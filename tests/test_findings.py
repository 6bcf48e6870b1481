"""Findings (:mod:`decoders.findings`): each rule on a generated capture that shows its symptom and
on one that does not; none on the clean samples and the real recordings."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from benchmarks.wire_synthesis import Transmission, exact_chunks
from decoders.crc import crc_bytes
from decoders.findings import TWO_MASTERS_OVERLAPS
from decoders.line import LineSettings
from tests.real_recordings import RECORDINGS, TEXT, available

LINE = LineSettings.parse("19200 8E1")
MS = 1_000_000
T0 = 1_700_000_000_000_000_000
CAPTURES = Path(__file__).resolve().parents[1] / "captures"


def rtu(hex_text: str) -> bytes:
    body = bytes.fromhex(hex_text)
    return body + crc_bytes(body)


def read(slave: int, address: int = 0, count: int = 2) -> bytes:
    return rtu(f"{slave:02x}03{address:04x}{count:04x}")


def answer(slave: int, count: int = 2) -> bytes:
    return rtu(f"{slave:02x}03{2 * count:02x}" + "0102" * count)


def refusal(slave: int, function: int, code: int) -> bytes:
    return rtu(f"{slave:02x}{function | 0x80:02x}{code:02x}")


def write(path: Path, transmissions: Iterator[Transmission] | list[Transmission]) -> Path:
    lines = ["# rtu-capture v1", "# line: 19200 8E1", "# timing: exact"]
    lines += [f"{chunk.t_end_ns // 10**9}.{chunk.t_end_ns % 10**9:09d} {chunk.data.hex(' ')}"
              for chunk in exact_chunks(transmissions, LINE, T0)]
    path.write_text("\n".join(lines) + "\n")
    return path


def poll(slaves: list[int], rounds: int, *, period_ms: float = 100, answers: Callable[[int, int], bool] | None = None,
         latency_ms: float = 5, count: int = 2) -> Iterator[Transmission]:
    """A master reading ``count`` registers of each slave in turn, ``period_ms`` after the last
    answer; ``answers(round, slave)`` says who answers."""
    for turn in range(rounds):
        for slave in slaves:
            yield Transmission(read(slave, 0, count), int(period_ms * MS))
            if answers is None or answers(turn, slave):
                yield Transmission(answer(slave, count), int(latency_ms * MS))


def findings(cli: Callable[..., Any], capture: Path) -> list[dict[str, Any]]:
    result = cli("stats", str(capture), "--format", "json")
    assert result.code == 0, result.err
    found: list[dict[str, Any]] = json.loads(result.out)["findings"]
    return found


def rules(found: list[dict[str, Any]]) -> list[str]:
    return [finding["rule"] for finding in found]


def test_a_clean_bus_has_no_finding(tmp_path: Path, cli: Callable[..., Any]) -> None:
    assert findings(cli, write(tmp_path / "clean.log", poll([1, 2, 3], 30))) == []


SESSIONS = TEXT.parent / "sigrok" / "uart"
#: Logic analyzers' sessions of real lines that read without options: Modbus buses, and UART text
#: that is not Modbus (no bus in trouble: "hello world" filling the line is no busy bus).
CLEAN_SESSIONS = sorted([*SESSIONS.glob("modbus_rtu/flowmeter/*.sr"), *SESSIONS.glob("hello_world/*/*.sr")]) \
    if SESSIONS.is_dir() else []


@pytest.mark.parametrize("capture", [*sorted(CAPTURES.glob("xbt-hmi.*")), *sorted(CAPTURES.glob("nord-uss.*")),
                                     *([TEXT / name for name in RECORDINGS] if available() else []),
                                     *CLEAN_SESSIONS], ids=lambda path: path.name)
def test_clean_samples_and_real_recordings_have_no_finding(cli: Callable[..., Any], capture: Path) -> None:
    assert findings(cli, capture) == []


@pytest.mark.parametrize(("capture", "profile"), [("xbt-hmi.log", "xbt"), ("nord-uss.log", "nord-sk")])
def test_clean_samples_decoded_by_their_profile_have_no_finding(cli: Callable[..., Any], capture: str,
                                                                profile: str) -> None:
    """The rules that read decoded values (a drive in fault, a parameter read back otherwise) run
    where frames are decoded: the report. The clean samples, named by their profile, give none."""
    result = cli("report", str(CAPTURES / capture), "--profile", profile, "--format", "md")
    assert result.code == 0, result.err
    assert "## Findings\n\nNothing wrong found." in result.out


@pytest.mark.skipif(not SESSIONS.is_dir(), reason="the real recordings are not here")
def test_the_report_says_guessed_line_settings_as_guessed(cli: Callable[..., Any]) -> None:
    """A logic analyzer's session read without --line: the settings the samples read best as,
    said as guessed in the report's provenance; with --line, as given."""
    session = next(SESSIONS.rglob("flowmeter_graph_tool.sr"))
    guessed = cli("report", str(session), "--format", "md").out
    assert "| line | 9600 8N1 (guessed, not given: the samples read best as 9600 8N1 (" in guessed
    given = cli("report", str(session), "--format", "md", "--line", "9600 8N1").out
    assert "| line | 9600 8N1 |" in given and "guessed" not in given


def test_a_slave_that_never_answers(tmp_path: Path, cli: Callable[..., Any]) -> None:
    found = findings(cli, write(tmp_path / "silent.log", poll([1, 9], 12, answers=lambda _, slave: slave != 9)))
    assert rules(found) == ["silent_slave"]
    (silent,) = found
    assert silent["severity"] == "error" and silent["slave"] == 9 and silent["evidence"]["answers"] == 0
    assert silent["sentence"].startswith("Slave 9 never answered") and len(silent["frames"]) == 5
    assert "the slave address set on the device" in silent["causes"]


def test_a_slave_that_answers_rarely(tmp_path: Path, cli: Callable[..., Any]) -> None:
    rare = poll([1, 5], 12, answers=lambda turn, slave: slave != 5 or turn % 4 == 0)
    (finding,) = findings(cli, write(tmp_path / "rare.log", rare))
    assert finding["rule"] == "rare_answers" and finding["slave"] == 5 and "only 3 of 12" in finding["sentence"]
    often = poll([1, 5], 12, answers=lambda turn, slave: slave != 5 or turn % 4 != 0)  # 9 of 12: no finding
    assert findings(cli, write(tmp_path / "often.log", often)) == []


def test_requests_a_device_refuses(tmp_path: Path, cli: Callable[..., Any]) -> None:
    def traffic() -> Iterator[Transmission]:
        for _ in range(5):
            yield from poll([1], 1)
            yield Transmission(read(1, 8400, 4), 100 * MS)
            yield Transmission(refusal(1, 3, 2), 5 * MS)

    (finding,) = findings(cli, write(tmp_path / "refused.log", traffic()))
    assert finding["rule"] == "refused_requests" and finding["evidence"]["count"] == 5
    assert "at addresses 8400..8403: exception 02 (Illegal Data Address), 5×" in finding["sentence"]
    assert "while it answers 5 other requests" in finding["sentence"]


def test_answers_after_the_master_moved_on(tmp_path: Path, cli: Callable[..., Any]) -> None:
    """Slave 4 answers 80 ms after the request; the master waits 50 ms, then asks slave 1."""
    def traffic(late: bool) -> Iterator[Transmission]:
        for _ in range(6):
            yield Transmission(read(4), 100 * MS)
            if not late:
                yield Transmission(answer(4), 5 * MS)
            yield Transmission(read(1), 50 * MS)
            yield Transmission(answer(1), 5 * MS)
            if late:
                yield Transmission(answer(4), 20 * MS)

    found = findings(cli, write(tmp_path / "late.log", traffic(True)))
    late = next(finding for finding in found if finding["rule"] == "late_answers")
    assert late["slave"] == 4 and late["evidence"]["late_answers"] >= 2
    assert late["evidence"]["slave_latency_ms"] > late["evidence"]["master_wait_ms"] > 45
    assert "the master's response timeout is shorter than the slave's answer time: raise it" in late["causes"]
    assert findings(cli, write(tmp_path / "in-time.log", traffic(False))) == []


def test_crc_errors_on_one_slave_s_answers_in_a_burst(tmp_path: Path, cli: Callable[..., Any]) -> None:
    def traffic() -> Iterator[Transmission]:
        for turn in range(30):
            for slave in (1, 2, 7):
                yield Transmission(read(slave), 30 * MS)
                good = answer(slave)
                damaged = slave == 7 and 10 <= turn < 15
                yield Transmission(good[:5] + bytes([good[5] ^ 0x10]) + good[6:] if damaged else good, 5 * MS)

    (finding,) = findings(cli, write(tmp_path / "crc.log", traffic()))
    assert finding["rule"] == "crc_errors" and finding["severity"] == "warning" and finding["slave"] == 7
    sentence = finding["sentence"]
    assert "5 of them from or to slave 7" in sentence and "5 on the slaves' answers" in sentence
    assert "5 in bursts" in sentence  # and the bits the line flipped, against the next good answer:
    assert sentence.endswith("is the good retry of damaged #89: byte 5 11, good 01 (one bit, 0x10).")


def test_stray_bytes_before_a_slave_s_answers(tmp_path: Path, cli: Callable[..., Any]) -> None:
    def traffic(glitch: bool) -> Iterator[Transmission]:
        for _ in range(10):
            yield Transmission(read(1), 100 * MS)
            yield Transmission(answer(1), 5 * MS)
            yield Transmission(read(3), 100 * MS)
            if glitch:  # nearer the answer than the request (within two t3.5 of it)
                yield Transmission(b"\x00", 5 * MS)
            yield Transmission(answer(3), int(2.5 * MS) if glitch else 5 * MS)

    found = findings(cli, write(tmp_path / "glitch.log", traffic(True)))
    glitch = next(finding for finding in found if finding["rule"] == "glitch_bytes")
    assert glitch["sentence"] == "A stray 0x00 comes before the frames of slave 3 (10×)." and glitch["slave"] == 3
    assert findings(cli, write(tmp_path / "quiet.log", traffic(False))) == []


@pytest.mark.parametrize("rule", ["gap_1_5", "short_idle"])
def test_silences_one_transmitter_gets_wrong(tmp_path: Path, cli: Callable[..., Any], rule: str) -> None:
    def traffic() -> Iterator[Transmission]:
        for turn in range(10):
            yield Transmission(read(1), 100 * MS)
            yield Transmission(answer(1), 5 * MS)
            yield Transmission(read(2), 100 * MS)
            odd = turn % 3 == 0
            gaps = {4: int(1.2 * MS)} if odd and rule == "gap_1_5" else {}
            idle = int(1.2 * MS) if odd and rule == "short_idle" else 5 * MS
            yield Transmission(answer(2), idle, gaps)

    found = findings(cli, write(tmp_path / f"{rule}.log", traffic()))
    (finding,) = [finding for finding in found if finding["rule"] == rule]
    assert finding["slave"] == 2 and finding["sentence"].startswith("Slave 2 sends")
    assert finding["evidence"]["count"] == 4 and finding["evidence"]["frames_sent"] == 10


def test_polling_that_stalls_or_stops(tmp_path: Path, cli: Callable[..., Any]) -> None:
    def stalled() -> Iterator[Transmission]:
        yield from poll([1], 20)
        yield Transmission(read(1), 3000 * MS)
        yield Transmission(answer(1), 5 * MS)
        yield from poll([1], 20)

    (finding,) = findings(cli, write(tmp_path / "stall.log", stalled()))
    assert finding["rule"] == "polling_stalls" and finding["sentence"] == \
        "Polling stalled on 1 slave/function pair: slave 1 FC 3: usually every 115 ms, once not for 3015 ms."

    def stopped() -> Iterator[Transmission]:
        yield from poll([1, 2], 20)
        yield from poll([1], 40)

    (finding,) = findings(cli, write(tmp_path / "stop.log", stopped()))
    assert finding["rule"] == "polling_stops" and finding["slave"] == 2
    assert finding["sentence"].startswith("Polling stopped before the capture's end on 1 slave/function pair: slave 2 ")


def test_a_busy_bus(tmp_path: Path, cli: Callable[..., Any]) -> None:
    busy = poll([1, 2], 100, period_ms=2.1, latency_ms=2.1, count=10)
    (finding,) = findings(cli, write(tmp_path / "busy.log", busy))
    assert finding["rule"] == "busy_bus" and finding["evidence"]["bus_load"] >= 0.7
    assert findings(cli, write(tmp_path / "calm.log", poll([1, 2], 100, period_ms=20))) == []


def test_broadcast_writes_nobody_confirms(tmp_path: Path, cli: Callable[..., Any]) -> None:
    def traffic() -> Iterator[Transmission]:
        yield from poll([1], 5)
        for value in range(3):
            yield Transmission(rtu(f"0006001000{value:02x}"), 100 * MS)

    (finding,) = findings(cli, write(tmp_path / "broadcast.log", traffic()))
    assert finding["rule"] == "unconfirmed_broadcasts" and finding["severity"] == "info"
    assert finding["sentence"].startswith("3 broadcast writes")


def test_findings_follow_the_statistics_in_the_text(cli: Callable[..., Any]) -> None:
    """After the tables: a block, most severe first, frames by index and what to check."""
    out = cli("stats", str(CAPTURES / "atv71-plc-poll.log"), "--width", "80").out
    block = out[out.index("findings ("):]
    assert block.splitlines()[1].startswith("error    Slave 3 never answered: 5 requests, no answer.")
    assert all(len(line) <= 80 for line in block.splitlines())
    piped = cli("stats", str(CAPTURES / "atv71-plc-poll.log")).out
    assert "\nwarning  1 frame with a CRC error (1.92% of the frames); frame #27 is the good retry of damaged " \
           "#25: byte 6 50, good 58 (one bit, 0x08). (frames #25)\n" in piped


def test_a_command_the_device_refuses(tmp_path: Path, cli: Callable[..., Any]) -> None:
    """A write refused with any exception (03: a value out of range; 04: the device's state) is a
    refused request; a read refused with 03 or 04 is not said as one."""
    def traffic() -> Iterator[Transmission]:
        for _ in range(3):
            yield from poll([2], 1)
            yield Transmission(rtu("02062135000f"), 100 * MS)  # CMD = 16#000F
            yield Transmission(refusal(2, 6, 4), 5 * MS)
            yield Transmission(read(2, 100), 100 * MS)
            yield Transmission(refusal(2, 3, 4), 5 * MS)

    (finding,) = findings(cli, write(tmp_path / "command.log", traffic()))
    assert finding["rule"] == "refused_requests" and finding["evidence"]["exception"] == 4
    assert finding["sentence"].startswith("Slave 2 refuses FC 6 (Write Single Register) at address 8501: exception 04")
    assert any("exception 03, 04" in cause for cause in finding["causes"])


def test_a_drive_in_fault(tmp_path: Path, cli: Callable[..., Any]) -> None:
    """ETA in the state the profile names "fault": an error in the report (HTML and Markdown) and
    the live view, which decode the frames; not ETA in operation."""
    def traffic(raw: int) -> Iterator[Transmission]:
        for _ in range(3):
            yield Transmission(read(2, 3201, 1), 100 * MS)
            yield Transmission(rtu(f"020302{raw:04x}"), 5 * MS)

    faulty = write(tmp_path / "fault.log", traffic(0x0008))
    report = cli("report", str(faulty), "--profile", "atv71", "--format", "md")
    assert report.code == 0, report.err
    assert "- **error** Slave 2 reports ETA = 16\\#0008: fault (3×). (frames #1, #3, #5)" in report.out
    running = write(tmp_path / "running.log", traffic(0x0637))
    assert "## Findings\n\nNothing wrong found." in cli("report", str(running), "--profile", "atv71", "--format",
                                                          "md").out


def test_two_masters_on_one_bus(tmp_path: Path, cli: Callable[..., Any]) -> None:
    """A second master asks slave 2 whenever its cycle says, in the first master's turn with slave
    1: requests after waits from 2.2 to 12.2 ms, answers after both. One master whose timeout (50 ms)
    is shorter than the slave's answer time is said as late answers, not as two masters."""
    def traffic() -> Iterator[Transmission]:
        for turn in range(12):
            yield Transmission(read(1), 100 * MS)
            yield Transmission(read(2), int((2.2 + turn * 5 % 11) * MS))  # the second master's request
            yield Transmission(answer(1), 3 * MS)
            yield Transmission(answer(2), 4 * MS)

    found = findings(cli, write(tmp_path / "two.log", traffic()))
    assert rules(found) == ["two_masters"]
    (two,) = found
    assert two["evidence"]["overlaps"] >= TWO_MASTERS_OVERLAPS and two["evidence"]["shortest_wait_ms"] < 3
    assert two["sentence"].startswith("Two masters seem to share the bus: ")
    assert any("a second master on the line" in cause for cause in two["causes"])

    def one_master_short_timeout() -> Iterator[Transmission]:
        for _ in range(12):
            yield Transmission(read(4), 100 * MS)
            yield Transmission(read(1), 50 * MS)
            yield Transmission(answer(1), 5 * MS)
            yield Transmission(answer(4), 20 * MS)

    assert rules(findings(cli, write(tmp_path / "one.log", one_master_short_timeout()))) == ["late_answers"]


def test_a_parameter_written_and_read_back_otherwise(tmp_path: Path, cli: Callable[..., Any]) -> None:
    """HSP (3104, 0.1 Hz) written 16#0258 (60 Hz), confirmed, then read back 16#01F4: the drive
    clamped it. A read on the way that differs counts only while it stays the last."""
    def traffic(read_back: list[int]) -> Iterator[Transmission]:
        yield from poll([2], 2)
        yield Transmission(rtu("02060c200258"), 100 * MS)  # HSP = 16#0258
        yield Transmission(rtu("02060c200258"), 5 * MS)
        for raw in read_back:
            yield Transmission(read(2, 3104, 1), 100 * MS)
            yield Transmission(rtu(f"020302{raw:04x}"), 5 * MS)

    def report(name: str, read_back: list[int]) -> str:
        result = cli("report", str(write(tmp_path / name, traffic(read_back))), "--profile", "atv71", "--format", "md")
        assert result.code == 0, result.err
        return str(result.out)

    clamped = report("clamped.log", [0x0258, 0x01F4])
    assert ("- **warning** Slave 2's HSP was written 16\\#0258 (60.0 Hz) and reads back 16\\#01F4 (50.0 Hz). "
            "(frames #4, #9)") in clamped
    assert "read back" not in report("taken.log", [0x01F4, 0x0258])  # on its way, then as written

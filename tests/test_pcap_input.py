"""pcap and pcapng files of serial lines read as captures: rtusniff's own export read back, the
same converted to pcapng by Wireshark's editcap, RTAC serial records, and bad files."""

from __future__ import annotations

import shutil
import struct
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.conftest import SAMPLE_LOG, CliResult

Cli = Callable[..., CliResult]
LINE = ["--line", "19200", "8E1"]


def frames(cli: Cli, *argv: str) -> list[str]:
    result = cli("analyze", *argv, "--format", "jsonl")
    assert result.code == 0, result.err
    return [record["hex"] for record in result.jsonl() if record["kind"] == "frame"]


@pytest.fixture
def exported(cli: Cli, tmp_path: Path) -> Path:
    pcap = tmp_path / "sample.pcap"
    assert cli("export", str(SAMPLE_LOG), "--pcap", str(pcap), "-q").code == 0
    return pcap


def test_own_export_reads_back_to_the_same_frames(cli: Cli, exported: Path) -> None:
    assert frames(cli, str(exported), *LINE) == frames(cli, str(SAMPLE_LOG))
    header = cli("analyze", str(exported), *LINE, "--format", "jsonl").jsonl()[0]
    assert header["timing"] == "host" and "a chunk per record" in header["notes"][0]


@pytest.mark.skipif(shutil.which("editcap") is None, reason="Wireshark's editcap is not installed")
def test_pcapng_written_by_wireshark_tools(cli: Cli, exported: Path, tmp_path: Path) -> None:
    pcapng = tmp_path / "sample.pcapng"
    subprocess.run(["editcap", "-F", "pcapng", str(exported), str(pcapng)], check=True)
    assert pcapng.read_bytes()[:4] == b"\x0a\x0d\x0d\x0a"
    assert frames(cli, str(pcapng), *LINE) == frames(cli, str(exported), *LINE)
    renamed = tmp_path / "no-suffix.bin"
    shutil.copy(pcapng, renamed)  # recognised by its first bytes
    assert frames(cli, str(renamed), *LINE) == frames(cli, str(exported), *LINE)


def rtac_pcap(path: Path, records: list[tuple[int, bytes]], link_type: int = 250) -> Path:
    out = [struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, link_type)]
    for t_us, data in records:
        header = struct.pack(">IIBBH", t_us // 1_000_000, t_us % 1_000_000, 0x01, 0, 0)
        payload = header + data if link_type == 250 else data
        out.append(struct.pack("<IIII", t_us // 1_000_000, t_us % 1_000_000, len(payload), len(payload)) + payload)
    path.write_bytes(b"".join(out))
    return path


def test_rtac_serial_records(cli: Cli, tmp_path: Path) -> None:
    request, answer = bytes.fromhex("02030c1e0004276c"), bytes.fromhex("0203080028025801f4000052b0")
    t0 = 1_700_000_000_000_000
    pcap = rtac_pcap(tmp_path / "rtac.pcap", [(t0, request), (t0 + 12_000, answer), (t0 + 100_000, request)])
    assert frames(cli, str(pcap), *LINE) == [request.hex(), answer.hex(), request.hex()]


@pytest.mark.parametrize(("change", "code", "said"), [
    ("ethernet", 5, "link type 1 is not a serial line's"),
    ("cut", 7, "cut short in a record"),
    ("backwards", 8, "goes back in time"),
    ("no-line", 10, "give --line"),
])
def test_bad_pcaps_are_one_line(cli: Cli, tmp_path: Path, change: str, code: int, said: str) -> None:
    good = [(1_700_000_000_000_000, bytes.fromhex("02030c1e0004276c")), (1_700_000_000_050_000, b"\x02\x03")]
    if change == "backwards":
        good.reverse()
    pcap = rtac_pcap(tmp_path / "bad.pcap", good, link_type=1 if change == "ethernet" else 147)
    if change == "cut":
        pcap.write_bytes(pcap.read_bytes()[:-1])
    result = cli("analyze", str(pcap), *([] if change == "no-line" else LINE))
    assert result.code == code and said in result.err and str(pcap) in result.err
    assert len(result.err.strip().splitlines()) == 1


@pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark is not installed")
def test_wireshark_tells_queries_from_responses_with_the_udp_link(cli: Cli, tmp_path: Path) -> None:
    """With link type 147 Wireshark cannot tell an FC 43 or FC 23 query from its response (same
    shape both ways); in UDP packets from and to port 502 it can, for every function, with one
    preference (the profile ``rtusniff wireshark setup`` writes holds it). pcapng carries each
    packet's direction and rtusniff's comment."""
    user, udp = tmp_path / "user.pcapng", tmp_path / "udp.pcapng"
    assert cli("export", str(SAMPLE_LOG), "--pcap", str(user), "--pcap-link", "user", "-q").code == 0
    assert cli("export", str(SAMPLE_LOG), "--pcap", str(udp), "-q").code == 0  # udp: the default

    def tshark(path: Path, *options: str) -> str:
        return subprocess.run(["tshark", "-n", "-r", str(path), *options], check=True, capture_output=True,
                              text=True).stdout

    mapped = tshark(user, "-o", 'uat:user_dlts:"User 0 (DLT=147)","mbrtu","0","","0",""')
    assert "Unable to classify" in mapped
    by_port = tshark(udp, "-o", "mbrtu.udp.port:502")
    assert "Unable to classify" not in by_port and by_port.count("Modbus RTU") == 51  # all but the noise
    assert "Query: Unit:   2, Func:  43" in by_port and "Response: Unit:  20, Func:  23" in by_port
    fields = tshark(user, "-T", "fields", "-e", "frame.comment", "-e", "frame.packet_flags_direction").splitlines()
    assert fields[1].startswith("rtusniff #1: response to #0, latency 3.295 ms — device identification: ")
    assert fields[1].endswith("\t0x00000001")  # an answer comes in
    assert fields[0].endswith("\t0x00000002")  # a request goes out from the master
    # rtusniff reads both back to the frames it wrote.
    assert frames(cli, str(udp), *LINE) == frames(cli, str(user), *LINE) == frames(cli, str(SAMPLE_LOG))


def test_pcapng_directions_are_kept_as_channels(cli: Cli, tmp_path: Path) -> None:
    """rtusniff's pcapng says each packet's direction (requests out, answers in); read back, the
    direction is each frame's channel, and bytes of two directions never share a frame."""
    pcapng = tmp_path / "sample.pcapng"
    assert cli("export", str(SAMPLE_LOG), "--pcap", str(pcapng), "-q").code == 0
    records = cli("analyze", str(pcapng), *LINE, "--format", "jsonl").jsonl()
    assert records[0]["channels"] == ["inbound", "outbound"]
    said = {(r["role"], r.get("channel")) for r in records if r["kind"] == "frame"}
    assert {("request", "outbound"), ("response", "inbound")} <= said
    assert not {channel for role, channel in said if role in ("response", "exception")} - {"inbound"}
    # A classic pcap has no directions: no channel.
    classic = tmp_path / "sample.pcap"
    assert cli("export", str(SAMPLE_LOG), "--pcap", str(classic), "-q").code == 0
    plain = cli("analyze", str(classic), *LINE, "--format", "jsonl").jsonl()
    assert "channels" not in plain[0] and all("channel" not in r for r in plain if r["kind"] == "frame")

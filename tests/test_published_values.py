"""Exports plot only what the wire proves: valid answers and accepted writes, never a marker.

A capture built frame by frame (slave 5, generic profile): a valid read, the same read
answered with a damaged CRC and other values, a write refused with exception 04, a write
accepted, an FC 6 write echoed. Plus the shipped sample, whose drive 12 reads 16#8000
("non-existent or protected parameter") in one answer.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from decoders.crc import crc_bytes
from tests.conftest import SAMPLE_LOG, CliResult
from tests.test_exports import _rerun_rows

T0 = 1_700_000_000.0


def adu(hex_pdu: str) -> bytes:
    body = bytes.fromhex(hex_pdu)
    return body + crc_bytes(body)


def damaged(frame: bytes) -> bytes:
    return frame[:-1] + bytes([frame[-1] ^ 0xFF])


#: (seconds after T0, frame) at 19200 8E1, exact timing: each frame stamped at its end.
EXCHANGES: list[tuple[float, bytes]] = [
    (0.00, adu("05 03 0064 0002")),                  # read 100..101
    (0.02, adu("05 03 04 000A 0014")),               # valid: 100 = 10, 101 = 20
    (0.10, adu("05 03 0064 0002")),
    (0.12, damaged(adu("05 03 04 000A 0063"))),      # CRC error: 101 = 99 never happened
    (0.20, adu("05 10 00C8 0002 04 0007 0008")),     # write 200..201 = 7, 8
    (0.22, adu("05 90 04")),                         # refused: exception 04
    (0.30, adu("05 10 00C8 0002 04 0003 0004")),     # write 200..201 = 3, 4
    (0.32, adu("05 10 00C8 0002")),                  # accepted
    (0.40, adu("05 06 012C 0005")),                  # write 300 = 5
    (0.42, adu("05 06 012C 0005")),                  # echoed: accepted
]


@pytest.fixture(scope="module")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("published") / "writes.log"
    lines = ["# rtu-capture v1", "# line: 19200 8E1", "# timing: exact"]
    lines += [f"{T0 + t:.9f} {frame.hex(' ').upper()}" for t, frame in EXCHANGES]
    path.write_text("\n".join(lines) + "\n")
    return path


def mcap_messages(path: Path, topic: str) -> list[dict[str, Any]]:
    with path.open("rb") as f:
        return [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(topics=[topic])]


def test_mcap_params_carry_only_valid_answers_and_accepted_writes(capture: Path, cli: Any, tmp_path: Path) -> None:
    out = tmp_path / "writes.mcap"
    assert cli("export", str(capture), "--mcap", str(out)).code == 0
    params = mcap_messages(out, "/slave/5/params")
    values = [{k: v for k, v in p.items() if k != "index"} for p in params]
    assert values == [{"100": 10, "101": 20}, {"200": 3, "201": 4}, {"300": 5}]
    # Published at the answers (frames 1, 7, 9), never at a request or the damaged answer.
    assert [p["index"] for p in params] == [1, 7, 9]
    # The damaged and refused frames are still there, marked, in the frame records.
    frames = mcap_messages(out, "/modbus/frames")
    assert frames[3]["crc_ok"] is False and frames[3]["summary"].startswith("CRC error")
    assert frames[5]["role"] == "exception" and frames[5]["exception_code"] == 4


def test_rerun_plots_only_valid_answers_and_accepted_writes(capture: Path, cli: Any, tmp_path: Path) -> None:
    out = tmp_path / "writes.rrd"
    assert cli("export", str(capture), "--rrd", str(out)).code == 0
    _, values, _ = _rerun_rows(out)
    plotted = {path: series for path, series in values.items() if "/params/" in path}
    assert plotted == {"/slaves/5/params/100": [10.0], "/slaves/5/params/101": [20.0],
                       "/slaves/5/params/200": [3.0], "/slaves/5/params/201": [4.0], "/slaves/5/params/300": [5.0]}


def test_the_protected_marker_is_not_a_number(cli: Any, tmp_path: Path) -> None:
    out, rrd = tmp_path / "sample.mcap", tmp_path / "sample.rrd"
    assert cli("export", str(SAMPLE_LOG), "--mcap", str(out), "--rrd", str(rrd), "--profile", "atv71").code == 0
    frames = mcap_messages(out, "/modbus/frames")
    marked = [p for f in frames for p in f["params"] if p["raw"] == 0x8000 and f["role"] == "response"]
    assert marked and all(p["value"] == "non-existent or protected parameter" for p in marked)
    for message in mcap_messages(out, "/slave/12/params"):
        assert 32768 not in message.values()
    _, values, _ = _rerun_rows(rrd)
    assert all(32768.0 not in series for path, series in values.items() if path.startswith("/slaves/12/"))
    # The drive's other values stay on their state series; the marker is on none.
    states = _state_texts(rrd)
    assert states["/slaves/12/state/CHCF"] == ["CHCF: I/O profile"]
    assert states["/slaves/12/state/COP"] == ["COP: copy of the command word"]
    assert not any("protected" in text for texts in states.values() for text in texts)


def test_state_series_take_no_refused_write(tmp_path: Path, cli: Any) -> None:
    """Writing CMD (8501) on an Altivar and being refused is no change of its command state."""
    capture = tmp_path / "cmd.log"
    frames = [(0.00, adu("02 06 2135 000F")), (0.02, adu("02 86 04")),   # CMD = 16#000F refused
              (0.10, adu("02 06 2135 0006")), (0.12, adu("02 06 2135 0006"))]  # CMD = 16#0006 accepted
    lines = ["# rtu-capture v1", "# line: 19200 8E1", "# timing: exact"]
    capture.write_text("\n".join(lines + [f"{T0 + t:.9f} {f.hex(' ')}" for t, f in frames]) + "\n")
    rrd = tmp_path / "cmd.rrd"
    assert cli("export", str(capture), "--rrd", str(rrd), "--profile", "atv71").code == 0
    texts = _state_texts(rrd)
    assert list(texts) == ["/slaves/2/state/CMD"]
    assert len(texts["/slaves/2/state/CMD"]) == 1 and "000F" not in texts["/slaves/2/state/CMD"][0]


def _state_texts(rrd: Path) -> dict[str, list[str]]:
    import rerun as rr

    texts: dict[str, list[str]] = {}
    for chunk in rr.chunk.RrdReader(str(rrd)).stream().to_chunks():
        if "/state/" in chunk.entity_path and chunk.timeline_names:
            batch = chunk.to_record_batch()
            column = next(name for name in batch.schema.names if name.endswith(":text"))
            texts.setdefault(chunk.entity_path, []).extend(v[0] for v in batch.column(column).to_pylist() if v)
    return texts


def test_host_timing_publishes_no_latency(cli: Any, tmp_path: Path) -> None:
    usb = SAMPLE_LOG.with_name("atv71-plc-poll-usb.log")
    frames = [r for r in cli("analyze", str(usb), "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    paired = [f for f in frames if f["request_index"] is not None]
    assert paired and all(f["latency_s"] is None for f in paired)
    stats: CliResult = cli("stats", str(usb), "--format", "json")
    document = json.loads(stats.out)
    assert document["latency_measured"] is False
    table = cli("stats", str(usb))
    assert "latency n/a: host timing" in table.out and "0.00" not in table.out
    out = tmp_path / "usb.mcap"
    assert cli("export", str(usb), "--mcap", str(out)).code == 0
    answered = [t for t in mcap_messages(out, "/modbus/transactions") if t["outcome"] == "answered"]
    assert answered and all(t["latency_ms"] is None for t in answered)
    # Exact captures keep their measured latencies.
    exact = [r for r in cli("analyze", str(SAMPLE_LOG), "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    assert any(f["latency_s"] for f in exact)
    assert json.loads(cli("stats", str(SAMPLE_LOG), "--format", "json").out)["latency_measured"] is True

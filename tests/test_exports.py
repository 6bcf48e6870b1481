"""Exports read back with the real libraries: the mcap reader, the rerun CLI and Rerun's reader."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import struct
import subprocess
import sys
from collections import Counter
from collections.abc import Callable
from decimal import Decimal
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from tests.conftest import SAMPLE_LOG, CliResult

Cli = Callable[..., CliResult]
RERUN = shutil.which("rerun") or str(Path(os.sys.executable).with_name("rerun"))  # type: ignore[attr-defined]
QUIET_RERUN = {**os.environ, "CI": "1"}  # the rerun CLI writes no analytics files with CI set


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    from sniffer.cli import main

    folder = tmp_path_factory.mktemp("export")
    mcap, rrd = folder / "poll.mcap", folder / "poll.rrd"
    os.environ.setdefault("CI", "1")
    assert main(["export", str(SAMPLE_LOG), "--mcap", str(mcap), "--rrd", str(rrd), "--profile", "atv71"]) == 0
    return mcap, rrd


def messages(path: Path, topic: str) -> list[dict[str, Any]]:
    with path.open("rb") as f:
        return [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(topics=[topic])]


def test_mcap_channels_schemas_and_metadata(exported: tuple[Path, Path]) -> None:
    mcap, _ = exported
    with mcap.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        topics = {c.topic: c for c in summary.channels.values()}
        counts = {topics_id.topic: summary.statistics.channel_message_counts[cid]
                  for cid, topics_id in summary.channels.items()}
        schemas = {s.id: s for s in summary.schemas.values()}
        assert schemas[topics["/modbus/log"].schema_id].name == "foxglove.Log"
        assert schemas[topics["/modbus/log"].schema_id].encoding == "protobuf"
        assert schemas[topics["/modbus/frames"].schema_id].encoding == "jsonschema"
        assert summary.chunk_indexes and all(c.compression == "zstd" for c in summary.chunk_indexes)
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    assert counts["/modbus/frames"] == counts["/modbus/log"] == 52
    assert {"/slave/2/params", "/slave/12/params", "/slave/20/params", "/rtusniff/raw_chunks"} <= set(topics)
    export = metadata["rtusniff.export"]
    assert export["source_sha256"] == hashlib.sha256(SAMPLE_LOG.read_bytes()).hexdigest()
    assert (export["line"], export["timing"], export["profiles"]) == ("19200 8E1", "exact", "default atv71")
    assert export["tool"].startswith("rtusniff ") and "export" in export["command"]
    assert metadata["rtusniff.capture"]["line"] == "19200 8E1"


def test_mcap_values_transactions_and_log_levels(exported: tuple[Path, Path]) -> None:
    mcap, _ = exported
    params = messages(mcap, "/slave/2/params")
    assert {"SFr": 4.0, "tFr": 60.0, "HSP": 50.0, "LSP": 0.0}.items() <= params[0].items()
    scanner = messages(mcap, "/slave/20/params")
    assert any(p.get("NM2→RFRD") == 5000 for p in scanner)
    outcomes = Counter(t["outcome"] for t in messages(mcap, "/modbus/transactions"))
    # 21 responses, one with a CRC error; drive 3's 4 unanswered requests; 2 exceptions.
    assert outcomes == {"answered": 20, "crc_error": 1, "timeout": 4, "exception": 2}
    answered = [t for t in messages(mcap, "/modbus/transactions") if t["outcome"] == "answered"]
    assert all(t["latency_ms"] > 0 and t["answer"] for t in answered)
    frames = messages(mcap, "/modbus/frames")
    assert frames[7]["summary"].endswith("HSP = 50.0 Hz, LSP = 0.0 Hz")


def test_rerun_checks_the_mcap(exported: tuple[Path, Path]) -> None:
    mcap, _ = exported
    result = subprocess.run([RERUN, "mcap", "check", str(mcap)], capture_output=True, text=True,
                            env=QUIET_RERUN, check=False, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr


def test_rerun_renders_the_mcap_log(exported: tuple[Path, Path], tmp_path: Path) -> None:
    """Rerun turns the protobuf foxglove.Log channel into a text log with levels."""
    import rerun as rr

    mcap, _ = exported
    converted = tmp_path / "converted.rrd"
    result = subprocess.run([RERUN, "mcap", "convert", str(mcap), "-o", str(converted)], capture_output=True,
                            text=True, env=QUIET_RERUN, check=False, timeout=120)
    assert result.returncode == 0, result.stderr
    levels: Counter[str] = Counter()
    texts: list[str] = []
    for chunk in rr.chunk.RrdReader(str(converted)).stream().to_chunks():
        batch = chunk.to_record_batch()
        if chunk.entity_path == "/modbus/log" and "TextLog:text" in batch.schema.names:
            levels.update(v[0] for v in batch.column("TextLog:level").to_pylist())
            texts += [v[0] for v in batch.column("TextLog:text").to_pylist()]
    assert sum(levels.values()) == 52
    assert levels["ERROR"] == 1 + 4 + 2  # a CRC error, drive 3's timeouts, two exceptions
    assert levels["WARN"] >= 3  # gap_1_5, short_idle, noise, retries
    assert texts[7].startswith("#7 response: HR = 0028 0258 01F4 0000")


def test_analyze_of_the_export_equals_analyze_of_the_capture(exported: tuple[Path, Path], cli: Cli) -> None:
    mcap, _ = exported
    original = cli("analyze", str(SAMPLE_LOG), "--format", "jsonl").jsonl()
    again = cli("analyze", str(mcap), "--format", "jsonl").jsonl()
    assert again[1:] == original[1:]  # all but the capture record, which names the file


def test_mcap_frames_are_the_jsonl_frame_records(exported: tuple[Path, Path], cli: Cli) -> None:
    """Every field of every frame record; the times in seconds are the exact decimals of their
    nanoseconds there, so they equal the JSONL's floats to within the floats' rounding."""
    mcap, _ = exported
    records = [
        r
        for r in cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", "--profile", "atv71").jsonl()
        if r["kind"] == "frame"
    ]
    frames = messages(mcap, "/modbus/frames")
    assert len(frames) == len(records) == 52
    for frame, record in zip(frames, records, strict=True):
        for field in ("t", "t_end", "latency_s"):
            ours, theirs = frame.pop(field), record.pop(field)
            assert (ours is None) == (theirs is None)
            assert ours is None or ours == pytest.approx(theirs, rel=1e-15, abs=1e-12)
        assert frame == record


def test_mcap_json_messages_follow_their_channels_schemas(exported: tuple[Path, Path]) -> None:
    """Every JSON message validates against the JSON Schema its channel declares in the file
    (what Foxglove reads the channel with)."""
    import jsonschema

    mcap, _ = exported
    validated: Counter[str] = Counter()
    with mcap.open("rb") as f:
        for schema, _, message in make_reader(f).iter_messages():
            if schema is None or schema.encoding != "jsonschema":
                continue
            jsonschema.validate(json.loads(message.data), json.loads(schema.data))
            validated[schema.name] += 1
    assert validated["rtusniff.Frame"] == 52 and validated["rtusniff.Transaction"] == 27
    assert validated["rtusniff.SlaveParams"] > 0


def test_mcap_times_are_exact_decimals(exported: tuple[Path, Path]) -> None:
    mcap, _ = exported
    with mcap.open("rb") as f:
        for _, channel, message in make_reader(f).iter_messages(topics=["/modbus/frames"]):
            record = json.loads(message.data, parse_float=Decimal)
            assert record["t"] == Decimal(record["t_ns"]) / 10**9
            assert record["t_end"] == Decimal(record["t_end_ns"]) / 10**9
            assert message.log_time == record["t_ns"] and channel.message_encoding == "json"


def test_rerun_styles_only_series_that_have_rows(exported: tuple[Path, Path]) -> None:
    """A series style (static) goes with an entity's first rows: a slave that never failed a CRC,
    a state word (text, not plotted) or a function never answered shows no empty series."""
    import rerun as rr

    static, timed = set(), set()
    for chunk in rr.chunk.RrdReader(str(exported[1])).stream().to_chunks():
        (timed if chunk.timeline_names else static).add(chunk.entity_path)
    assert static and static <= timed | {"/__properties"}, sorted(static - timed)


def _rerun_rows(rrd: Path) -> tuple[list[tuple[str, int]], dict[str, list[float]], set[str]]:
    """Per chunk with a timeline: its entity and rows; the scalar values per entity; the timelines."""
    import rerun as rr

    chunks: list[tuple[str, int]] = []
    values: dict[str, list[float]] = {}
    timelines: set[str] = set()
    for chunk in rr.chunk.RrdReader(str(rrd)).stream().to_chunks():
        if not chunk.timeline_names:
            continue  # static: the series' name and style
        chunks.append((chunk.entity_path, chunk.num_rows))
        timelines.update(chunk.timeline_names)
        batch = chunk.to_record_batch()
        if "Scalars:scalars" in batch.schema.names:
            values.setdefault(chunk.entity_path, []).extend(
                v[0] for v in batch.column("Scalars:scalars").to_pylist() if v)
    return chunks, values, timelines


def test_rerun_recording_read_back(exported: tuple[Path, Path], cli: Cli) -> None:
    _, rrd = exported
    frames = [r for r in cli("analyze", str(SAMPLE_LOG), "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    chunks, values, timelines = _rerun_rows(rrd)
    rows = _summed(chunks)
    assert {"capture_time", "frame"} <= timelines
    assert values["/slaves/2/params/HSP"][0] == 50.0
    assert values["/slaves/20/params/NM2_RFRD"][0] == 5000.0
    assert rows["/slaves/2/log"] == sum(1 for f in frames if f["slave"] == 2)
    assert rows["/slaves/3/errors/timeout"] == 4
    assert rows["/slaves/12/errors/exception"] == 1
    assert any(path.startswith("/slaves/20/state/") for path in rows)


@pytest.mark.parametrize("limits", [(4, 10**9, 32), (10**9, 24, 32), (10**9, 10**9, 2)])
def test_rerun_chunks_are_large_and_memory_is_capped(
    exported: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, limits: tuple[int, int, int]
) -> None:
    """An entity is sent when it holds ENTITY_ROWS rows (so a long capture makes few, large
    chunks: the recording keeps an index entry per chunk); past MAX_BUFFERED_ROWS the largest
    go early; a buffer's column pieces are merged at MAX_PIECES. Either way the recording holds
    the same rows, in the same order."""
    entity_rows, max_buffered, max_pieces = limits
    from sniffer.cli import main
    from sniffer.exports import rerun_rows

    monkeypatch.setattr(rerun_rows, "ENTITY_ROWS", entity_rows)
    monkeypatch.setattr(rerun_rows, "MAX_BUFFERED_ROWS", max_buffered)
    monkeypatch.setattr(rerun_rows, "MAX_PIECES", max_pieces)
    buffered: list[int] = []
    send_due = rerun_rows.EntityRows.send_due

    def recorded_send_due(self: rerun_rows.EntityRows) -> None:
        send_due(self)
        buffered.append(self.rows)

    monkeypatch.setattr(rerun_rows.EntityRows, "send_due", recorded_send_due)
    rrd = tmp_path / "small.rrd"
    assert main(["export", str(SAMPLE_LOG), "--rrd", str(rrd), "--profile", "atv71"]) == 0
    chunks, values, _ = _rerun_rows(rrd)
    expected_chunks, expected_values, _ = _rerun_rows(exported[1])
    assert values == expected_values
    assert _summed(chunks) == _summed(expected_chunks)
    if entity_rows == 4:
        per_entity: dict[str, list[int]] = {}
        for entity, count in chunks:
            per_entity.setdefault(entity, []).append(count)
        assert all(min(counts[:-1], default=entity_rows) >= entity_rows for counts in per_entity.values())
        assert max(len(counts) for counts in per_entity.values()) > 1
    elif max_buffered == 24:
        assert buffered and max(buffered) <= max_buffered
        assert len(chunks) > len(expected_chunks)


def _summed(chunks: list[tuple[str, int]]) -> Counter[str]:
    totals: Counter[str] = Counter()
    for entity, count in chunks:
        totals[entity] += count
    return totals


def test_export_options(cli: Cli, tmp_path: Path) -> None:
    nothing = cli("export", str(SAMPLE_LOG))
    assert nothing.code == 2 and "give --mcap OUT.mcap, --rrd OUT.rrd, --pcap OUT.pcap, --parquet DIR" in nothing.err
    existing = tmp_path / "x.mcap"
    existing.write_bytes(b"keep")
    refused = cli("export", str(SAMPLE_LOG), "--mcap", str(existing))
    assert refused.code == 11 and existing.read_bytes() == b"keep"


TSHARK = shutil.which("tshark")


@pytest.mark.skipif(TSHARK is None, reason="tshark (Wireshark) not installed")
def test_pcap_decoded_by_tshark(cli: Cli, tmp_path: Path) -> None:
    from sniffer.exports.pcap_export import WIRESHARK_USER_DLT

    pcap = tmp_path / "poll.pcap"
    assert cli("export", str(SAMPLE_LOG), "--pcap", str(pcap), "--pcap-link", "user").code == 0
    fields = ["frame.time_epoch", "mbrtu.unit_id", "modbus.func_code", "modbus.exception_code",
              "mbrtu.crc16.status"]
    shown = subprocess.run(
        [str(TSHARK), "-n", "-o", f"uat:user_dlts:{WIRESHARK_USER_DLT}", "-o", "mbrtu.crc_verification:TRUE",
         "-r", str(pcap), "-T", "fields", "-E", "separator=;", *[a for f in fields for a in ("-e", f)]],
        capture_output=True, text=True, check=True, timeout=120).stdout.splitlines()
    analyzed = cli("analyze", str(SAMPLE_LOG), "--format", "jsonl")
    frames = [r for r in map(json.loads, analyzed.out.splitlines()) if r["kind"] == "frame"]
    assert len(shown) == len(frames) > 40
    for row, frame in zip(shown, frames, strict=True):
        time, unit, function, exception, crc = row.split(";")
        assert abs(float(time) - frame["t"]) < 1e-6
        if frame["protocol"] != "modbus" or frame["slave"] is None:
            assert unit == ""  # noise: shown as malformed, but there
            continue
        assert int(unit) == frame["slave"]
        assert crc == ("1" if frame["crc_ok"] else "0")
        if frame["crc_ok"]:
            assert int(function) == frame["function"] & 0x7F
            assert (int(exception) if exception else None) == frame["exception_code"]


def read_pcap(path: Path) -> tuple[int, list[tuple[int, str]]]:
    """Link type and (time ns, hex) per packet, read with struct as any pcap reader would."""
    data = path.read_bytes()
    magic, major, minor, _, _, _, linktype = struct.unpack_from("<IHHiIII", data)
    assert (magic, major, minor) == (0xA1B23C4D, 2, 4)
    packets, at = [], 24
    while at < len(data):
        seconds, nanos, captured, length = struct.unpack_from("<IIII", data, at)
        assert captured == length
        packets.append((seconds * 1_000_000_000 + nanos, data[at + 16 : at + 16 + captured].hex()))
        at += 16 + captured
    assert at == len(data)
    return linktype, packets


@pytest.mark.parametrize("sample", ["atv71-plc-poll-usb.log", "nord-uss.log", "xbt-hmi.log", "atv312-setup.log"])
def test_pcap_holds_every_frame_with_its_time(cli: Cli, tmp_path: Path, sample: str) -> None:
    source = SAMPLE_LOG.parent / sample
    pcap = tmp_path / "out.pcap"
    assert cli("export", str(source), "--pcap", str(pcap), "--pcap-link", "user").code == 0
    frames = [r for r in cli("analyze", str(source), "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    linktype, packets = read_pcap(pcap)
    assert linktype == 147
    assert packets == [(f["t_ns"], f["hex"]) for f in frames]


@pytest.mark.parametrize("option", ["--mcap", "--rrd", "--pcap"])
@pytest.mark.parametrize("target", ["missing folder", "full disk"])
def test_an_output_that_cannot_be_written_is_one_error_line(option: str, target: str, tmp_path: Path) -> None:
    """A missing folder, or a disk that fills up (/dev/full), is said once, naming the file."""
    if target == "full disk" and not Path("/dev/full").exists():
        pytest.skip("no /dev/full here")
    path = str(tmp_path / "no" / "such" / "out") if target == "missing folder" else "/dev/full"
    command = [os.sys.executable, "-m", "sniffer", "export", str(SAMPLE_LOG), option, path, "--force"]  # type: ignore[attr-defined]
    result = subprocess.run(command, capture_output=True, text=True, env=QUIET_RERUN, check=False, timeout=120)
    assert result.returncode == 11, result.stderr
    assert result.stderr.count("\n") == 1 and result.stderr.startswith(f"error: {path}: cannot write: ")
    assert "Traceback" not in result.stderr


def test_rerun_buffered_rows_own_their_memory(tmp_path: Path) -> None:
    """Rows wait in their entity's buffer, a state's for a whole day if it rarely changes: each
    buffered column must own its data, not be a view that keeps its batch's column alive (a
    one-row view did, and the export grew 20 MB per million frames)."""
    from decoders.modbus.annotate import Annotator
    from decoders.pipeline import Decoder
    from decoders.profiles.apply import ProfileApplier
    from sniffer.exports import rerun_rows
    from sniffer.exports.rerun_export import RerunExporter
    from sniffer.io.registry import open_reader
    from sniffer.profiles_io import profile_book

    reader = open_reader(str(SAMPLE_LOG))
    assert reader.info.line is not None
    decoder = Decoder(reader.info.line, reader.info.timing)
    annotator = Annotator(ProfileApplier(profile_book(["atv71"], [])))
    exporter = RerunExporter(str(tmp_path / "buffered.rrd"))
    for chunks in reader.batches():
        for batch in decoder.feed(chunks):
            exporter.messages(annotator.annotate_batch(batch))
    buffers = exporter.entities.buffers.values()
    columns = [c for rows in buffers for c in (*rows.times, *rows.frames, *rows.values, *rows.texts, *rows.levels)]
    assert any("/state/" in exporter.entities.paths[entity] for entity in exporter.entities.buffers)
    assert columns and all(column.base is None for column in columns)
    assert all(len(rows.times) < rerun_rows.MAX_PIECES for rows in buffers)
    exporter.close()


@pytest.mark.parametrize(("given", "used"), [(None, "QUIET"), ("debug", "debug")])
def test_the_rerun_sdk_log_filter_is_set_before_its_import_unless_the_user_set_one(
    given: str | None, used: str
) -> None:
    """The SDK reads ``RUST_LOG`` once, at import: rerun_sdk sets the quiet filter first, and a
    filter the user set wins."""
    from sniffer.exports.rerun_sdk import QUIET_FILTER

    env = {key: value for key, value in os.environ.items() if key != "RUST_LOG"}
    if given is not None:
        env["RUST_LOG"] = given
    script = "import os, sniffer.exports.rerun_sdk as sdk; print(os.environ['RUST_LOG'], sdk.rr.__name__)"
    shown = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True).stdout
    assert shown.split() == [QUIET_FILTER if used == "QUIET" else used, "rerun"]

"""``export --parquet``: a dataset DuckDB and pyarrow read as one table per kind, holding what
``analyze``, ``values`` and ``stats`` say of the same captures; appended to, never rewritten."""

from __future__ import annotations

import json
import re
import shutil
import signal
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.dataset as ds
import pytest

from tests.real_recordings import RECORDINGS, TEXT, available

duckdb = pytest.importorskip("duckdb")
CAPTURES = Path(__file__).resolve().parents[1] / "captures"
SAMPLES = ["atv71-plc-poll.mcap", "xbt-hmi.mcap", "atv312-setup.mcap", "nord-uss.mcap"]
#: Where the documented queries are: the README, and the exports' page.
DOCUMENTS = [Path(__file__).resolve().parents[1] / name for name in ("README.md", "docs/exports.md")]


def readme_query(table_name: str) -> str:
    """The documented DuckDB query over ``table_name`` (its dataset folder: ``{dataset}``)."""
    text = "".join(document.read_text(encoding="utf-8") for document in DOCUMENTS)
    blocks = re.findall(r"```sql\n(.*?)```", text, re.DOTALL)
    (query,) = [block for block in blocks if f"'plant/{table_name}/" in block]
    return query.replace("'plant/", "'{dataset}/").rstrip().removesuffix(";")


#: The README's queries: latency p95 per slave per day, across every bus of the dataset; exact,
#: and to within 1 % from the latency histograms.
P95_QUERY = readme_query("transactions")
P95_HISTOGRAM_QUERY = readme_query("latencies")


def table(dataset: Path, name: str) -> list[dict[str, Any]]:
    """A table's rows, each time as its exact nanoseconds (``t_ns``), checked against the
    microsecond timestamp beside it."""
    import pyarrow as pa

    read = ds.dataset(dataset / name, partitioning="hive").to_table()
    for position, column in enumerate(read.schema):
        if pa.types.is_timestamp(column.type):
            assert column.type == pa.timestamp("us", tz="UTC")
            exact = read.column(f"{column.name}_ns")
            assert read.column(position).cast(pa.int64()).to_pylist() == [t // 1000 for t in exact.to_pylist()]
            read = read.set_column(position, column.name, exact)
    rows: list[dict[str, Any]] = read.to_pylist()
    return rows


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from sniffer.cli import main

    folder = tmp_path_factory.mktemp("parquet") / "plant"
    for sample in SAMPLES:
        assert main(["export", str(CAPTURES / sample), "--parquet", str(folder), "--profile", "atv71", "-q"]) == 0
    return folder


def assert_frames_are_records(rows: list[dict[str, Any]], records: list[dict[str, Any]]) -> None:
    rows = sorted(rows, key=lambda r: r["index"])
    assert [r["index"] for r in rows] == [r["index"] for r in records]
    for row, record in zip(rows, records, strict=True):
        assert row["bytes"].hex() == record["hex"] and row["role"] == record["role"]
        assert row["flags"] == record["flags"] and row["summary"] == record["summary"]
        assert (row["slave"], row["function"], row["request_index"]) == \
            (record["slave"], record["function"], record["request_index"])
        assert row["t"] == record["t_ns"] and row["crc_ok"] == record["crc_ok"]
        expected = None if record["latency_s"] is None else record["latency_s"] * 1e3
        assert row["latency_ms"] == pytest.approx(expected)


def test_frames_are_the_frame_records(dataset: Path, cli: Callable[..., Any]) -> None:
    for sample in SAMPLES:
        records = [r for r in cli("analyze", str(CAPTURES / sample), "--format", "jsonl", "--profile", "atv71").jsonl()
                   if r["kind"] == "frame"]
        assert_frames_are_records([r for r in table(dataset, "frames") if r["bus"] == Path(sample).stem], records)


def test_a_window_exports_its_frames_alone(tmp_path: Path, cli: Callable[..., Any]) -> None:
    """Frames of part of a batch: each column picks the window's rows."""
    window = ["--around", "20", "--context", "7"]
    sample = str(CAPTURES / "atv71-plc-poll.mcap")
    assert cli("export", sample, *window, "--parquet", str(tmp_path), "-q").code == 0
    records = [r for r in cli("analyze", sample, "--format", "jsonl", *window).jsonl() if r["kind"] == "frame"]
    assert [r["index"] for r in records] == list(range(13, 28))
    assert_frames_are_records(table(tmp_path, "frames"), records)


def test_values_are_what_values_says(dataset: Path, cli: Callable[..., Any]) -> None:
    expected = cli("values", str(CAPTURES / "atv71-plc-poll.mcap"), "--profile", "atv71", "--format", "jsonl").jsonl()
    rows = sorted((r for r in table(dataset, "values") if r["bus"] == "atv71-plc-poll"),
                  key=lambda r: (r["t"], r["index"], r["address"]))
    expected.sort(key=lambda r: (r["t_ns"], r["index"], r["address"]))
    assert len(rows) == len(expected) > 0
    for row, record in zip(rows, expected, strict=True):
        assert (row["slave"], row["kind"], row["address"], row["code"], row["raw"], row["valid"]) == \
            (record["slave"], record["kind"], record["address"], record["code"], record["raw"], record["valid"])
        if isinstance(record["value"], str):
            assert row["text"] == record["value"] and row["value"] is None
        else:
            assert row["value"] == pytest.approx(record["value"])


@pytest.mark.parametrize("profile", [[], ["--profile", "20=atv71"]], ids=["no profile", "one slave profiled"])
def test_values_without_a_profile_are_what_values_says(tmp_path: Path, cli: Callable[..., Any],
                                                       profile: list[str]) -> None:
    """Slaves no profile speaks for go to the table in columns (runs of registers and coils);
    alone or between profiled slaves' rows (the generated drives identify themselves; steady
    ones repeat their values, which the table takes apart once), the table holds what
    ``values`` lists, in its order."""
    from benchmarks.bench_memory import benchmark_capture

    generated = [benchmark_capture(tmp_path, 3000, traffic) for traffic in ("coils", "steady", "mixed")]
    for capture in (CAPTURES / "atv71-plc-poll.mcap", CAPTURES / "xbt-hmi.mcap", *generated):
        folder = tmp_path / f"{capture.stem}-{len(profile)}"
        assert cli("export", str(capture), "--parquet", str(folder), *profile, "-q").code == 0
        expected = cli("values", str(capture), *profile, "--format", "jsonl").jsonl()
        rows = table(folder, "values")
        assert len(rows) == len(expected) > 0
        for row, record in zip(rows, expected, strict=True):
            assert (row["t"], row["index"], row["slave"], row["kind"], row["address"], row["code"], row["name"],
                    row["raw"], row["valid"], row["request_index"], row["unit"]) == \
                (record["t_ns"], record["index"], record["slave"], record["kind"], record["address"], record["code"],
                 record["name"], record["raw"], record["valid"], record["request_index"], record["unit"])
            assert row["value"] == pytest.approx(record["value"]) if not isinstance(record["value"], str) else \
                row["text"] == record["value"]


def test_anomalies_and_transactions_are_counted_as_stats_counts(dataset: Path, cli: Callable[..., Any]) -> None:
    stats = json.loads(cli("stats", str(CAPTURES / "atv71-plc-poll.mcap"), "--format", "json").out)
    kinds = Counter(r["kind"] for r in table(dataset, "anomalies") if r["bus"] == "atv71-plc-poll")
    assert kinds["crc_error"] == stats["crc_errors"]
    for flag, count in stats["flags"].items():
        assert kinds[flag] == count, flag
    outcomes = Counter(r["outcome"] for r in table(dataset, "transactions") if r["bus"] == "atv71-plc-poll")
    assert outcomes["timeout"] == stats["flags"]["timeout"]
    assert outcomes["exception"] == stats["roles"].get("exception", 0)


def test_the_readme_query_runs_on_duckdb(dataset: Path, cli: Callable[..., Any]) -> None:
    """Latency p95 per slave per day across all buses, as the README shows it: the nearest rank of
    every answer's latency, and what ``stats`` shows of each slave (to its bin, within 0.5 %):
    one definition of a percentile (the exact query read 5.63 ms where ``stats`` said 6.00 for
    slave 2 of the sample, by interpolating)."""
    result = duckdb.sql(P95_QUERY.format(dataset=dataset)).fetchall()
    assert {row[0] for row in result} == {Path(sample).stem for sample in SAMPLES}
    transactions = [r for r in table(dataset, "transactions") if r["outcome"] == "answered"]
    for bus, date, slave, answers, p95 in result:
        mine = sorted(r["latency_ms"] for r in transactions if (r["bus"], r["slave"]) == (bus, slave))
        assert answers == len(mine) and p95 == mine[(95 * answers + 99) // 100 - 1]
        assert str(date) == "2023-11-14"
    report = cli("report", str(CAPTURES / "atv71-plc-poll.mcap"), "--format", "md")
    assert report.code == 0, report.err  # its slaves table: the p95 column is the exact p95, to its bin
    for bus, _, slave, _, p95 in result:
        if bus != "atv71-plc-poll":
            continue
        cells = [cell.strip() for cell in re.search(rf"^\| {slave} \|(.*)$", report.out, re.M)[1].split("|")]  # type: ignore[index]
        assert float(cells[10]) == pytest.approx(p95, rel=0.006, abs=0.006), (slave, cells)


def test_the_readme_histogram_query_is_within_one_percent(dataset: Path) -> None:
    """The histograms count every answer of the ``transactions`` table, and their p95 is the
    upper bound of the bin that holds the exact one (nearest rank, as ``stats`` ranks): at most
    1 % above it."""
    exact = duckdb.sql(P95_QUERY.format(dataset=dataset)).fetchall()
    result = duckdb.sql(P95_HISTOGRAM_QUERY.format(dataset=dataset)).fetchall()
    assert [row[:4] for row in result] == [row[:4] for row in exact]
    transactions = [r for r in table(dataset, "transactions") if r["outcome"] == "answered"]
    for bus, date, slave, answers, p95 in result:
        mine = sorted(r["latency_ms"] for r in transactions if (r["bus"], str(r["date"]), r["slave"]) ==
                      (bus, str(date), slave))
        nearest_rank = mine[(95 * answers + 99) // 100 - 1]
        assert nearest_rank <= p95 <= nearest_rank * 1.0101, (bus, slave)
    latencies = table(dataset, "latencies")
    assert all(row["to_ms"] == pytest.approx(1.01 * row["from_ms"]) for row in latencies)
    assert sum(row["answers"] for row in latencies) == len(transactions)


def test_every_file_says_where_it_comes_from(dataset: Path) -> None:
    import pyarrow.parquet as pq

    files = sorted(dataset.glob("*/bus=xbt-hmi/date=*/*.parquet"))
    assert len(files) == 5
    for file in files:
        metadata = pq.read_schema(file).metadata
        assert metadata[b"rtusniff.line"] == b"19200 8N1" and len(metadata[b"rtusniff.source_sha256"]) == 64
        assert metadata[b"rtusniff.tool"].startswith(b"rtusniff ")
        assert pq.ParquetFile(file).metadata.row_group(0).column(0).compression == "ZSTD"


def test_times_and_indexes_are_stored_as_differences(dataset: Path) -> None:
    """DELTA_BINARY_PACKED where rows grow a little (a dataset a quarter smaller; not the values'
    times, which repeat a frame's), dictionaries where they repeat (the tests above read them
    back with DuckDB and pyarrow)."""
    import pyarrow.parquet as pq

    from sniffer.exports.parquet_export import DELTA_COLUMNS, DICTIONARY_COLUMNS, UNSUMMARISED_COLUMNS

    seen = set()
    for file in sorted(dataset.glob("*/bus=atv71-plc-poll/date=*/*.parquet")):
        table = file.parts[-4]
        group = pq.ParquetFile(file).metadata.row_group(0)
        for place in range(group.num_columns):
            column = group.column(place)
            name = column.path_in_schema.split(".")[0]
            if name in DELTA_COLUMNS[table]:
                assert "DELTA_BINARY_PACKED" in column.encodings, (file, name)
                seen.add((table, name))
            else:
                assert "DELTA_BINARY_PACKED" not in column.encodings, (file, name)
                if name in DICTIONARY_COLUMNS and name == column.path_in_schema:  # not in a list
                    assert "RLE_DICTIONARY" in column.encodings, (file, name)
            # Min/max statistics where an engine may skip a row group by them; not on texts, bytes, values.
            assert column.is_stats_set is (name not in UNSUMMARISED_COLUMNS), (file, name)
    assert ("frames", "t") in seen and ("values", "index") in seen and ("values", "t") not in seen
    assert {name for _, name in seen} == {name for names in DELTA_COLUMNS.values() for name in names}


def test_columns_every_row_has_are_required(dataset: Path, tmp_path: Path) -> None:
    """Every table's columns that every row has are declared so (no definition levels to write),
    the others optional; a table of files written before, every column optional, reads as one."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from sniffer.exports.parquet_export import REQUIRED_COLUMNS

    for table, required in REQUIRED_COLUMNS.items():
        file = next(dataset.glob(f"{table}/bus=atv71-plc-poll/date=*/*.parquet"))
        schema = pq.read_schema(file)
        assert {field.name for field in schema if not field.nullable} == required, table
        assert table == "latencies" or {"t", "index"} & required, table
        older = tmp_path / table / "bus=older" / "date=2020-01-01" / "0.parquet"
        older.parent.mkdir(parents=True)
        written = pq.read_table(file)
        pq.write_table(written.cast(pa.schema([field.with_nullable(True) for field in written.schema])), older)
        shutil.copytree(file.parent.parent, tmp_path / table / file.parent.parent.name)
        both = duckdb.sql(f"SELECT count(*) FROM read_parquet('{tmp_path / table}/*/*/*.parquet')").fetchall()
        assert both == [(2 * written.num_rows,)]
        assert ds.dataset(tmp_path / table, partitioning="hive").to_table().num_rows == 2 * written.num_rows


def test_a_dictionary_of_many_values_stops_at_its_page_limit(tmp_path: Path) -> None:
    """``raw`` and ``value`` are dictionary-encoded while few (coils, states); registers polled
    at random make 65 536 of them, stored plain past a dictionary page of 32 KiB."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from sniffer.exports.parquet_export import (
        DELTA_COLUMNS,
        DICTIONARY_COLUMNS,
        DICTIONARY_PAGE_BYTES,
        UNSUMMARISED_COLUMNS,
    )
    from sniffer.exports.parquet_writing import RowGroupWriter

    many = np.random.default_rng(1).permutation(50_000)
    table = pa.table({"raw": pa.array(many, pa.int32()), "value": pa.array(many % 2, pa.float64())})
    writer = RowGroupWriter(DICTIONARY_COLUMNS, DELTA_COLUMNS, UNSUMMARISED_COLUMNS, DICTIONARY_PAGE_BYTES)
    writer.write(tmp_path / "values.parquet", "values", table)
    writer.close()
    group = pq.ParquetFile(tmp_path / "values.parquet").metadata.row_group(0)
    raw, value = group.column(0), group.column(1)
    assert raw.has_dictionary_page and raw.data_page_offset - raw.dictionary_page_offset <= DICTIONARY_PAGE_BYTES + 64
    assert value.has_dictionary_page and value.data_page_offset - value.dictionary_page_offset < 100  # 0.0 and 1.0
    assert pq.read_table(tmp_path / "values.parquet").equals(table)


def test_a_dataset_is_added_to_and_never_rewritten(tmp_path: Path, cli: Callable[..., Any]) -> None:
    folder = tmp_path / "plant"
    assert cli("export", str(CAPTURES / "xbt-hmi.log"), "--parquet", str(folder), "--bus", "line-1").code == 0
    before = {path: path.stat().st_mtime_ns for path in folder.rglob("*.parquet")}
    again = cli("export", str(CAPTURES / "xbt-hmi.log"), "--parquet", str(folder), "--bus", "line-1")
    assert again.code == 11 and "in the dataset already" in again.err and again.err.count("\n") == 1
    assert {path: path.stat().st_mtime_ns for path in folder.rglob("*")  if path.is_file()} == before
    other = cli("export", str(CAPTURES / "atv71-plc-poll.log"), "--parquet", str(folder), "--bus", "line-1")
    assert other.code == 0 and "added 5 files" in other.err
    assert len(list(folder.rglob("*.parquet"))) == 10
    assert all(path.stat().st_mtime_ns == mtime for path, mtime in before.items())


def test_a_dataset_of_nanosecond_times_is_not_added_to(tmp_path: Path, cli: Callable[..., Any]) -> None:
    """Files of an earlier rtusniff (nanosecond timestamps) and of this one would read as one
    table with mixed units, or not at all: adding to such a dataset is refused, and nothing changes."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    folder = tmp_path / "plant"
    assert cli("export", str(CAPTURES / "xbt-hmi.log"), "--parquet", str(folder), "-q").code == 0
    (old,) = folder.glob("transactions/*/*/*.parquet")
    written = pq.read_table(old)
    position = written.schema.get_field_index("t")
    pq.write_table(written.set_column(position, "t", written.column("t_ns").cast(pa.timestamp("ns", tz="UTC"))), old)
    before = sorted(folder.rglob("*"))
    refused = cli("export", str(CAPTURES / "atv71-plc-poll.log"), "--parquet", str(folder))
    assert refused.code == 11 and refused.err.count("\n") == 1, refused.err
    assert str(old) in refused.err and "timestamp[ns, tz=UTC]" in refused.err and "new folder" in refused.err
    assert sorted(folder.rglob("*")) == before


def test_a_capture_across_midnight_lands_in_two_dates(tmp_path: Path, cli: Callable[..., Any]) -> None:
    capture = tmp_path / "midnight.log"
    lines = ["# rtu-capture v1", "# line: 19200 8N1", "# timing: exact"]
    request, answer = "36 03 00 14 00 05 C1 8A", "36 03 0A 00 54 01 23 01 A3 1A D5 00 9E 21 4C"
    for second in range(-2, 2):
        t = 1_700_006_400 + second  # 2023-11-15 00:00:00 UTC
        lines += [f"{t}.000000000 {request}", f"{t}.010000000 {answer}"]
    capture.write_text("\n".join(lines) + "\n")
    assert cli("export", str(capture), "--parquet", str(tmp_path / "d")).code == 0
    dates = sorted(path.name for path in (tmp_path / "d" / "frames" / "bus=midnight").iterdir())
    assert dates == ["date=2023-11-14", "date=2023-11-15"]
    assert duckdb.sql(f"SELECT count(*) FROM read_parquet('{tmp_path}/d/frames/**/*.parquet')").fetchall() == [(8,)]


def test_a_failed_export_adds_nothing(tmp_path: Path, cli: Callable[..., Any]) -> None:
    damaged = tmp_path / "damaged.log"
    damaged.write_text((CAPTURES / "xbt-hmi.log").read_text() + "1700000009.000000000 zz\n")
    result = cli("export", str(damaged), "--parquet", str(tmp_path / "d"))
    assert result.code != 0 and result.err.count("\n") == 1
    assert not [path for path in (tmp_path / "d").rglob("*") if path.is_file()]


@pytest.mark.parametrize("row_group", [8, 1 << 17])
def test_a_full_disk_in_the_writing_thread_is_one_error_and_adds_nothing(
    tmp_path: Path, cli: Callable[..., Any], monkeypatch: pytest.MonkeyPatch, row_group: int
) -> None:
    """Row groups are written by a thread of their own: its failure (mid-export with small row
    groups, at the end with the default) comes back as the export's one error line, and no file
    of the capture is left in the dataset."""
    import errno

    import pyarrow.parquet as pq

    from sniffer.exports import parquet_export

    def full(self: pq.ParquetWriter, table: object, row_group_size: object = None) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(parquet_export, "ROW_GROUP_ROWS", row_group)
    monkeypatch.setattr(pq.ParquetWriter, "write_table", full)
    result = cli("export", str(CAPTURES / "atv71-plc-poll.log"), "--parquet", str(tmp_path / "d"))
    assert result.code != 0 and result.err.count("\n") == 1, result.err
    assert "No space left on device" in result.err and "Traceback" not in result.err
    assert not [path for path in (tmp_path / "d").rglob("*") if path.is_file()]


@pytest.mark.parametrize(("args", "said"), [
    (["--parquet", "-"], "--parquet takes a folder"),
    (["--bus", "x", "--pcap", "{tmp}/x.pcap"], "--bus names the partition"),
    (["--parquet", "{tmp}/d", "--bus", "a/b"], "--bus 'a/b'"),
])
def test_wrong_dataset_options(tmp_path: Path, cli: Callable[..., Any], args: list[str], said: str) -> None:
    args = [arg.format(tmp=tmp_path) for arg in args]
    result = cli("export", str(CAPTURES / "xbt-hmi.log"), *args)
    assert result.code == 2 and said in result.err


@pytest.mark.skipif(not available(), reason="needs ../shared/real beside the checkout")
def test_real_recordings_export_every_frame(tmp_path: Path, cli: Callable[..., Any]) -> None:
    """Real lines recorded by others (sigrok's test suite): each one a bus of one dataset, whose
    tables hold as many frames and CRC errors as stats counts."""
    folder = tmp_path / "d"
    expected = {}
    for name in RECORDINGS:
        copy = tmp_path / name
        shutil.copy(TEXT / name, copy)
        expected[copy.stem] = json.loads(cli("stats", str(copy), "--format", "json").out)
        assert cli("export", str(copy), "--parquet", str(folder), "-q").code == 0
    frames = dict(duckdb.sql(f"SELECT bus, count(*) FROM read_parquet('{folder}/frames/**/*.parquet', "
                             "hive_partitioning = true) GROUP BY bus").fetchall())
    crc = dict(duckdb.sql(f"SELECT bus, count(*) FROM read_parquet('{folder}/anomalies/**/*.parquet', "
                          "hive_partitioning = true) WHERE kind = 'crc_error' GROUP BY bus").fetchall())
    assert frames == {bus: stats["frames"] for bus, stats in expected.items()}
    assert {bus: crc.get(bus, 0) for bus in expected} == {bus: stats["crc_errors"] for bus, stats in expected.items()}


@pytest.mark.skipif(sys.platform == "win32", reason="SIGTERM cannot be sent to a process on Windows")
def test_sigterm_mid_export_leaves_nothing_in_the_dataset(tmp_path: Path) -> None:
    """``kill PID`` (a service manager stopping a job) while row groups are being written: the
    export stops as on Ctrl-C, says so, exits 143, and its partial files are gone."""
    from benchmarks.bench_memory import write_capture

    capture = tmp_path / "long.mcap"
    write_capture(capture, 600_000)
    dataset = tmp_path / "d"
    process = subprocess.Popen([sys.executable, "-m", "sniffer", "export", str(capture), "--parquet", str(dataset)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not [path for path in dataset.rglob("*.partial")] and time.monotonic() < deadline:
        time.sleep(0.01)
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 143 and err.strip() == "terminated", err
    assert not [path for path in dataset.rglob("*") if path.is_file()]


"""``rtusniff values``: the values of the shipped samples (golden files), the rules for what is
valid, ``--changes``, ``--wide``, and the same rows from CSV and JSON Lines, one or two processes.
After a deliberate change, regenerate with RTUSNIFF_REGENERATE_GOLDEN=1 and review the diff."""

from __future__ import annotations

import csv
import io
import os
import random
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import pytest

from sniffer.encoding.value_rows import ValueChoice
from sniffer.views.values import LONG_COLUMNS, ValuesView
from tests.conftest import ROOT, CliResult

Cli = Callable[..., CliResult]
GOLDEN = Path(__file__).parent / "golden" / "values"
REGENERATE = os.environ.get("RTUSNIFF_REGENERATE_GOLDEN") == "1"
SAMPLES = [("atv71-plc-poll.log", ["--profile", "atv71"]), ("atv312-setup.log", ["--profile", "atv312"]),
           ("xbt-hmi.log", ["--profile", "xbt"]),
           ("nord-uss.log", [])]


def rows(text: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(text)))


@pytest.mark.parametrize(("sample", "options"), SAMPLES, ids=[s for s, _ in SAMPLES])
def test_values_of_the_samples(cli: Cli, sample: str, options: list[str]) -> None:
    result = cli("values", str(ROOT / "captures" / sample), *options)
    assert result.code == 0, result.err
    golden = GOLDEN / f"{Path(sample).stem}.csv"
    if REGENERATE:
        golden.parent.mkdir(parents=True, exist_ok=True)
        golden.write_text(result.out)
    assert result.out == golden.read_text()
    assert result.out.splitlines()[0] == ",".join(LONG_COLUMNS)


def test_csv_and_jsonl_and_both_job_counts_agree(cli: Cli) -> None:
    sample = str(ROOT / "captures" / "atv71-plc-poll.log")
    table = rows(cli("values", sample, "--profile", "atv71", "--jobs", "1").out)
    records = cli("values", sample, "--profile", "atv71", "--format", "jsonl", "--jobs", "2").jsonl()
    assert len(table) == len(records) > 100
    for row, record in zip(table, records, strict=True):
        assert list(record) == list(LONG_COLUMNS)
        spelt = {key: "" if value is None else ("true" if value is True else "false" if value is False
                                                else str(value)) for key, value in record.items()}
        assert spelt == row


def test_what_is_valid(cli: Cli) -> None:
    """Reported: a good answer's reading (not a 16#8000 marker); written: accepted by a good answer."""
    records = cli("values", str(ROOT / "captures" / "atv71-plc-poll.log"), "--profile", "atv71",
                  "--format", "jsonl").jsonl()
    frames = {r["index"]: r for r in cli("analyze", str(ROOT / "captures" / "atv71-plc-poll.log"), "--profile",
                                         "atv71", "--format", "jsonl").jsonl() if r["kind"] == "frame"}
    answers = {r["request_index"]: r for r in frames.values() if r["request_index"] is not None}
    kinds = set()
    for record in records:
        frame = frames[record["index"]]
        if record["kind"] == "reported":
            assert frame["role"] == "response"
            marker = isinstance(record["value"], str) and "non-existent" in record["value"]
            assert record["valid"] == (frame["crc_ok"] and not marker)
            kinds.add(("reported", record["valid"]))
        else:
            answer = answers.get(record["index"])
            accepted = frame["crc_ok"] and answer is not None and answer["role"] == "response" and answer["crc_ok"]
            assert record["valid"] == accepted and record["request_index"] == record["index"]
            kinds.add(("written", record["valid"]))
    assert kinds == {("reported", True), ("reported", False), ("written", True), ("written", False)}


def test_changes_and_wide(cli: Cli) -> None:
    sample = str(ROOT / "captures" / "atv71-plc-poll.log")
    every = rows(cli("values", sample, "--profile", "atv71", "--slave", "2").out)
    changes = rows(cli("values", sample, "--profile", "atv71", "--slave", "2", "--changes").out)
    assert 0 < len(changes) < len(every) and {r["slave"] for r in every} == {"2"}
    last: dict[tuple[str, str], str] = {}
    for row in changes:
        key = (row["address"], row["kind"])
        assert last.get(key) != row["value"]
        last[key] = row["value"]
    wide = rows(cli("values", sample, "--profile", "atv71", "--slave", "2", "--wide").out)
    for row in every:
        [line] = [w for w in wide if w["index"] == row["index"] and w["kind"] == row["kind"]]
        assert line[f"2:{row['code'] or row['address']}"] == row["value"]
    only = rows(cli("values", sample, "--profile", "atv71", "--param", "HSP", "--param", "9001").out)
    assert {r["code"] for r in only} == {"HSP", "ACC"}


def test_bad_options_are_one_line(cli: Cli, tmp_path: Path) -> None:
    with pytest.raises(SystemExit) as refused:  # argparse: its usage line and exit 2
        cli("values", str(ROOT / "captures" / "atv71-plc-poll.log"), "--format", "xlsx")
    assert refused.value.code == 2
    target = tmp_path / "values.csv"
    target.write_text("keep")
    kept = cli("values", str(ROOT / "captures" / "atv71-plc-poll.log"), "-o", str(target))
    assert kept.code != 0 and target.read_text() == "keep"
    written = cli("values", str(ROOT / "captures" / "atv71-plc-poll.log"), "-o", str(target), "--force")
    assert written.code == 0 and f"wrote {target}: csv," in written.err


@pytest.mark.parametrize("zone", ["UTC", "Europe/Paris", "America/St_Johns", "Asia/Kathmandu"])
@pytest.mark.parametrize("mode", ["utc", "local"])
def test_times_are_what_datetime_writes(monkeypatch: pytest.MonkeyPatch, zone: str, mode: str) -> None:
    """A row's time, its second's text made once for the frames of that second, is what
    ``datetime`` writes of each time alone: across seconds, midnights and changes of summer time."""
    if not hasattr(time, "tzset"):
        pytest.skip("time zones are set through tzset (POSIX)")
    monkeypatch.setenv("TZ", zone)
    time.tzset()
    try:
        view = ValuesView(io.StringIO(), ValueChoice(), as_json=False, wide=False, time_mode=mode)
        generator = random.Random(7)
        start = 1_711_846_800 * 10**9  # 2024-03-31 01:00 UTC: Europe's clocks go forward
        times = sorted(start + generator.randrange(-10**13, 10**13) for _ in range(2000))
        times += [start - 1, start, start + 999_999_999, 1_700_006_399_999_999_000, 1_700_006_400_000_000_000]
        for t_ns in times:
            seconds, nanos = divmod(t_ns, 10**9)
            moment = datetime.fromtimestamp(seconds, UTC).replace(microsecond=nanos // 1000)
            expected = (moment.astimezone().isoformat(timespec="microseconds") if mode == "local"
                        else moment.strftime("%Y-%m-%dT%H:%M:%S.%fZ"))
            assert view._time(t_ns) == expected
    finally:
        monkeypatch.delenv("TZ")
        time.tzset()

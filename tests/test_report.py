"""``rtusniff report``: the Markdown of the shipped samples (golden files), the HTML's content
checked against ``stats`` on the samples, a generated hour and the real recordings, what is
escaped, and the errors. The HTML in a real browser is tests/test_report_browser.py.
After a deliberate change, regenerate with RTUSNIFF_REGENERATE_GOLDEN=1 and review the diff."""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import pytest

from benchmarks import generate_capture
from decoders.line import LineSettings
from tests.conftest import ROOT, CliResult
from tests.real_recordings import TEXT

Cli = Callable[..., CliResult]
GOLDEN = Path(__file__).parent / "golden" / "report"
REGENERATE = os.environ.get("RTUSNIFF_REGENERATE_GOLDEN") == "1"
SAMPLES = ["atv71-plc-poll.log", "atv312-setup.log", "xbt-hmi.log", "nord-uss.log", "atv71-plc-poll-usb.mcap"]


class _Anomalies(HTMLParser):
    """The anomaly counts of a report (``data-kind``/``data-count``) and its external references."""

    def __init__(self) -> None:
        super().__init__()
        self.counts: dict[str, int] = {}
        self.references: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        found = dict(attrs)
        if tag == "details" and found.get("data-count"):
            self.counts[str(found["data-kind"])] = int(str(found["data-count"]))
        for name in ("src", "href"):
            value = found.get(name)
            if value and not value.startswith("#"):
                self.references.append(value)


def anomalies_of(html: str) -> _Anomalies:
    parser = _Anomalies()
    parser.feed(html)
    return parser


def expected_counts(stats: dict[str, Any]) -> dict[str, int]:
    """The anomaly counts ``stats --format json`` gives, by the report's kinds."""
    counts = {"crc_error": stats["crc_errors"], **stats["flags"],
              "exception": stats["roles"].get("exception", 0), "noise": stats["roles"].get("noise", 0)}
    return {kind: n for kind, n in counts.items() if n}


@pytest.mark.parametrize("sample", SAMPLES)
def test_markdown_of_the_samples(cli: Cli, sample: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)  # the report names the capture as given: relative, the same in every checkout
    result = cli("report", f"captures/{sample}", "--format", "md")
    assert result.code == 0, result.err
    golden = GOLDEN / f"{Path(sample).name}.md"
    if REGENERATE:
        golden.parent.mkdir(parents=True, exist_ok=True)
        golden.write_text(result.out)
    assert result.out == golden.read_text()


@pytest.mark.parametrize("sample", SAMPLES)
def test_html_anomalies_match_stats(cli: Cli, sample: str, tmp_path: Path) -> None:
    path = str(ROOT / "captures" / sample)
    out = tmp_path / "report.html"
    result = cli("report", path, "-o", str(out))
    assert result.code == 0, result.err
    assert result.err.startswith(f"wrote {out}: html report of ")
    html = out.read_text()
    parsed = anomalies_of(html)
    assert parsed.counts == expected_counts(json.loads(cli("stats", path, "--format", "json").out))
    assert parsed.references == []  # nothing outside the file
    assert "http://" not in html.replace("http://www.w3.org/2000/svg", "") and "https://" not in html


def test_the_report_says_where_it_came_from(cli: Cli, tmp_path: Path) -> None:
    import hashlib

    path = ROOT / "captures" / "atv71-plc-poll.log"
    out = tmp_path / "report.md"
    assert cli("report", str(path), "-o", str(out), "--from", "1s").code == 0
    text = out.read_text()
    assert hashlib.sha256(path.read_bytes()).hexdigest() in text
    assert f"| size | {path.stat().st_size:,} bytes |" in text
    assert "| part read | --from 1s |" in text
    assert f"`rtusniff report {path} -o {out} --from 1s`" in text
    assert "| line | 19200 8E1 |" in text and "| timing | exact:" in text
    whole = cli("report", str(path), "--format", "md", "--profile", "20=atv71").out
    assert "| profiles | --profile 20=atv71; slave 2: atv71 (ATV71HU15M3, identified) |" in whole


def test_a_damaged_answer_is_shown_against_its_good_retry(cli: Cli) -> None:
    text = cli("report", str(ROOT / "captures" / "atv71-plc-poll.log"), "--format", "md").out
    section = text.split("### CRC error: 1")[1].split("###")[0]
    assert "> #25 " in section and "CRC 52 b0 on the wire, b3 71 computed" in section
    assert "good retry of damaged #25: byte 6 50, good 58 (one bit, 0x08)" in section


def test_an_hour_at_19200_stays_small_and_lists_what_stats_counts(cli: Cli, tmp_path: Path) -> None:
    """An hour of a saturated 19200 Bd line with every fault: under 2 MB, charts and all."""
    capture = tmp_path / "hour.mcap"
    generate_capture.write(capture, 420_000, 1, LineSettings.parse("19200 8E1"), "exact", values="steady")
    out = tmp_path / "hour.html"
    assert cli("report", str(capture), "-o", str(out)).code == 0
    html = out.read_text()
    assert out.stat().st_size < 2_000_000
    stats = json.loads(cli("stats", str(capture), "--format", "json").out)
    assert stats["duration_s"] > 3600
    assert anomalies_of(html).counts == expected_counts(stats)
    data = json.loads(re.search(r'id="report-data">(.*?)</script>', html, re.S).group(1))  # type: ignore[union-attr]
    ids = [chart["id"] for chart in data["charts"]]
    assert ids[:4] == ["load", "anomalies", "retries", "latency"]
    assert sum(1 for i in ids if i.startswith("values-")) >= 16  # every drive's values
    assert 500 <= data["n"] <= 1000  # buckets
    assert len(data["distribution"]) == 6  # the 5 slowest slaves and the 11 others


@pytest.mark.parametrize("recording", sorted(path.name for path in TEXT.glob("*.log")) if TEXT.is_dir() else [])
def test_real_recordings(cli: Cli, recording: str, tmp_path: Path) -> None:
    """sigrok's recordings of real flowmeters and an I/O module: the report counts what stats counts."""
    path = str(TEXT / recording)
    out = tmp_path / "real.html"
    assert cli("report", path, "-o", str(out)).code == 0
    stats = json.loads(cli("stats", path, "--format", "json").out)
    assert anomalies_of(out.read_text()).counts == expected_counts(stats)
    markdown = cli("report", path, "--format", "md").out
    assert f"- frames: {stats['frames']:,}" in markdown


def test_text_from_the_capture_is_escaped(cli: Cli, tmp_path: Path) -> None:
    capture = tmp_path / "hostile.log"
    source = (ROOT / "captures" / "atv71-plc-poll.log").read_text()
    capture.write_text(source.replace("# timing: exact\n",
                                      "# timing: exact\n# </script><script>alert(1)</script><b>x\n", 1))
    out = tmp_path / "report.html"
    assert cli("report", str(capture), "-o", str(out)).code == 0, capture.read_text()[:200]
    html = out.read_text()
    assert "alert(1)" in html and "<script>alert" not in html and "<b>x" not in html
    md = cli("report", str(capture), "--format", "md").out
    # Markdown shows it as text in a table cell: every "<" escaped (tests/test_hostile_entrances.py renders it)
    assert r"\</script\>\<script\>alert(1)\</script\>\<b\>x" in md


def test_errors_are_one_line(cli: Cli, tmp_path: Path) -> None:
    sample = str(ROOT / "captures" / "xbt-hmi.log")
    existing = tmp_path / "r.html"
    existing.write_text("keep")
    result = cli("report", sample, "-o", str(existing))
    assert result.code != 0 and "exists; add --force" in result.err and existing.read_text() == "keep"
    broken = tmp_path / "broken.mcap"
    broken.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 40)
    out = tmp_path / "never.html"
    result = cli("report", str(broken), "-o", str(out))
    assert result.code not in (0, 1) and result.err.count("\n") == 1 and result.err.startswith("error: ")
    assert not out.exists()  # a failed report leaves nothing behind
    with pytest.raises(SystemExit) as refused:
        cli("report", sample, "--format", "pdf")
    assert refused.value.code == 2


def test_an_html_report_is_not_poured_onto_a_terminal(tmp_path: Path) -> None:
    import subprocess
    import sys

    pty = pytest.importorskip("pty")
    command = [sys.executable, "-m", "sniffer", "report", str(ROOT / "captures" / "xbt-hmi.log")]
    primary, secondary = pty.openpty()
    done = subprocess.run(command, stdout=secondary, stderr=subprocess.PIPE, check=False, timeout=60)
    os.close(secondary)
    os.close(primary)
    assert done.returncode == 2
    assert b"give -o report.html" in done.stderr and done.stderr.count(b"\n") == 1


def test_the_report_format_follows_the_output_suffix(cli: Cli, tmp_path: Path) -> None:
    out = tmp_path / "ticket.md"
    assert cli("report", str(ROOT / "captures" / "xbt-hmi.log"), "-o", str(out)).code == 0
    assert out.read_text().startswith("# Modbus RTU report: ")


def test_a_baseline_adds_what_compare_says(cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--baseline BEFORE``: the section 'before and after' holds compare's rows and verdicts."""
    monkeypatch.chdir(ROOT)
    before, after = "captures/atv71-plc-poll.log", "captures/atv71-plc-poll-usb.log"
    result = cli("report", after, "--baseline", before, "--format", "md")
    assert result.code == 0, result.err
    golden = GOLDEN / "atv71-plc-poll-usb.log.baseline.md"
    if REGENERATE:
        golden.write_text(result.out)
    assert result.out == golden.read_text()
    compared = json.loads(cli("compare", before, after, "--format", "json").out)
    out = tmp_path / "r.html"
    assert cli("report", after, "--baseline", before, "-o", str(out)).code == 0
    verdicts = re.findall(r'<tr data-verdict="([a-z]+)">', out.read_text())
    assert verdicts == [row["verdict"] for row in compared["per_slave_function"]]
    # A window narrows this capture only: the baseline is read whole.
    windowed = cli("report", after, "--baseline", before, "--format", "md", "--from", "1s").out
    assert "| frames | 52 | 3" in windowed
    result = cli("report", after, "--baseline", str(out), "-o", str(out), "--force")
    assert result.code == 2 and "rtusniff never writes over a capture it reads" in result.err

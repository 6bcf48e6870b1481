"""The HTML report in a real browser (headless Chromium from the system's packages, driven by
Playwright): it draws every chart without a console error, asks nothing of any network, lists the
anomalies ``stats`` counts, and zooms when dragged across. Screenshots go to the test's folder
(``RTUSNIFF_SCREENSHOTS=DIR`` keeps them)."""

from __future__ import annotations

import json
import os
import re
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from benchmarks import generate_capture
from decoders.line import LineSettings
from tests.conftest import ROOT, CliResult
from tests.real_recordings import TEXT
from tests.test_report import expected_counts

Cli = Callable[..., CliResult]
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
playwright_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed")
#: As the probe of this machine kind starts it: no sandbox as root, nothing fetched in the background.
FLAGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
         "--disable-component-update", "--disable-sync"]


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with playwright_api.sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
        yield launched
        launched.close()


class Opened:
    """A report open in a page, with everything the page said and asked for."""

    def __init__(self, browser: Any, path: Path, width: int = 1280) -> None:
        self.page = browser.new_page(viewport={"width": width, "height": 900})
        self.console: list[str] = []
        self.requests: list[str] = []
        self.page.on("console", lambda m: self.console.append(f"{m.type}: {m.text}")
                     if m.type in ("error", "warning") else None)
        self.page.on("pageerror", lambda e: self.console.append(f"pageerror: {e}"))
        self.page.on("request", lambda r: self.requests.append(r.url))
        self.url = path.resolve().as_uri()
        self.page.goto(self.url)
        self.page.wait_for_load_state("load")

    def shot(self, name: str, tmp_path: Path) -> Path:
        path = tmp_path / name
        self.page.screenshot(path=str(path), full_page=True)
        keep = os.environ.get("RTUSNIFF_SCREENSHOTS")
        if keep:
            Path(keep).mkdir(parents=True, exist_ok=True)
            shutil.copy(path, Path(keep) / name)
        return path


def _report(cli: Cli, capture: Path, out: Path) -> Path:
    result = cli("report", str(capture), "-o", str(out))
    assert result.code == 0, result.err
    return out


@pytest.fixture(scope="module")
def steady_capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Half an hour of a saturated 19200 Bd line: 16 drives with values, every fault."""
    capture = tmp_path_factory.mktemp("steady") / "steady.mcap"
    generate_capture.write(capture, 200_000, 1, LineSettings.parse("19200 8E1"), "exact", values="steady")
    return capture


REAL = sorted(TEXT.glob("*.log"))[:2] if TEXT.is_dir() else []
CAPTURES = [ROOT / "captures" / name for name in ("atv71-plc-poll.log", "xbt-hmi.log", "atv71-plc-poll-usb.mcap")]


@pytest.mark.parametrize("capture", CAPTURES + REAL, ids=lambda path: path.name)
def test_captures_render_offline_without_errors(browser: Any, cli: Cli, capture: Path, tmp_path: Path) -> None:
    """The shipped samples and real recordings (sigrok's, of a flowmeter and an I/O module)."""
    sample = capture.name
    opened = Opened(browser, _report(cli, capture, tmp_path / "report.html"))
    assert opened.console == []
    assert opened.requests == [opened.url]  # the file itself, nothing else
    stats = json.loads(cli("stats", str(capture), "--format", "json").out)
    shown = opened.page.eval_on_selector_all(
        "details.kind", "nodes => nodes.map(n => [n.dataset.kind, Number(n.dataset.count)])")
    assert dict(shown) == expected_counts(stats)
    listed = opened.page.eval_on_selector_all("table.anomaly-kinds tr[data-kind] td.num",
                                              "cells => cells.map(c => Number(c.textContent.replace(/,/g, '')))")
    assert listed == [count for _, count in shown]
    charts = opened.page.eval_on_selector_all(
        "svg.plot", "svgs => svgs.map(s => s.querySelectorAll('path').length)")
    assert charts and all(count > 0 for count in charts)
    assert opened.shot(f"{Path(sample).stem}.png", tmp_path).stat().st_size > 20_000


def test_a_long_capture_draws_and_zooms(browser: Any, cli: Cli, steady_capture: Path, tmp_path: Path) -> None:
    opened = Opened(browser, _report(cli, steady_capture, tmp_path / "steady.html"))
    page = opened.page
    assert opened.console == [] and opened.requests == [opened.url]
    data = json.loads(page.text_content("#report-data") or "")
    drawn = page.eval_on_selector_all("figure.chart", "figures => figures.map(f => f.id)")
    ids = [f"chart-{chart['id']}" for chart in data["charts"]]
    # The latency distribution follows the latency over time; the drive values come last, per slave.
    bus = [f"chart-{chart['id']}" for chart in data["charts"] if "group" not in chart]
    assert bus == ["chart-load", "chart-anomalies", "chart-retries", "chart-latency"]
    assert drawn == [*bus, "chart-latency-distribution", *ids[len(bus):]]
    assert len(ids) > 4 + 16
    # 16 slaves: the 5 slowest drawn each, the others as one line, in the latency and its distribution.
    assert [s["name"] for s in data["charts"][3]["series"]][-1] == "11 other slaves"
    assert len(data["distribution"]) == 6 and data["distribution"][-1]["name"] == "11 other slaves, per slave"
    # The distribution's bins said in words: under the pointer, and as a table of every bar that has answers.
    figure = page.locator("#chart-latency-distribution svg")
    figure.scroll_into_view_if_needed()
    box = figure.bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    said = page.text_content("#chart-latency-distribution .readout") or ""
    assert re.fullmatch(r"[\d.]+–[\d.]+ ms, answers: slave \d+ [\d.k]+(; [^;]+ [\d.k]+)+", said), said
    page.click("#chart-latency-distribution details.bins summary")
    heads = page.eval_on_selector_all("table.bins th", "cells => cells.map(c => c.textContent)")
    assert heads == ["latency", *[series["name"] for series in data["distribution"]]]
    rows = page.eval_on_selector_all("table.bins tr",
                                     "rows => rows.slice(1).map(r => [...r.cells].map(c => c.textContent))")
    assert all(re.fullmatch(r"[\d.]+–[\d.]+ ms", row[0]) for row in rows)
    first = data["distribution"][0]
    assert sum(float(row[1] or 0) for row in rows) == sum(first["count"])
    # Values of the first slaves are open, the others fold until asked for.
    assert page.eval_on_selector_all("details.values", "d => d.map(x => x.open)")[:4] == [True, True, True, False]

    def ticks() -> list[str]:
        return page.eval_on_selector_all("#chart-load text.tick", "t => t.map(x => x.textContent)")

    whole = ticks()
    page.locator("#chart-load svg").scroll_into_view_if_needed()
    box = page.locator("#chart-load svg").bounding_box()
    y = box["y"] + box["height"] / 2
    page.mouse.move(box["x"] + box["width"] * 0.40, y)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] * 0.45, y, steps=5)
    page.mouse.up()
    state = page.text_content("#zoom-state") or ""
    assert state != "whole capture" and state.endswith("UTC")
    zoomed = ticks()
    assert zoomed != whole
    # Every time chart follows: the latency chart shows the same span.
    assert page.eval_on_selector_all("#chart-latency text.tick", "t => t.map(x => x.textContent)")[-3:] \
        == zoomed[-3:]
    opened.shot("steady-zoomed.png", tmp_path)
    page.locator("#chart-load svg").dblclick()
    assert page.text_content("#zoom-state") == "whole capture" and ticks() == whole
    # A legend entry hides its series, and shows it again.
    key = page.locator("#chart-latency .legend .key").first
    paths = "#chart-latency path.line"
    before = page.locator(paths).count()
    key.click()
    assert page.locator(paths).count() == before - 1 and "off" in (key.get_attribute("class") or "")
    key.click()
    assert page.locator(paths).count() == before
    opened.shot("steady.png", tmp_path)
    assert opened.console == []


def test_a_narrow_window_keeps_the_report_readable(browser: Any, cli: Cli, tmp_path: Path) -> None:
    """At a phone's width nothing spills out of the page: wide tables scroll inside their box, and a
    capture's long path (in the title, the provenance, the commands) breaks instead of widening it."""
    folder = tmp_path / "a-site-folder-with-a-rather-long-name-as-customers-make-them" / "line-2-cabinet-b"
    folder.mkdir(parents=True)
    capture = folder / "atv71-plc-poll-recorded-during-commissioning.log"
    shutil.copy(ROOT / "captures" / "atv71-plc-poll.log", capture)
    report = _report(cli, capture, tmp_path / "narrow.html")
    opened = Opened(browser, report, width=420)
    overflow = opened.page.evaluate("document.documentElement.scrollWidth - document.documentElement.clientWidth")
    assert overflow <= 0
    assert opened.console == []
    opened.shot("narrow.png", tmp_path)


def test_a_report_of_many_captures(browser: Any, cli: Cli, tmp_path: Path) -> None:
    """``report --each`` of a folder: it draws without a console error, its anomaly counts are
    the merged ``stats --each``, and its frame tables and state changes name each row's file."""
    folder = tmp_path / "site"
    folder.mkdir()
    for capture in CAPTURES:
        shutil.copy(capture, folder / capture.name)
    result = cli("report", "--each", str(folder), "-o", str(tmp_path / "plant.html"), "--profile", "2=atv71")
    assert result.code == 0, result.err
    opened = Opened(browser, tmp_path / "plant.html")
    assert opened.console == [] and opened.requests == [opened.url]
    stats = json.loads(cli("stats", "--each", str(folder), "--format", "json").out)
    shown = opened.page.eval_on_selector_all(
        "details.kind", "nodes => nodes.map(n => [n.dataset.kind, Number(n.dataset.count)])")
    assert dict(shown) == expected_counts(stats)
    heads = opened.page.eval_on_selector_all("table.frames tr:first-child th:first-child, table.states th:first-child",
                                             "cells => cells.map(c => c.textContent)")
    files = opened.page.eval_on_selector_all("table.states td:first-child, table.frames td:first-child",
                                             "cells => cells.map(c => c.textContent)")
    assert "file" in heads and set(files) & {str(folder / capture.name) for capture in CAPTURES}
    charts = opened.page.eval_on_selector_all(
        "svg.plot", "svgs => svgs.map(s => s.querySelectorAll('path').length)")
    assert charts and all(count > 0 for count in charts)
    assert opened.shot("plant.png", tmp_path).stat().st_size > 20_000


def test_the_findings_come_first(browser: Any, cli: Cli, tmp_path: Path) -> None:
    """The first screen says what is wrong: the findings are the first section, the sentences
    ``stats`` gives, each linking to anomalies the page holds; hex wraps between bytes only. The
    README's picture of it is this test's screenshot (``RTUSNIFF_SCREENSHOTS=DIR``)."""
    capture = Path(os.path.relpath(ROOT / "captures" / "atv71-plc-poll.log"))  # as a user names it
    opened = Opened(browser, _report(cli, capture, tmp_path / "report.html"), width=1100)
    headings = opened.page.eval_on_selector_all("h2", "nodes => nodes.map(n => [n.id, n.getBoundingClientRect().top])")
    assert headings[0][0] == "findings" and headings[0][1] < 150
    assert [name for name, _ in headings].index("health") < [name for name, _ in headings].index("anomalies")
    sentences = opened.page.eval_on_selector_all("li.finding", "nodes => nodes.map(n => n.dataset.rule)")
    stats = json.loads(cli("stats", str(capture), "--format", "json").out)
    assert sentences == [finding["rule"] for finding in stats["findings"]]
    text = opened.page.inner_text("ul.findings")
    assert all(finding["sentence"] in text for finding in stats["findings"])
    targets = opened.page.eval_on_selector_all("li.finding a", "links => links.map(a => a.getAttribute('href'))")
    assert targets and all(opened.page.query_selector(target) is not None for target in targets)
    assert opened.page.eval_on_selector("td.hex", "cell => getComputedStyle(cell).wordBreak") == "normal"
    captions = opened.page.eval_on_selector_all("figcaption", "nodes => nodes.map(n => n.textContent)")
    assert "Slave 2: values (Hz)" in captions  # the unit said once (not "values in Hz (Hz)")
    assert not [c for c in captions if re.search(r"in (\S+) \(\1\)", c)], captions
    path = tmp_path / "report-findings.png"
    opened.page.screenshot(path=str(path), full_page=False)
    keep = os.environ.get("RTUSNIFF_SCREENSHOTS")
    if keep:
        shutil.copy(path, Path(keep) / path.name)
    assert opened.console == [] and path.stat().st_size > 20_000


def test_the_slaves_table_reads_at_700_pixels(browser: Any, cli: Cli, tmp_path: Path) -> None:
    """In a 700 px window the slaves table keeps what says whether a slave is well, without a
    scroll bar; the other columns come back on a wide screen."""
    report = _report(cli, ROOT / "captures" / "atv71-plc-poll.log", tmp_path / "report.html")
    narrow = Opened(browser, report, width=700)
    fits = narrow.page.eval_on_selector("table.health", "t => [t.scrollWidth, t.parentElement.clientWidth]")
    assert fits[0] <= fits[1], fits
    shown = narrow.page.eval_on_selector_all("table.health th", "ths => ths.filter(th => th.offsetParent)"
                                                                 ".map(th => th.textContent)")
    assert shown == ["slave", "requests", "answers", "exceptions", "CRC errors", "timeouts", "error rate", "p95 ms"]
    wide = Opened(browser, report, width=1280)
    assert len(wide.page.eval_on_selector_all("table.health th", "ths => ths.filter(th => th.offsetParent)")) == 14
    assert narrow.console == [] and wide.console == []

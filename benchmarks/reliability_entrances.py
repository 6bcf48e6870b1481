"""The reliability benchmark's families for the entrances added last (issue 69): line names, logic
analyzer and pcap readers, sealed MCAP metadata, outputs over inputs, the Markdown report, the
dataset, bounds and following. Each run is counted by :func:`benchmarks.bench_reliability.rtusniff`;
a run that gives a result other than what its input holds counts as **altered**, one that changes
or removes a file it read as **destroyed**.
"""

from __future__ import annotations

import hashlib
import json
import os
import random
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from benchmarks.bench_reliability import ROOT, TIMEOUT_S, Family, rtusniff
from benchmarks.hostile_inputs import (
    DEVICE,
    FIELDS,
    FORGED,
    HOSTILE_ANNOTATION_LINES,
    HOSTILE_NAMES,
    HOSTILE_SESSION_METADATA,
    T0,
    block_at,
    crafted_mcap,
    hostile_pcaps,
    many_registers,
    sigrok_session,
    two_line_mcap,
)

SAMPLE = ROOT / "captures" / "atv71-plc-poll.log"
SAMPLE_MCAP = ROOT / "captures" / "atv71-plc-poll.mcap"


def _digest(path: Path) -> str | None:
    return hashlib.sha256(path.read_bytes()).hexdigest() if path.exists() else None


def _guarded(family: Family, inputs: list[Path], scratch: Path, *argv: str, stdin: Path | None = None) -> None:
    """A run that must leave ``inputs`` as they were."""
    before = [_digest(path) for path in inputs]
    rtusniff(family, scratch, *argv, stdin=stdin)
    for path, digest in zip(inputs, before, strict=True):
        if _digest(path) != digest:
            family.destroyed += 1
            family.problems.append(f"destroyed {path.name}: {' '.join(argv)}")


def line_names(scratch: Path, *, quick: bool) -> Family:
    """Names a reader accepts, through ``convert`` to text and back: no forged line, the same names."""
    family = Family("line names")
    for number, names in enumerate(HOSTILE_NAMES[:3] if quick else HOSTILE_NAMES):
        source = two_line_mcap(scratch / f"names-{number}.mcap", names)
        text = scratch / f"names-{number}.log"
        text.unlink(missing_ok=True)
        run = rtusniff(family, scratch, "convert", str(source), str(text), "-q")
        if run is None or run.code != 0:
            continue
        data = [line for line in text.read_text().splitlines() if not line.startswith("#")]
        back = rtusniff(family, scratch, "analyze", str(text), "--format", "jsonl")
        channels = [json.loads(line).get("channel") for line in (back.out if back else "").splitlines()
                    if '"kind":"frame"' in line]
        if FORGED in data or channels != [names[0], names[-1]]:
            family.altered += 1
            family.problems.append(f"altered: names {names!r} came back as {channels!r}")
    return family


def logic_and_pcap_readers(scratch: Path, *, quick: bool) -> Family:
    """Hostile sigrok sessions (bad metadata, a 512 MiB metadata, a 1 GiB sample file), pcaps
    (4 GiB and 60 MiB records, timestamp resolutions), sigrok-cli lines, Saleae values and times."""
    family = Family("logic, pcap")
    cases = 2 if quick else None  # a slice for CI: the unit tests read every case in-process
    for number, (metadata, _) in enumerate(HOSTILE_SESSION_METADATA[:cases]):
        path = sigrok_session(scratch / f"session-{number}.sr", metadata)
        rtusniff(family, scratch, "stats", str(path), "--line", "9600 8N1", "--channel", "RX")
    if not quick:
        for path in (sigrok_session(scratch / "metadata-bomb.sr", DEVICE, comment_mib=512),
                     sigrok_session(scratch / "sample-bomb.sr", DEVICE, bytes([0xFF]) * 2**20, repeats=2**10)):
            rtusniff(family, scratch, "stats", str(path), "--line", "9600 8N1", "--channel", "RX")
    for _, name, content, _, _ in hostile_pcaps()[::3] if quick else hostile_pcaps():
        path = scratch / name
        path.write_bytes(content)
        rtusniff(family, scratch, "stats", str(path), "--line", "19200 8E1")
    for number, (line, _) in enumerate(HOSTILE_ANNOTATION_LINES[:cases]):
        path = scratch / f"annotations-{number}.ann"
        path.write_text('10-20 uart-1: rx-data: "02"\n' + line + "\n", encoding="utf-8")
        rtusniff(family, scratch, "stats", str(path), "--line", "9600 8N1")
    for number, value in enumerate(["0x1_2", "0o17", "0b1_01", "٧٢", "nan"][:cases]):
        path = scratch / f"saleae-{number}.csv"
        path.write_text(f'name,type,start_time,duration,data\n"Async Serial","data",0.001,0.0005,{value}\n'
                        if value != "nan" else "Time [s],Channel 0\n0.0,1\n0.001,0\nnan,1\n", encoding="utf-8")
        run = rtusniff(family, scratch, "stats", str(path), "--line", "9600 8N1")
        if run is not None and run.code == 0:
            family.altered += 1
            family.problems.append(f"altered: Saleae {value!r} read as a byte or a time")
    return family


def mcap_metadata(scratch: Path, flips: int, rng: random.Random) -> Family:
    """Bit flips inside the sealed ``rtusniff.capture`` record (a run that reads must read the very
    same capture), notes that are no text, and late notes."""
    family = Family("MCAP metadata")
    original = SAMPLE_MCAP.read_bytes()
    start = original.index(b"rtusniff.capture") - 13
    end = start + 9 + int.from_bytes(original[start + 1 : start + 9], "little")
    whole = scratch / "whole.log"
    whole.unlink(missing_ok=True)
    rtusniff(family, scratch, "convert", str(SAMPLE_MCAP), str(whole), "-q")
    for _ in range(flips):
        data = bytearray(original)
        position = rng.randrange(start, end)
        data[position] ^= 1 << rng.randrange(8)
        flipped, text = scratch / "flipped.mcap", scratch / "flipped.log"
        flipped.write_bytes(bytes(data))
        text.unlink(missing_ok=True)
        run = rtusniff(family, scratch, "convert", str(flipped), str(text), "-q")
        if run is not None and run.code == 0 and text.read_bytes() != whole.read_bytes():
            family.altered += 1
            family.problems.append(f"altered: metadata bit flipped at byte {position} read with exit 0")
    for notes in ("[" * 100_000, '["\\ud800"]'):
        path = crafted_mcap(scratch / "notes.mcap", {**FIELDS, "notes": notes}, [block_at(T0)])
        rtusniff(family, scratch, "analyze", str(path), "--format", "jsonl")
        rtusniff(family, scratch, "report", str(path), "--format", "md")
    return family


def outputs_over_inputs(scratch: Path, *, quick: bool) -> Family:
    """Every way an output could land on an input: a folder read with ``--each``, standard input
    redirected from the output, a followed rotation; and a failed run's output."""
    family = Family("outputs, inputs")
    folder = scratch / "site"
    folder.mkdir(exist_ok=True)
    inside = folder / "x.log"
    shutil.copy(SAMPLE, inside)
    for command in ("stats", "report"):
        _guarded(family, [inside], scratch, command, "--each", str(folder), "-o", str(inside), "--force")
    redirected = [["analyze", "-", "-o"], ["stats", "-", "-o"], ["values", "-", "-o"], ["report", "-", "-o"],
                  ["export", "-", "--mcap"]]
    for argv in redirected[::2] if quick else redirected:
        _guarded(family, [inside], scratch, *argv, str(inside), "--force", stdin=inside)
    rotation = folder / "x-0002.log"
    shutil.copy(SAMPLE, rotation)
    _guarded(family, [rotation], scratch, "analyze", "--follow", str(inside), "-o", str(rotation), "--force")
    broken = scratch / "broken.log"
    broken.write_text("# rtu-capture v1\n# line: 19200 8E1\n1.0 01 03 00 00 00 01 84 0A\n2.0 01 ZZ\n")
    for command in ("analyze",) if quick else ("analyze", "stats", "values"):
        out = scratch / f"failed-{command}.txt"
        out.unlink(missing_ok=True)
        run = rtusniff(family, scratch, command, str(broken), "-o", str(out))
        if run is not None and run.code != 0 and out.exists():
            family.altered += 1
            family.problems.append(f"altered: a failed {command} left {out.name}")
    return family


def reports_and_datasets(scratch: Path) -> Family:
    """A Markdown report of hostile notes renders nothing of theirs; a capture joins a dataset once."""
    family = Family("report, dataset")
    hostile = scratch / "hostile.log"
    hostile.write_text(SAMPLE.read_text().replace(
        "# timing: exact\n", "# timing: exact\n# <img src=http://e.x/p> ![i](http://e.x/q) [l](http://e.x) `c`\n", 1))
    run = rtusniff(family, scratch, "report", str(hostile), "--format", "md")
    if run is not None and run.code == 0:
        from markdown_it import MarkdownIt  # rich brings it

        rendered = MarkdownIt("commonmark").enable("table").render(run.out)
        # rtusniff's own links go from a finding to its anomalies in the same report (#anchor).
        if "<img" in rendered or any(not link.startswith("#") for link in re.findall(r'<a href="([^"]*)"', rendered)):
            family.altered += 1
            family.problems.append("altered: the Markdown report renders an image or a link from the capture")
    dataset = scratch / "plant"
    shutil.rmtree(dataset, ignore_errors=True)
    copy = scratch / "copy.log"
    shutil.copy(SAMPLE, copy)
    for argv in ([str(SAMPLE)], [str(SAMPLE), "--bus", "other"], [str(copy)]):
        rtusniff(family, scratch, "export", *argv, "--parquet", str(dataset), "-q")
    for bus in ("..", "a\nb", "a\x1b[2Jb"):
        rtusniff(family, scratch, "export", str(copy), "--parquet", str(dataset), "--bus", bus, "-q")
    import pyarrow.dataset as ds

    rows = ds.dataset(dataset / "frames", partitioning="hive").count_rows() if (dataset / "frames").exists() else 0
    if rows != 52:
        family.altered += 1
        family.problems.append(f"altered: the dataset holds {rows} frame rows for a capture of 52")
    return family


def bounds(scratch: Path) -> Family:
    """Outputs and work that grow with what the input holds: ``values --wide`` of ever new
    registers, ``compare`` of thousands of slave/function pairs."""
    family = Family("bounds")
    wide = many_registers(scratch / "many.log", 400)
    rtusniff(family, scratch, "values", str(wide), "--wide", "-o", str(scratch / "wide.csv"), "--force")
    pairs = [scratch / f"pairs-{side}.log" for side in "ab"]
    for seed, path in enumerate(pairs):
        _pairs_capture(path, seed, 30_000)
    rtusniff(family, scratch, "compare", str(pairs[0]), str(pairs[1]), "--format", "json")
    return family


def _pairs_capture(path: Path, seed: int, requests: int) -> None:
    """Requests to any of 247 slaves with any of 127 function codes: some 6 000 pairs."""
    from decoders.crc import crc_bytes

    rng = random.Random(seed)
    lines = ["# rtu-capture v1", "# line: 115200 8N1", "# timing: host"]
    for number in range(requests):
        body = bytes([rng.randrange(1, 248), rng.randrange(1, 128), 0, 0, 0, 1])
        lines.append(f"{1_700_000_000 + number * 0.002:.6f} {(body + crc_bytes(body)).hex()}")
    path.write_text("\n".join(lines) + "\n")


def following(scratch: Path) -> Family:
    """``stats --follow`` of a text recording changed under it: it must end (a text recording is
    otherwise followed until Ctrl-C), within the benchmark's timeout."""
    family = Family("following")
    for change in ("truncated", "replaced", "removed"):
        path = scratch / f"followed-{change}.log"
        shutil.copy(SAMPLE, path)
        family.runs += 1
        process = subprocess.Popen([sys.executable, "-m", "sniffer", "stats", "--follow", str(path)],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=scratch)
        time.sleep(2.0)
        if change == "truncated":
            os.truncate(path, 40)
        elif change == "replaced":
            other = scratch / "other.log"
            shutil.copy(SAMPLE, other)
            os.replace(other, path)
        else:
            path.unlink()
        try:
            _, err = process.communicate(timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate()
            family.hangs += 1
            family.problems.append(f"hang: stats --follow of a file {change} under it")
            continue
        if b"following stopped" not in err:
            family.altered += 1
            family.problems.append(f"altered: a file {change} under --follow was not said")
    return family


def families(scratch: Path, per_family: int, rng: random.Random, *,
             quick: bool) -> list[tuple[str, Callable[[], Family]]]:
    """These families by name, each run when called."""
    runs: list[tuple[str, Callable[[], Family]]] = [
        ("line names", lambda: line_names(scratch, quick=quick)),
        ("logic, pcap", lambda: logic_and_pcap_readers(scratch, quick=quick)),
        ("MCAP metadata", lambda: mcap_metadata(scratch, 1 if quick else per_family * 5, rng)),
        ("outputs, inputs", lambda: outputs_over_inputs(scratch, quick=quick)),
        ("report, dataset", lambda: reports_and_datasets(scratch))]
    if not quick:
        runs += [("bounds", lambda: bounds(scratch)), ("following", lambda: following(scratch))]
    return runs

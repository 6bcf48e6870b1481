"""Every output of every command on every input, written to one folder, so that two trees'
outputs compare with ``diff -r``: the proof that a change to decoding changed no output.

    python -m benchmarks.output_snapshot OUT_DIR [--rev REV] [--frames 20000] [--quick]

Inputs: the shipped samples (``captures/``), the real recordings (``../shared/real/``: sigrok-cli
text captures, and the sigrok Modbus session), and generated captures of each benchmark traffic
(``benchmarks/bench_memory.py``, ``--frames`` frames each). Outputs per input: the table into a
pipe (with and without ``--registers``, with a ``--filter``), JSONL (with and without a filter),
``stats`` (table and JSON), ``values`` (CSV and JSONL), the Markdown and HTML reports, and the
MCAP, pcap, pcapng and Parquet exports (each MCAP and Parquet file read back into a text form:
their bytes carry the writing library's version). The output folder, the generated captures'
folder and rtusniff's version are written alike in every run.

``--rev REV``: the same outputs of commit ``REV`` (a temporary ``git worktree``) are written to
``OUT_DIR/REV`` beside this checkout's ``OUT_DIR/here``, and the two are compared: the command
prints the differing files and exits 1 where any differ. ``--quick``: the samples and real
recordings only.
"""

from __future__ import annotations

import argparse
import filecmp
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
REAL = ROOT.parent / "shared" / "real"
TRAFFICS = ("polling", "mixed", "steady", "coils", "wide")
#: What differs between trees though their outputs agree: the tool's version.
VERSION = re.compile(rb"rtusniff \d+\.\d+\.\d+\S*")
SIZE = re.compile(rb"\b\d+(\.\d+)? [kMG]?B\b")


def inputs(scratch: Path, frames: int, quick: bool) -> Iterator[tuple[str, Path, list[str]]]:
    """(name, capture, extra options) of every input."""
    for capture in sorted((ROOT / "captures").glob("*.log")) + sorted((ROOT / "captures").glob("*.mcap")):
        yield capture.name, capture, []
    for capture in sorted((REAL / "sigrok-cli-text").glob("*.log")):
        yield f"real-{capture.name}", capture, []
    sessions = REAL / "sigrok" / "uart" / "modbus_rtu"
    for capture in sorted(sessions.glob("flowmeter/*.sr")):
        yield f"real-{capture.name}", capture, ["--line", "9600 8N1"]
    two_probes = sessions / "brainchild_io_16do" / "brainchild-io-16do.sr"
    if two_probes.is_file():
        yield f"real-{two_probes.name}", two_probes, ["--line", "19200 8E1", "--channel", "0", "--channel", "1"]
    if quick:
        return
    from benchmarks.bench_memory import benchmark_capture  # numpy and the writers: only here

    for traffic in TRAFFICS:
        yield f"generated-{traffic}", benchmark_capture(scratch, frames, traffic), []


def runs(capture: Path, out: Path) -> Iterator[tuple[str, list[str]]]:
    """(output file name, rtusniff arguments) of every output of one input."""
    c = str(capture)
    yield "table.txt", ["analyze", c, "--width", "200"]
    yield "table-piped.txt", ["analyze", c]
    yield "table-registers.txt", ["analyze", c, "--width", "200", "--registers", "f32", "--word-order", "little"]
    yield "table-filter.txt", ["analyze", c, "--width", "200", "--filter", "role=response"]
    yield "frames.jsonl", ["analyze", c, "--format", "jsonl"]
    yield "frames-filter.jsonl", ["analyze", c, "--format", "jsonl", "--filter", "role=response"]
    yield "stats.txt", ["stats", c, "--width", "200"]
    yield "stats.json", ["stats", c, "--format", "json"]
    yield "values.csv", ["values", c]
    yield "values.jsonl", ["values", c, "--format", "jsonl"]
    yield "report.md", ["report", c, "-o", str(out / "report.md")]
    yield "report.html", ["report", c, "-o", str(out / "report.html")]
    yield "export.mcap", ["export", c, "--mcap", str(out / "export.mcap"), "-q"]
    yield "export.pcap", ["export", c, "--pcap", str(out / "export.pcap"), "-q"]
    yield "export.pcapng", ["export", c, "--pcap", str(out / "export.pcapng"), "-q"]
    yield "export.rrd", ["export", c, "--rrd", str(out / "export.rrd"), "-q"]
    yield "parquet", ["export", c, "--parquet", str(out / "parquet"), "--bus", "bus", "-q"]


def snapshot(tree: Path, out: Path, scratch: Path, frames: int, quick: bool) -> None:
    """Every output of rtusniff run from ``tree``, under ``out`` (the inputs are this checkout's,
    whichever tree runs: outputs name their input)."""
    env = {**os.environ, "PYTHONPATH": str(tree), "COLUMNS": "200"}
    for name, capture, extra in inputs(scratch, frames, quick):
        folder = out / name
        folder.mkdir(parents=True, exist_ok=True)
        for output, argv in runs(capture, folder):
            done = subprocess.run([sys.executable, "-m", "sniffer", *argv, *extra], cwd=tree, env=env,
                                  capture_output=True, check=False)
            written = folder / output
            if not written.exists():
                written.write_bytes(done.stdout)
            said = _stable(done.stderr, folder, scratch)
            (folder / f"{output}.exit").write_bytes(b"%d\n%s" % (done.returncode, said))
            if written.is_dir():
                _parquet_as_text(written)
            elif output.endswith(".mcap") and done.returncode == 0:
                written = _mcap_as_text(written)
            elif output.endswith(".rrd") and done.returncode == 0:
                written = _rrd_as_text(written)
            for text in [written] if written.is_file() else sorted(written.rglob("*.txt")):
                text.write_bytes(_stable(text.read_bytes(), folder, scratch))
        print(f"output_snapshot: {tree.name or tree}: {name}", file=sys.stderr)


def _stable(text: bytes, folder: Path, scratch: Path) -> bytes:
    """``text`` with the output and scratch folders (generated captures) and the tool's version
    written alike in every run."""
    text = text.replace(str(folder).encode(), b"OUT").replace(str(scratch).encode(), b"SCRATCH")
    # A written file's size, as the commands tell it, moves with the length of the folder's name.
    return SIZE.sub(b"SIZE", VERSION.sub(b"rtusniff VERSION", text))


def _parquet_as_text(folder: Path) -> None:
    """Each Parquet file of ``folder`` replaced by its schema and rows as text (a file's bytes
    carry the writer's version)."""
    import pyarrow as pa  # only for exports
    import pyarrow.parquet as pq

    for path in sorted(folder.rglob("*.parquet")):
        table = pq.read_table(path)
        # Nanosecond times as integers: Python's datetime holds microseconds.
        columns = [column.cast(pa.int64()) if pa.types.is_timestamp(column.type) else column
                   for column in table.columns]
        rows = pa.table(columns, names=table.column_names).to_pylist()
        metadata = sorted((table.schema.metadata or {}).items())
        path.with_suffix(".txt").write_text(f"{table.schema.remove_metadata()}\n{metadata!r}\n"
                                            + "\n".join(map(repr, rows)) + "\n")
        path.unlink()
    for path in sorted(folder.rglob("*")):
        if path.is_file() and path.suffix != ".txt":
            path.unlink()


def _mcap_as_text(path: Path) -> Path:
    """An MCAP file replaced by its records as text (its bytes carry the writer's version)."""
    from mcap.reader import make_reader  # only for exports

    lines: list[bytes] = []
    with path.open("rb") as stream:
        reader = make_reader(stream)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            name = schema.name if schema is not None else ""
            lines.append(b"%s %s %d %d %s" % (channel.topic.encode(), name.encode(), message.log_time,
                                                message.publish_time, message.data))
        stream.seek(0)
        for metadata in make_reader(stream).iter_metadata():
            lines.extend(b"metadata %s %s=%s" % (metadata.name.encode(), key.encode(), value.encode())
                         for key, value in sorted(metadata.metadata.items()))
        stream.seek(0)
        for attachment in make_reader(stream).iter_attachments():
            lines.append(b"attachment %s %d %s" % (attachment.name.encode(), attachment.log_time, attachment.data))
    text = path.with_suffix(".mcap.txt")
    text.write_bytes(b"\n".join(lines))
    path.unlink()
    return text


def _rrd_as_text(path: Path) -> Path:
    """A Rerun recording replaced by its chunks as text: each chunk with a timeline in the order
    written, with its rows; the static ones (series styles) sorted, as the SDK sends them in an
    order of its own from run to run; the recording's start (the wall clock) left out."""
    import pyarrow as pa  # only for exports

    from sniffer.exports.rerun_sdk import rr

    timed: list[str] = []
    static: list[str] = []
    for chunk in rr.chunk.RrdReader(str(path)).stream().to_chunks():
        batch = chunk.to_record_batch()
        columns = [column.cast(pa.int64()) if pa.types.is_timestamp(column.type) else column
                   for column in batch.columns]
        rows = pa.RecordBatch.from_arrays(columns, names=batch.schema.names).to_pylist()
        lines = [f"{chunk.entity_path} {sorted(chunk.timeline_names)}"]
        lines += [repr({key: value for key, value in sorted(row.items())
                        if "RowId" not in key and key != "RecordingInfo:start_time"}) for row in rows]
        (timed if chunk.timeline_names else static).append("\n".join(lines))
    text = path.with_suffix(".rrd.txt")
    text.write_text("\n".join([*timed, *sorted(static)]) + "\n")
    path.unlink()
    return text


def differing(left: Path, right: Path) -> list[str]:
    """The files that differ between two snapshots, or are in one only."""
    found: list[str] = []

    def walk(compared: filecmp.dircmp[str], prefix: str) -> None:
        found.extend(f"{prefix}{name} (only in {left.name})" for name in compared.left_only)
        found.extend(f"{prefix}{name} (only in {right.name})" for name in compared.right_only)
        _, mismatch, errors = filecmp.cmpfiles(compared.left, compared.right, compared.common_files, shallow=False)
        found.extend(prefix + name for name in mismatch + errors)
        for name, sub in sorted(compared.subdirs.items()):
            walk(sub, f"{prefix}{name}/")

    walk(filecmp.dircmp(left, right), "")
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--rev", help="also the outputs of this commit, and compare")
    parser.add_argument("--frames", type=int, default=20_000, help="frames of each generated capture")
    parser.add_argument("--quick", action="store_true", help="samples and real recordings only")
    args = parser.parse_args()
    if args.out.exists() and any(args.out.iterdir()):
        sys.exit(f"output_snapshot: {args.out} is not empty")
    scratch = Path(tempfile.mkdtemp(prefix="snapshot-"))
    try:
        snapshot(ROOT, args.out / "here", scratch, args.frames, args.quick)
        if args.rev is None:
            return
        worktree = scratch / "tree"
        subprocess.run(["git", "worktree", "add", "--detach", str(worktree), args.rev], cwd=ROOT, check=True,
                       capture_output=True)
        try:
            snapshot(worktree, args.out / args.rev, scratch, args.frames, args.quick)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(worktree)], cwd=ROOT, check=False)
        different = differing(args.out / args.rev, args.out / "here")
        for name in different:
            print(f"differs: {name}")
        print(f"output_snapshot: {len(different)} file(s) differ between {args.rev} and this checkout")
        sys.exit(1 if different else 0)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    main()

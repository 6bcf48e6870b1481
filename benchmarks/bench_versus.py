"""This checkout against an earlier commit, side by side: the commands alternate; prints a table.

    python -m benchmarks.bench_versus REV [--frames 1000000] [--runs 2] [--keep DIR]
                                          [--threads | --instructions] [--only stats:steady jsonl:coils ...]

On a shared machine whose speed drifts by a quarter within minutes, two passes made minutes
apart say little about a change; here every command runs on ``REV`` and on this checkout one
after the other, ``--runs`` times, so both see the same state of the machine. ``REV`` is checked
out into a temporary ``git worktree`` (removed at the end) and both are byte-compiled; each
command runs in its own process from its tree (``python -m sniffer`` with the tree as the
working directory, which puts that tree's packages first), output to ``/dev/null``. Captures are
the benchmark captures of ``benchmarks/bench_memory.py``. The table gives every run's seconds
and the ratio of the medians (earlier / this checkout: above 1 is faster now).

``--threads``: each command runs under :mod:`benchmarks.thread_clock`, and a second line per
command gives the medians of where its CPU went: the main thread (which annotates and writes,
and bounds the exports), the decoding process, the Parquet writing thread.

``--instructions``: instead of seconds, the instructions each command executes (billions),
counted by valgrind's callgrind in every process (the decoding process's on a second line), with
``PYTHONHASHSEED=0``. A machine's load and clock move seconds by ±10 % here; they do not move
these counts, which differ by a few hundredths of a percent from run to run: a change of 2 %
shows. One run takes about 60 s for 100 000 frames (``--frames 100000``); instructions are not
time (a cache miss costs more than an addition), so a change that counts less is then timed.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_memory import benchmark_capture

ROOT = Path(__file__).resolve().parent.parent
#: (command, traffic) pairs timed unless --only names others.
DEFAULT_CASES = ("stats:steady", "stats:polling", "jsonl:mixed", "jsonl:polling", "jsonl:coils", "mcap:mixed",
                 "mcap:polling", "mcap:coils")
COMMANDS = ("stats", "jsonl", "table", "values", "filtered", "mcap", "parquet")
TRAFFICS = ("steady", "mixed", "polling", "coils", "wide")


def _argv(command: str, capture: Path, scratch: Path) -> list[str]:
    """The rtusniff arguments of a benchmark command (a new output under ``scratch`` where it writes one)."""
    if command == "stats":
        return ["stats", str(capture)]
    if command == "jsonl":
        return ["analyze", str(capture), "--format", "jsonl"]
    if command == "table":
        return ["analyze", str(capture)]
    if command == "values":
        return ["values", str(capture), "--format", "csv"]
    if command == "filtered":  # the piped table narrowed to answers
        return ["analyze", str(capture), "--filter", "role=response"]
    output = scratch / f"out-{time.monotonic_ns()}"
    if command == "mcap":
        return ["export", str(capture), "--mcap", f"{output}.mcap", "-q"]
    return ["export", str(capture), "--parquet", str(output), "-q"]


def _timed(tree: Path, argv: list[str], *, threads: bool = False) -> dict[str, float]:
    """The wall time of ``rtusniff ARGV`` run from ``tree`` (``threads``: also its CPU by thread,
    :mod:`benchmarks.thread_clock`)."""
    start = time.perf_counter()
    command = [sys.executable, str(ROOT / "benchmarks" / "thread_clock.py")] if threads else [
        sys.executable, "-m", "sniffer"]
    done = subprocess.run([*command, *argv], cwd=tree, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          check=False, env={**os.environ, "PYTHONPATH": str(tree)})
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"bench_versus: rtusniff {' '.join(argv)} in {tree} failed: {done.stderr.decode().strip()}")
    clocks: dict[str, float] = json.loads(done.stderr.decode().splitlines()[-1]) if threads else {}
    return {**clocks, "wall": seconds}


def _counted(tree: Path, argv: list[str], scratch: Path) -> dict[str, float]:
    """The instructions (billions) ``rtusniff ARGV`` run from ``tree`` executes: ``wall`` all
    its processes', ``children`` those of the processes it started (callgrind, one count per
    process)."""
    counts = scratch / f"callgrind-{time.monotonic_ns()}"
    counts.mkdir()
    with subprocess.Popen(["valgrind", "--tool=callgrind", "--trace-children=yes",
                           f"--callgrind-out-file={counts}/%p", sys.executable, "-m", "sniffer", *argv],
                          cwd=tree, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          env={**os.environ, "PYTHONPATH": str(tree), "PYTHONHASHSEED": "0"}) as run:
        _, errors = run.communicate()
    if run.returncode != 0:
        sys.exit(f"bench_versus: rtusniff {' '.join(argv)} under callgrind in {tree} failed: "
                 f"{errors.decode().strip()[-500:]}")
    # valgrind runs the command in its own process: the file named by its id is the command's.
    by_process = {int(path.name): callgrind_total(path.read_text()) for path in counts.iterdir()}
    shutil.rmtree(counts)
    total = sum(by_process.values())
    return {"wall": total / 1e9, "children": (total - by_process[run.pid]) / 1e9}


def callgrind_total(text: str) -> int:
    """The instructions a callgrind output file counts (its ``totals:`` line, else its ``summary:``)."""
    found: dict[str, int] = {}
    for line in text.splitlines():
        key, _, value = line.partition(":")
        if key in ("totals", "summary") and value.strip():
            found[key] = int(value.split()[0])
    if not found:
        raise ValueError("no totals: or summary: line in a callgrind output")
    return found.get("totals", found.get("summary", 0))


def _where(figures: list[dict[str, float]]) -> str:
    """The medians of the main thread's, the decoding process's and the writing thread's CPU."""
    return " / ".join(f"{statistics.median(run[key] for run in figures):.2f}" for key in ("main", "children", "writer"))


def _case(text: str) -> tuple[str, str]:
    command, _, traffic = text.partition(":")
    if command not in COMMANDS or traffic not in TRAFFICS:
        raise argparse.ArgumentTypeError(f"{text!r}: expected COMMAND:TRAFFIC, COMMAND one of {', '.join(COMMANDS)}, "
                                         f"TRAFFIC one of {', '.join(TRAFFICS)}")
    return command, traffic


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("rev", help="the commit to compare with (anything git rev-parse takes)")
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--keep", type=Path, help="keep (and reuse) the generated captures in this folder")
    parser.add_argument("--threads", action="store_true",
                        help="also the CPU of the main thread, the decoding process and the writing thread")
    parser.add_argument("--instructions", action="store_true",
                        help="instructions executed (callgrind; billions) instead of seconds")
    parser.add_argument("--only", type=_case, nargs="+", default=[_case(c) for c in DEFAULT_CASES],
                        metavar="COMMAND:TRAFFIC")
    args = parser.parse_args()
    commit = subprocess.run(["git", "rev-parse", "--short", args.rev], cwd=ROOT, capture_output=True, text=True,
                            check=True).stdout.strip()
    with tempfile.TemporaryDirectory() as tmp:
        scratch, earlier = Path(tmp), Path(tmp) / "earlier"
        subprocess.run(["git", "worktree", "add", "--detach", "-q", str(earlier), commit], cwd=ROOT, check=True)
        try:
            for tree in (earlier, ROOT):
                subprocess.run([sys.executable, "-m", "compileall", "-q", "sniffer", "decoders"], cwd=tree,
                               stdout=subprocess.DEVNULL, check=True)
            unit = "billions of instructions (callgrind)" if args.instructions else "seconds"
            print(f"{args.frames:,} frames, {args.runs} runs each, alternating; {unit}")
            print(f"{'command':<8} {'traffic':<8} {commit:>20} {'this checkout':>20} {'ratio':>6}")
            for command, traffic in args.only:
                capture = benchmark_capture(args.keep or scratch, args.frames, traffic)
                runs: dict[Path, list[dict[str, float]]] = {earlier: [], ROOT: []}
                for _ in range(args.runs):
                    for tree in (earlier, ROOT):
                        argv = _argv(command, capture, scratch)
                        runs[tree].append(_counted(tree, argv, scratch) if args.instructions else
                                          _timed(tree, argv, threads=args.threads))
                times = {tree: [run["wall"] for run in figures] for tree, figures in runs.items()}
                ratio = statistics.median(times[earlier]) / statistics.median(times[ROOT])
                digits, ratio_digits = (3, 4) if args.instructions else (2, 2)
                shown = {tree: ", ".join(f"{s:.{digits}f}" for s in figures) for tree, figures in times.items()}
                print(f"{command:<8} {traffic:<8} {shown[earlier]:>20} {shown[ROOT]:>20} {ratio:>6.{ratio_digits}f}")
                if args.instructions:
                    children = {tree: ", ".join(f"{run['children']:.3f}" for run in figures)
                                for tree, figures in runs.items()}
                    print(f"{'':<8} {'children':<8} {children[earlier]:>20} {children[ROOT]:>20}")
                if args.threads:
                    where = {tree: _where(figures) for tree, figures in runs.items()}
                    print(f"{'':<8} {'main/decoding/writer':<8} {where[earlier]:>20} {where[ROOT]:>20}")
                for leftover in scratch.glob("out-*"):
                    shutil.rmtree(leftover) if leftover.is_dir() else leftover.unlink()
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(earlier)], cwd=ROOT, check=False)


if __name__ == "__main__":
    main()

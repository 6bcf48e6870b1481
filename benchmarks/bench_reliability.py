"""Hostile and unlucky inputs, family by family: does every run end with one clear line and a
documented exit code, in bounded memory and time, without altering what it reads? Prints a table.

    python -m benchmarks.bench_reliability [--per-family N] [--seed 1] [--keep DIR] [--quick]
                                           [--family NAME ...]

Families (each run is ``rtusniff`` in a fresh process, as a user runs it):

* ``truncation``: the shipped samples and the real sigrok recordings cut at every 1 % (``stats``);
  a cut that reads (exit 0) must give a prefix of the whole file's bytes (``convert`` to text);
* ``bit flips``: one bit flipped at random in the MCAP samples (``stats``); a flip that reads must
  give the very same statistics (chunk CRCs are checked: never different frames);
* ``crafted MCAP``: a chunk claiming gigabytes, notes that are not a list of text, times that go
  back or before 1970, a read of megabytes;
* ``hostile sizes``: a 5 000-digit time, a noise line of megabytes, a flood of comment lines;
* ``hostile profiles``: nesting, dotted keys, wrong types, huge counts (``profiles check``);
* ``full disk``: every command writing to ``/dev/full`` (Linux);
* the entrances of ``reliability_entrances.py``: ``line names`` (through the text format and
  back), ``logic, pcap`` (hostile sigrok sessions and zip bombs, pcap records and resolutions,
  sigrok-cli lines, Saleae values and times), ``MCAP metadata`` (bit flips in the sealed record,
  notes that are no text), ``outputs, inputs`` (an output that is an input, a failed run's
  output), ``report, dataset`` (a Markdown report renders nothing of the capture's; a capture
  joins a dataset once), ``bounds`` (``values --wide``, ``compare`` of 6 000 pairs) and
  ``following`` (a followed file changed under it);
* ``live (pty)``: on socat pseudo-terminals, two captures on one port, ``kill -9`` of a recording
  capture, a consumer of ``--format jsonl`` that stops reading, and a disk that fills up during a
  capture (``reliability_live.py``).

A run counts as a **traceback** when standard error holds one, a **hang** when it outlives
``TIMEOUT_S``, a **wrong exit** when its code is not the README's for what went wrong (anything but
0 and 2–14; 1 is "other runtime error", never expected here), **not one line** when an error run
says more or less than one ``error:`` line, **altered** when what it gives is not what its input
holds, **destroyed** when a file it read is changed or gone after it. Peak RSS is the largest
any run of the family used.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
REAL = ROOT.parent / "shared" / "real" / "sigrok-cli-text"
TIMEOUT_S = 60
DOCUMENTED = {0, *range(2, 15)}
#: The run, and its peak memory: VmHWM where Linux has it (ru_maxrss counts the memory of the
#: process that forked this one too).
CHILD = """
import os, re, resource, sys
from sniffer.cli import main
try:
    code = main(sys.argv[1:])
finally:
    with open(os.environ["RTUSNIFF_BENCH_RSS"], "w") as out:
        try:
            out.write(re.search(r"VmHWM:\\s*(\\d+)", open("/proc/self/status").read())[1])
        except OSError:
            out.write(str(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss))
sys.exit(code)
"""


@dataclass
class Family:
    name: str
    runs: int = 0
    tracebacks: int = 0
    hangs: int = 0
    wrong_exits: int = 0
    not_one_line: int = 0
    altered: int = 0
    destroyed: int = 0
    peak_rss_kb: int = 0
    problems: list[str] = field(default_factory=list)

    def row(self) -> str:
        return (f"{self.name:<17} {self.runs:>6} {self.tracebacks:>10} {self.hangs:>6} {self.wrong_exits:>11} "
                f"{self.not_one_line:>13} {self.altered:>8} {self.destroyed:>10} {self.peak_rss_kb / 1024:>10.0f}")


@dataclass
class Run:
    code: int
    out: str
    err: str


def rtusniff(family: Family, scratch: Path, *argv: str, stdin: bytes | Path | None = None) -> Run | None:
    """One run in a fresh process, counted against ``family``; ``None`` when it hung.
    ``stdin``: bytes through a pipe, or a file standard input is redirected from (``< FILE``)."""
    rss_file = scratch / "rss"
    env = {**os.environ, "RTUSNIFF_BENCH_RSS": str(rss_file)}
    family.runs += 1
    redirected = stdin.open("rb") if isinstance(stdin, Path) else None
    try:
        done = subprocess.run([sys.executable, "-c", CHILD, *argv], capture_output=True, timeout=TIMEOUT_S, env=env,
                              cwd=scratch, check=False, **({"stdin": redirected} if redirected else {"input": stdin}))
    except subprocess.TimeoutExpired:
        family.hangs += 1
        family.problems.append(f"hang: {' '.join(argv)}")
        return None
    finally:
        if redirected is not None:
            redirected.close()
    if rss_file.exists():
        family.peak_rss_kb = max(family.peak_rss_kb, int(rss_file.read_text() or 0))
    err = done.stderr.decode(errors="replace")
    if "Traceback" in err:
        family.tracebacks += 1
        family.problems.append(f"traceback: {' '.join(argv)}: {err.strip().splitlines()[-1]}")
    if done.returncode not in DOCUMENTED:
        family.wrong_exits += 1
        family.problems.append(f"exit {done.returncode}: {' '.join(argv)}")
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    if done.returncode != 0 and len(errors) != 1:
        family.not_one_line += 1
        family.problems.append(f"{len(errors)} error lines: {' '.join(argv)}")
    return Run(done.returncode, done.stdout.decode(errors="replace"), err)


QUICK_SAMPLES = [ROOT / "captures" / "atv71-plc-poll.log", ROOT / "captures" / "atv71-plc-poll.mcap"]


def samples(*, quick: bool = False) -> list[Path]:
    if quick:
        return QUICK_SAMPLES
    found = sorted((ROOT / "captures").glob("*.log")) + sorted((ROOT / "captures").glob("*.mcap"))
    return found + (sorted(REAL.glob("*.log")) if REAL.is_dir() else [])


def truncation(scratch: Path, per_file: int, rng: random.Random, *, quick: bool = False) -> Family:
    family = Family("truncation")
    for path in samples(quick=quick):
        data = path.read_bytes()
        whole = _text_bytes(family, scratch, path)
        cuts = sorted({len(data) * k // 100 for k in range(1, 100)})
        for cut in rng.sample(cuts, min(per_file, len(cuts))):
            target = scratch / f"cut{path.suffix}"
            target.write_bytes(data[:cut])
            run = rtusniff(family, scratch, "stats", str(target), "--line", "19200 8E1")
            if run is not None and run.code == 0 and whole is not None:
                read = _text_bytes(family, scratch, target)
                if read is not None and not whole.startswith(read):
                    family.altered += 1
                    family.problems.append(f"altered: {path.name} cut at {cut}")
    return family


def _text_bytes(family: Family, scratch: Path, path: Path) -> bytes | None:
    """The line data of a capture, through ``convert`` to text (times and bytes, no header)."""
    out = scratch / "as-text.log"
    out.unlink(missing_ok=True)
    run = rtusniff(family, scratch, "convert", str(path), str(out), "--line", "19200 8E1", "-q")
    if run is None or run.code != 0:
        return None
    return b"".join(bytes.fromhex(line.split(" ", 1)[1]) for line in out.read_text().splitlines()
                    if line and not line.startswith("#"))


def bit_flips(scratch: Path, per_file: int, rng: random.Random, *, quick: bool = False) -> Family:
    family = Family("bit flips")
    for path in [p for p in samples(quick=quick) if p.suffix == ".mcap" and p.parent.name == "captures"]:
        data = path.read_bytes()
        reference = rtusniff(family, scratch, "stats", str(path), "--format", "json")
        for _ in range(per_file):
            flipped = bytearray(data)
            position = rng.randrange(len(data))
            flipped[position] ^= 1 << rng.randrange(8)
            target = scratch / "flipped.mcap"
            target.write_bytes(bytes(flipped))
            run = rtusniff(family, scratch, "stats", str(target), "--format", "json")
            if run is not None and run.code == 0 and reference is not None and \
                    _counts(run.out) != _counts(reference.out):
                family.altered += 1
                family.problems.append(f"altered: {path.name} bit flipped at byte {position}")
    return family


def _counts(stats_json: str) -> object:
    document = json.loads(stats_json)
    return {key: document[key] for key in ("frames", "bytes", "roles", "flags", "crc_errors")}


#: Inputs per crafted family in a quick slice (the unit tests read every shape in-process).
QUICK_SHAPES = 3


def crafted_mcaps(scratch: Path, *, quick: bool = False) -> Family:
    from benchmarks.hostile_inputs import crafted_mcap_files

    family = Family("crafted MCAP")
    shapes = crafted_mcap_files(scratch)
    for path in shapes[-QUICK_SHAPES:] if quick else shapes:  # the last ones: the big read and the bomb
        rtusniff(family, scratch, "stats", str(path))
    return family


def hostile_sizes(scratch: Path, *, quick: bool = False) -> Family:
    from benchmarks.hostile_inputs import hostile_text_files

    family = Family("hostile sizes")
    for path in hostile_text_files(scratch)[: QUICK_SHAPES if quick else None]:
        rtusniff(family, scratch, "stats", str(path))
    if quick:
        return family
    flood = b"# rtu-capture v1\n# line: 19200 8E1\n" + b"# a comment line from a chatty tool\n" * 1_000_000
    rtusniff(family, scratch, "stats", "-", stdin=flood)
    return family


def hostile_profiles(scratch: Path, *, both: bool = True) -> Family:
    from benchmarks.hostile_inputs import hostile_profile_texts

    family = Family("hostile profiles")
    for number, text in enumerate(hostile_profile_texts()[: None if both else QUICK_SHAPES]):
        path = scratch / f"hostile-{number}.toml"
        path.write_text(text)
        rtusniff(family, scratch, "profiles", "check", str(path))
        if both:
            rtusniff(family, scratch, "analyze", str(ROOT / "captures" / "xbt-hmi.log"), "--profile-file", str(path))
    return family


def full_disk(scratch: Path, *, quick: bool = False) -> Family:
    family = Family("full disk")
    if not Path("/dev/full").exists():
        return family
    sample = str(ROOT / "captures" / "atv71-plc-poll.log")
    commands = [["analyze", sample, "-o", "/dev/full"], ["convert", sample, "/dev/full", "--output-format", "text"],
                ["report", sample, "-o", "/dev/full"], ["stats", sample, "-o", "/dev/full"],
                ["analyze", sample, "--format", "jsonl", "-o", "/dev/full"], ["values", sample, "-o", "/dev/full"],
                ["export", sample, "--pcap", "/dev/full"]]
    for argv in commands[: 3 if quick else None]:
        run = rtusniff(family, scratch, *argv)
        if run is not None and run.code != 11:
            family.wrong_exits += 1
            family.problems.append(f"exit {run.code}, not 11: {' '.join(argv)}")
    return family


def families(scratch: Path, per_family: int, seed: int, *,
             quick: bool = False) -> list[tuple[str, Callable[[], Family]]]:
    """Every family by name, each run when called; ``quick``: a slice for CI (the shipped samples
    only, one command per profile)."""
    from benchmarks.reliability_entrances import families as entrances  # it imports this module

    rng = random.Random(seed)
    runs: list[tuple[str, Callable[[], Family]]] = [
        ("truncation", lambda: truncation(scratch, per_family, rng, quick=quick)),
        ("bit flips", lambda: bit_flips(scratch, per_family, rng, quick=quick)),
        ("crafted MCAP", lambda: crafted_mcaps(scratch, quick=quick)),
        ("hostile sizes", lambda: hostile_sizes(scratch, quick=quick)),
        ("hostile profiles", lambda: hostile_profiles(scratch, both=not quick)),
        ("full disk", lambda: full_disk(scratch, quick=quick)),
        *entrances(scratch, per_family, rng, quick=quick)]
    if not quick:  # the tests run these scenarios themselves (tests/test_capture.py, test_live_gaps.py)
        from benchmarks.reliability_live import live

        runs.append(("live (pty)", lambda: live(scratch)))
    return runs


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--per-family", type=int, default=20,
                        help="cuts per file and bit flips per MCAP sample (the crafted families run whole)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--keep", type=Path, help="keep the inputs made in this folder")
    parser.add_argument("--quick", action="store_true", help="a slice: the shipped samples only (what CI runs)")
    parser.add_argument("--family", action="append", help="only this family (by its name; repeatable)")
    args = parser.parse_args(argv)
    failed = False
    with tempfile.TemporaryDirectory() as temporary:
        scratch = args.keep or Path(temporary)
        scratch.mkdir(parents=True, exist_ok=True)
        print(f"{'family':<17} {'inputs':>6} {'tracebacks':>10} {'hangs':>6} {'wrong exits':>11} "
              f"{'not one line':>13} {'altered':>8} {'destroyed':>10} {'peak MB':>10}", flush=True)
        for name, run in families(scratch, args.per_family, args.seed, quick=args.quick):
            if args.family and name not in args.family:
                continue
            family = run()
            print(family.row(), flush=True)
            for problem in family.problems[:10]:
                print(f"    {problem}", flush=True)
            failed = failed or bool(family.problems)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

"""Shared fixtures: the manual's example frames, the shipped samples, a CLI runner."""

from __future__ import annotations

import io
import json
from collections.abc import Callable
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from mcap.writer import Writer

from sniffer.cli import main

ROOT = Path(__file__).resolve().parent.parent
CAPTURES = ROOT / "captures"
SAMPLE_LOG = CAPTURES / "atv71-plc-poll.log"
SAMPLE_MCAP = CAPTURES / "atv71-plc-poll.mcap"


def write_foreign_mcap(path: Path) -> None:
    """A valid MCAP that another tool wrote: no rtusniff capture in it."""
    with path.open("wb") as f:
        writer = Writer(f)
        writer.start(profile="", library="someone else")
        channel = writer.register_channel(topic="/imu", message_encoding="json", schema_id=0)
        writer.add_message(channel_id=channel, log_time=1, publish_time=1, data=b"{}")
        writer.finish()


def load_manual_frames() -> list[dict[str, Any]]:
    frames: list[dict[str, Any]] = json.loads((CAPTURES / "manual-frames.json").read_text())["frames"]
    return frames


@pytest.fixture(scope="session")
def manual_frames() -> dict[str, bytes]:
    return {f["id"]: bytes.fromhex(f["hex"]) for f in load_manual_frames()}


@dataclass
class CliResult:
    code: int
    out: str
    err: str

    def jsonl(self) -> list[dict[str, Any]]:
        return [json.loads(line) for line in self.out.splitlines()]


@pytest.fixture
def cli() -> Callable[..., CliResult]:
    """Run ``rtusniff`` in this process and capture what it prints."""

    def run(*argv: str) -> CliResult:
        out, err = io.StringIO(), io.StringIO()
        with redirect_stdout(out), redirect_stderr(err):
            code = main(list(argv))
        return CliResult(code, out.getvalue(), err.getvalue())

    return run

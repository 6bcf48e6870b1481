"""The allocator kept from handing a batch's memory back (:mod:`sniffer.allocator`)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from sniffer import allocator, cli

ON_GLIBC = allocator.glibc_version() is not None
#: Allocates and frees arrays of 2, 5, 1 and 7 MB twenty times, as batches do, and prints the
#: page faults it took and the pages of one round (run in a process of its own: the test must
#: not change pytest's allocator).
ROUNDS = """
import json, resource, sys
import numpy as np
from sniffer.allocator import keep_freed_memory
set_here = keep_freed_memory() if sys.argv[1] == "keep" else False
sizes = [2 << 20, 5 << 20, 1 << 20, 7 << 20]
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(20):
    held = [np.ones(size, np.uint8) for size in sizes]
    del held
faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
print(json.dumps({"set": set_here, "faults": faults, "round_pages": sum(sizes) // 4096}))
"""


def _rounds(mode: str) -> dict[str, int]:
    env = {name: value for name, value in os.environ.items() if name not in allocator.TUNING_VARIABLES}
    done = subprocess.run([sys.executable, "-c", ROUNDS, mode], capture_output=True, text=True, check=True, env=env)
    result: dict[str, int] = json.loads(done.stdout)
    return result


@pytest.mark.skipif(not ON_GLIBC, reason="the allocator is tuned on glibc only")
def test_batches_reuse_the_pages_freed_by_the_batch_before() -> None:
    kept = _rounds("keep")
    assert kept["set"]
    # Twenty rounds fault about one round's pages in, once; freed to the kernel between rounds
    # (glibc's own adaptive trimming), they took 6.5 rounds' worth here.
    assert kept["faults"] < 1.5 * kept["round_pages"]


@pytest.mark.skipif(not ON_GLIBC, reason="the allocator is tuned on glibc only")
def test_without_it_the_same_rounds_fault_their_pages_in_again() -> None:
    """The test above can fail: glibc's own defaults do not keep the pages."""
    plain = _rounds("plain")
    assert not plain["set"]
    assert plain["faults"] > 1.5 * plain["round_pages"]


@pytest.mark.parametrize("name", allocator.TUNING_VARIABLES)
def test_an_allocator_tuned_by_the_environment_is_left_as_it_is(monkeypatch: pytest.MonkeyPatch, name: str) -> None:
    monkeypatch.setenv(name, "1048576")
    assert not allocator.keep_freed_memory()


def test_elsewhere_than_glibc_nothing_is_asked(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in allocator.TUNING_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(sys, "platform", "win32")
    monkeypatch.setattr(allocator.ctypes, "CDLL", lambda *_: pytest.fail("no C library is loaded off Linux"))
    assert allocator.glibc_version() is None
    assert not allocator.keep_freed_memory()


def test_every_command_runs_with_it(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    asked = []
    monkeypatch.setattr(cli, "keep_freed_memory", lambda: asked.append(True) or True)
    assert cli.main(["profiles"]) == 0
    assert asked == [True]

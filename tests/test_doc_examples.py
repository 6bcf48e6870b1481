"""Every example output in the README and the docs is what the command prints today.

An example is an HTML comment naming the command, then a fenced block with its output:

    <!-- example: rtusniff stats captures/atv71-plc-poll.log -->
    ```
    …output…
    ```

The command runs from the project's root, as a user would type it (``| head -N`` and
``| tail -N`` are understood). ``RTUSNIFF_REGENERATE_GOLDEN=1 pytest tests/test_doc_examples.py``
rewrites the blocks after a deliberate change of the output.
"""

from __future__ import annotations

import json
import os
import re
import shlex
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.conftest import CAPTURES, ROOT, CliResult

EXAMPLE = re.compile(r"<!-- example: (?P<command>.+?) -->\n```[a-z]*\n(?P<output>.*?)```", re.DOTALL)
DOCUMENTS = [ROOT / "README.md", ROOT / "captures" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
REGENERATE = os.environ.get("RTUSNIFF_REGENERATE_GOLDEN") == "1"


def run_example(cli: Callable[..., CliResult], command: str) -> str:
    pipeline = [part.strip() for part in command.split("|")]
    argv = shlex.split(pipeline[0])
    assert argv[0] == "rtusniff", command
    result = cli(*argv[1:])
    assert result.code == 0, (command, result.err)
    lines = [line.rstrip() for line in result.out.splitlines()]
    for stage in pipeline[1:]:
        tool, count = shlex.split(stage)[0], int(shlex.split(stage)[1].lstrip("-n"))
        assert tool in ("head", "tail"), command
        lines = lines[:count] if tool == "head" else lines[-count:]
    return "\n".join(lines) + "\n"


def examples() -> list[tuple[Path, str]]:
    found = [(path, match["command"]) for path in DOCUMENTS if path.exists()
             for match in EXAMPLE.finditer(path.read_text(encoding="utf-8"))]
    return found


def test_there_are_examples_in_the_readme_and_the_docs() -> None:
    places = {path.name for path, _ in examples()}
    assert {"README.md", "jsonl-output.md"} <= places


@pytest.mark.parametrize(("path", "command"), examples(), ids=lambda value: str(value)[-60:])
def test_example_output_is_what_the_command_prints(
    cli: Callable[..., CliResult], monkeypatch: pytest.MonkeyPatch, path: Path, command: str
) -> None:
    monkeypatch.chdir(ROOT)
    monkeypatch.delenv("COLUMNS", raising=False)
    output = run_example(cli, command)
    text = path.read_text(encoding="utf-8")
    block = next(m for m in EXAMPLE.finditer(text) if m["command"] == command)
    if REGENERATE:
        path.write_text(text[: block.start("output")] + output + text[block.end("output") :], encoding="utf-8")
        return
    shown = "\n".join(line.rstrip() for line in block["output"].splitlines()) + "\n"
    assert shown == output, f"{path.name}: the example of '{command}' is out of date (see this module's docstring)"


def test_every_jsonl_field_written_is_documented(cli: Callable[..., CliResult]) -> None:
    documented = set(re.findall(r"`([a-z_0-9]+)`", (ROOT / "docs" / "jsonl-output.md").read_text()))
    written: set[str] = set()
    for sample in sorted(CAPTURES.glob("*.log")):
        for line in cli("analyze", str(sample), "--format", "jsonl").out.splitlines():
            record = json.loads(line)
            written.update(record)
            for param in record.get("params", []):
                written.update(param)
            for row in record.get("per_slave_function", []):
                written.update(row)
                written.update(row["latency_s"])
    assert written - documented == set()

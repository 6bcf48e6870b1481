"""The README is the user's manual: its commands run in CI, and it documents every command."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from sniffer.cli import COMMAND_NAMES
from sniffer.errors import ErrorKind
from tests.conftest import ROOT


def setup_commands() -> list[str]:
    readme = (ROOT / "README.md").read_text()
    block = re.search(r"<!-- setup-commands.*?-->\n```sh\n(.*?)```", readme, re.S)
    assert block, "README.md lost its setup-commands block"
    return block.group(1).strip().splitlines()


def test_two_setup_commands_run_a_shipped_capture_and_the_tests() -> None:
    analyze, tests = setup_commands()
    capture = re.search(r"rtusniff analyze (\S+)", analyze)
    assert capture and (ROOT / capture.group(1)).is_file()
    assert ".[test]" in tests and "pytest" in tests


def test_ci_runs_the_readme_block() -> None:
    ci = (ROOT / ".ci" / "run").read_text()
    assert "setup-commands" in ci
    for tool in ("ruff check", "mypy", "lint-imports"):
        assert tool in ci


def test_every_command_has_a_usage_section() -> None:
    readme = (ROOT / "README.md").read_text()
    for name in COMMAND_NAMES:
        assert f"### `rtusniff {name}" in readme, name


def test_exit_codes_are_documented() -> None:
    readme = (ROOT / "README.md").read_text()
    for kind in ErrorKind:
        assert re.search(rf"^\| {kind.exit_code} \|", readme, re.M), kind


def test_ci_runs_every_command_from_the_installed_wheel() -> None:
    """What only a wheel can get wrong (entry points, package data) shows when a command runs
    from it: CI's wheel check runs each one."""
    ci = (ROOT / ".ci" / "run").read_text()
    assert "wheel_commands.sh" in ci
    script = (ROOT / ".ci" / "wheel_commands.sh").read_text()
    for name in COMMAND_NAMES:
        assert re.search(rf'"\$bin/rtusniff" {name}\b', script), name


def _imports(package_root: Path) -> dict[str, set[str]]:
    """Each module of ``sniffer`` and ``decoders`` with the modules of both it imports: at its top,
    inside functions and under ``TYPE_CHECKING`` alike."""
    modules = {}
    for package in ("sniffer", "decoders"):
        for path in (package_root / package).rglob("*.py"):
            name = ".".join(path.relative_to(package_root).with_suffix("").parts).removesuffix(".__init__")
            modules[name] = path
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        found = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module and not node.level:
                found |= {node.module} | {f"{node.module}.{alias.name}" for alias in node.names}
            elif isinstance(node, ast.Import):
                found |= {alias.name for alias in node.names}
        graph[name] = (found & modules.keys()) - {name}
    return graph


def test_no_import_cycle_not_even_for_type_checking() -> None:
    """A module that two others need each other for is two ideas in one place, or one in two."""
    graph = _imports(ROOT)
    done: set[str] = set()

    def cycle_from(start: str, path: list[str]) -> list[str] | None:
        for follower in sorted(graph[path[-1]]):
            if follower == start:
                return [*path, start]
            if follower not in path and follower not in done:
                found = cycle_from(start, [*path, follower])
                if found:
                    return found
        return None

    for module in sorted(graph):
        cycle = cycle_from(module, [module])
        assert cycle is None, " -> ".join(cycle)
        done.add(module)

"""Release quality: where users run it, never losing a capture, the small things users trip over."""

from __future__ import annotations

import importlib.metadata
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import CAPTURES, ROOT, SAMPLE_LOG

USB_LOG = CAPTURES / "atv71-plc-poll-usb.log"


def run_without_posix(*argv: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    """``rtusniff ARGV`` in a Python that has no ``fcntl``, ``termios`` nor ``os.fork``, as on Windows."""
    program = textwrap.dedent(f"""
        import os, sys
        sys.modules["fcntl"] = None      # import fcntl -> ImportError, as on Windows
        sys.modules["termios"] = None
        del os.fork
        from sniffer.cli import main
        sys.exit(main({list(argv)!r}))
    """)
    return subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, cwd=cwd, check=False,
                          timeout=120)


def test_runs_where_there_is_no_fcntl_termios_nor_fork() -> None:
    version = run_without_posix("--version")
    assert version.returncode == 0 and version.stdout.startswith("rtusniff "), version.stderr
    analyzed = run_without_posix("analyze", str(SAMPLE_LOG))
    assert analyzed.returncode == 0 and "Traceback" not in analyzed.stderr, analyzed.stderr
    assert "52 frames, 28 request, 21 response" in analyzed.stdout
    stats = run_without_posix("stats", str(SAMPLE_LOG))
    assert stats.returncode == 0 and "per slave and function" in stats.stdout, stats.stderr
    exported = run_without_posix("export", str(SAMPLE_LOG), "--pcap", os.devnull, "--jobs", "auto")
    assert exported.returncode == 0, exported.stderr
    forked = run_without_posix("analyze", str(SAMPLE_LOG), "--jobs", "2")
    assert forked.returncode == 2 and forked.stderr.count("\n") == 1 and "cannot fork" in forked.stderr


def test_no_module_imports_a_posix_only_module_at_its_top() -> None:
    program = textwrap.dedent("""
        import importlib, pkgutil, sys
        sys.modules["fcntl"] = None
        sys.modules["termios"] = None
        import decoders, sniffer
        for package in (decoders, sniffer):
            for module in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
                if not module.name.endswith("__main__"):  # that one runs the command line
                    importlib.import_module(module.name)
        print("ok")
    """)
    result = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, cwd=ROOT, check=False)
    assert result.stdout.strip() == "ok", result.stderr


def test_analyze_and_stats_never_write_over_their_input(cli: Any, tmp_path: Path) -> None:
    capture = tmp_path / "cap.log"
    shutil.copy(SAMPLE_LOG, capture)
    original = capture.read_bytes()
    link = tmp_path / "link.log"
    link.symlink_to(capture)
    hard = tmp_path / "hard.log"
    os.link(capture, hard)
    for command in ("analyze", "stats"):
        for output in (capture, link, hard, tmp_path / "." / "cap.log"):
            for force in ((), ("--force",)):
                refused = cli(command, str(capture), "-o", str(output), *force)
                assert refused.code == 2 and "never writes over a capture it reads" in refused.err, refused.err
                assert capture.read_bytes() == original
    converted = cli("convert", str(capture), str(link), "--force")
    assert converted.code == 2 and capture.read_bytes() == original
    exported = cli("export", str(capture), "--pcap", str(hard), "--force")
    assert exported.code == 2 and capture.read_bytes() == original


def test_an_existing_output_needs_force(cli: Any, tmp_path: Path) -> None:
    for command in ("analyze", "stats"):
        out = tmp_path / f"{command}.txt"
        out.write_text("keep")
        refused = cli(command, str(SAMPLE_LOG), "-o", str(out))
        assert refused.code == 11 and "add --force" in refused.err and out.read_text() == "keep"
        assert cli(command, str(SAMPLE_LOG), "-o", str(out), "--force").code == 0
        assert out.read_text() != "keep"
        # A device is no file to keep: -o /dev/null needs no --force.
        assert cli(command, str(SAMPLE_LOG), "-o", os.devnull).code == 0
    twice = cli("export", str(SAMPLE_LOG), "--mcap", str(tmp_path / "a.mcap"), "--pcap", str(tmp_path / "a.mcap"))
    assert twice.code == 2 and "named as two outputs" in twice.err


def test_line_before_the_capture_and_its_errors(cli: Any) -> None:
    before = cli("analyze", "--line", "19200", "8E1", str(SAMPLE_LOG))
    assert before.code == 0 and "read HR" in before.out
    quoted = cli("analyze", str(SAMPLE_LOG), "--line", "19200 8E1")
    assert quoted.code == 0
    wrong = cli("analyze", "--line", "19200", "8Q1", str(SAMPLE_LOG))
    assert wrong.code == 2 and "--line: line settings '19200 8Q1'" in wrong.err


def test_wrong_line_settings_are_told(cli: Any) -> None:
    slow = cli("analyze", str(SAMPLE_LOG), "--line", "9600", "8E1", "--format", "jsonl")
    assert slow.code == 0
    assert "--line 9600 8E1 overrides the capture's own 19200 8E1" in slow.err
    assert "the bytes come faster than the line settings allow" in slow.err
    assert slow.err.count("warning:") == 2  # each once, also with the decoding process
    right = cli("analyze", str(SAMPLE_LOG), "--line", "19200", "8E1")
    assert right.code == 0 and right.err == ""


def test_host_captures_read_too_fast_for_the_line_are_told(cli: Any, tmp_path: Path) -> None:
    """Host timing: 10 000 bytes read within one second cannot come over 9600 Bd (960 bytes/s)."""
    capture = tmp_path / "fast.log"
    lines = ["# rtu-capture v1", "# line: 9600 8N1", "# timing: host"]
    frame = "02 03 0C 1E 00 04 27 6C"
    lines += [f"1700000000.{k * 500:09d} {frame}" for k in range(1250)]
    capture.write_text("\n".join(lines) + "\n")
    result = cli("analyze", str(capture), "-o", os.devnull)
    assert result.code == 0 and "bytes were read within one second" in result.err
    usb = cli("analyze", str(USB_LOG), "-o", os.devnull)
    assert usb.code == 0 and usb.err == ""


def test_the_recordings_of_others_fit_their_line_settings(cli: Any) -> None:
    real = ROOT.parent / "shared" / "real" / "sigrok-cli-text"
    recordings = sorted(real.glob("*.log")) + sorted(CAPTURES.glob("*.log")) + sorted(CAPTURES.glob("*.mcap"))
    if not any(path.parent == real for path in recordings):
        pytest.skip("../shared/real is not beside the checkout")
    for path in recordings:
        result = cli("analyze", str(path), "-o", os.devnull)
        assert result.code == 0 and "faster than the line settings" not in result.err, (path, result.err)


def test_response_timeout_zero_means_no_time_limit(cli: Any, tmp_path: Path) -> None:
    frames = [r for r in cli("analyze", str(SAMPLE_LOG), "--format", "jsonl", "--response-timeout", "0").jsonl()
              if r["kind"] == "frame"]
    timed_out = [f for f in frames if "timeout" in f["flags"]]
    # Drive 3 never answers: with no time limit its requests time out only when the master moves on.
    default = [r for r in cli("analyze", str(SAMPLE_LOG), "--format", "jsonl").jsonl() if r["kind"] == "frame"]
    assert frames and len(timed_out) <= len([f for f in default if "timeout" in f["flags"]])


def test_bare_command_prints_help() -> None:
    result = subprocess.run([sys.executable, "-m", "sniffer"], capture_output=True, text=True, check=False)
    assert result.returncode == 0 and "commands:" in result.stdout and "analyze" in result.stdout


def test_debug_after_the_command(cli: Any) -> None:
    result = subprocess.run([sys.executable, "-m", "sniffer", "analyze", "missing.log", "--debug"],
                            capture_output=True, text=True, check=False)
    assert "Traceback" in result.stderr and "no such file" in result.stderr
    plain = cli("analyze", "missing.log")
    assert plain.code == 3 and plain.err == "error: missing.log: no such file\n"


def test_unknown_format_hint_names_an_option_the_command_has(cli: Any, tmp_path: Path) -> None:
    odd = tmp_path / "capture.bin"
    odd.write_bytes(b"\x00\x01\x02")
    analyzed = cli("analyze", str(odd))
    assert analyzed.code == 5 and "--input-format" in analyzed.err and "--output-format" not in analyzed.err
    converted = cli("convert", str(SAMPLE_LOG), str(tmp_path / "out.bin"))
    assert converted.code == 5 and "--output-format" in converted.err


def test_export_pcap_to_standard_output(tmp_path: Path) -> None:
    result = subprocess.run([sys.executable, "-m", "sniffer", "export", str(SAMPLE_LOG), "--pcap", "-"],
                            capture_output=True, check=False)
    assert result.returncode == 0 and not (tmp_path / "-").exists() and not Path("-").exists()
    assert result.stdout[:4] == bytes.fromhex("4d3cb2a1")  # pcap, nanosecond timestamps, little-endian
    assert b"wrote 52 frames as pcap to standard output" in result.stderr
    tshark = shutil.which("tshark")
    if tshark is not None:
        read = subprocess.run([tshark, "-r", "-", "-T", "fields", "-e", "frame.number"], input=result.stdout,
                              capture_output=True, check=False, timeout=120)
        assert read.stdout.decode().split()[-1] == "52"


def test_export_and_convert_say_what_they_wrote(cli: Any, tmp_path: Path) -> None:
    exported = cli("export", str(SAMPLE_LOG), "--mcap", str(tmp_path / "x.mcap"), "--pcap", str(tmp_path / "x.pcap"))
    assert exported.code == 0
    assert f"wrote {tmp_path / 'x.mcap'}: MCAP, 52 frames," in exported.err
    assert f"wrote {tmp_path / 'x.pcap'}: pcap, 52 frames," in exported.err
    converted = cli("convert", str(SAMPLE_LOG), str(tmp_path / "x2.mcap"))
    assert converted.code == 0 and converted.err.startswith("wrote ") and "x2.mcap" in converted.err


def test_spawn_without_a_display_is_one_error_line(monkeypatch: pytest.MonkeyPatch) -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    result = subprocess.run([sys.executable, "-m", "sniffer", "export", str(SAMPLE_LOG), "--spawn"],
                            capture_output=True, text=True, check=False, env=env, timeout=60)
    if not sys.platform.startswith("linux"):
        pytest.skip("the display check is for Linux")
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "no display" in result.stderr


def test_the_rerun_viewer_is_found_beside_the_interpreter(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    from sniffer.exports import streams

    beside = Path(sys.executable).parent / ("rerun.exe" if os.name == "nt" else "rerun")
    monkeypatch.setenv("PATH", str(tmp_path))  # not on PATH
    if beside.is_file():
        assert streams.rerun_viewer() == str(beside)
    monkeypatch.setattr(sys, "executable", str(tmp_path / "python"))
    assert streams.rerun_viewer() is None


def test_a_missing_profile_folder_is_one_error_line(tmp_path: Path) -> None:
    """An installation without its data files (a broken wheel): an error line, not a traceback."""
    program = textwrap.dedent("""
        import sys
        import importlib.resources
        from sniffer import profiles_io
        class Empty:
            def joinpath(self, name): return self
            def iterdir(self): raise FileNotFoundError(2, "No such file or directory")
            def __str__(self): return "decoders/profiles/data"
        profiles_io.files = lambda package: Empty()
        from sniffer.cli import main
        sys.exit(main(["analyze", sys.argv[1]]))
    """)
    result = subprocess.run([sys.executable, "-c", program, str(SAMPLE_LOG)], capture_output=True, text=True,
                            cwd=ROOT, check=False)
    assert result.returncode == 12 and result.stderr.count("\n") == 1, result.stderr
    assert result.stderr.startswith("error: decoders/profiles/data: the shipped device profiles cannot be read")


def test_the_shipped_profiles_are_package_data(cli: Any) -> None:
    """Every profile is declared package data, and the package in use (the checkout, or the
    installed wheel when CI runs the suite against it) carries every one of them."""
    import tomllib

    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    assert "profiles/data/*.toml" in declared["decoders"]
    listed = cli("profiles")
    assert listed.code == 0
    for name in ("generic", "atv71", "atv312", "nord-sk", "xbt"):
        assert name in listed.out


@pytest.mark.parametrize("argv", [["stats", "--format", "json", "LOG"], ["analyze", "--format", "jsonl", "LOG"],
                                  ["compare", "--format", "json", "LOG", "LOG"], ["--version"]],
                         ids=["stats-json", "analyze-jsonl", "compare-json", "version"])
def test_output_that_no_terminal_reads_starts_without_rich_nor_metadata(argv: list[str], tmp_path: Path) -> None:
    """rich (tens of ms to import) only for a terminal's tables and bars, importlib.metadata
    never (the version is the package's own constant): a command writing JSON to a file or a
    pipe starts without either."""
    arguments = [str(SAMPLE_LOG) if word == "LOG" else word for word in argv]
    program = textwrap.dedent(f"""
        import contextlib, io, sys
        from sniffer.cli import main
        with contextlib.redirect_stdout(io.StringIO()):
            try:
                main({arguments!r})
            except SystemExit:
                pass
        print(any(name.split(".")[0] == "rich" for name in sys.modules), "importlib.metadata" in sys.modules)
    """)
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, cwd=tmp_path, check=False,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False", "False"], done.stdout


def test_the_version_is_told_without_importing_any_command() -> None:
    """``rtusniff --version`` (scripts record it) imports no command's modules, nor numpy."""
    program = textwrap.dedent("""
        import contextlib, io, sys
        from sniffer.cli import main
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            code = main(["--version"])
        print(code, out.getvalue().strip(), any(name.startswith(("sniffer.commands", "numpy")) for name in sys.modules))
    """)
    done = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, check=False, timeout=120)
    assert done.returncode == 0, done.stderr
    code, name, version, imported = done.stdout.split()
    assert (code, name, imported) == ("0", "rtusniff", "False") and version[0].isdigit()
    # The constant is the installed package's version (pyproject.toml reads it).
    assert version == importlib.metadata.version("rtusniff")

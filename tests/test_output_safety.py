"""No command destroys what it was not told to: outputs are created exclusively, links are not
followed, ``--force`` replaces only a plain file, a copy appears only whole, and only what a
command created is ever removed (``sniffer/io/output_files.py``)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pytest

from decoders.capture import CaptureInfo, Chunk, TimingQuality
from decoders.line import LineSettings
from sniffer.errors import RtuSniffError
from sniffer.io.output_files import allow_replacing, open_new, published_whole
from sniffer.recorder import Recorder, Rotation
from tests.conftest import ROOT, CliResult

Cli = Callable[..., CliResult]
SAMPLE = ROOT / "captures" / "atv71-plc-poll.log"
posix_links = pytest.mark.skipif(os.name != "posix", reason="symbolic links need privileges on Windows")


@pytest.fixture(autouse=True)
def nothing_replaceable() -> None:
    allow_replacing([])


def broken_copy_of_the_sample(tmp_path: Path) -> Path:
    """The sample with a damaged line half way: a reader fails there, after writing began."""
    lines = SAMPLE.read_text().splitlines(keepends=True)
    broken = tmp_path / "broken.log"
    middle = len(lines) // 2
    broken.write_text("".join([*lines[:middle], "this is not a capture line\n", *lines[middle:]]))
    return broken


def test_a_file_that_appeared_is_never_truncated(tmp_path: Path) -> None:
    appeared = tmp_path / "out.mcap"
    appeared.write_bytes(b"someone else's")
    with pytest.raises(RtuSniffError, match="exists"):
        open_new(str(appeared))
    assert appeared.read_bytes() == b"someone else's"
    allow_replacing([str(appeared)])  # what --force says
    with open_new(str(appeared)) as file:
        file.write(b"ours")
    assert appeared.read_bytes() == b"ours"


@posix_links
def test_links_are_not_followed(tmp_path: Path) -> None:
    target = tmp_path / "etc-passwd"
    dangling = tmp_path / "out.log"
    dangling.symlink_to(target)
    with pytest.raises(RtuSniffError, match="exists"):
        open_new(str(dangling))
    assert not target.exists()  # the link's target was not created
    target.write_text("precious")
    allow_replacing([str(dangling)])
    with pytest.raises(RtuSniffError, match="symbolic link"):
        open_new(str(dangling))
    assert target.read_text() == "precious"


def test_devices_are_written_and_never_removed() -> None:
    null = "/dev/null" if os.name == "posix" else "NUL"
    with open_new(null) as file:
        file.write(b"x")
    with pytest.raises(ValueError), published_whole(null) as target:
        assert target == null
        raise ValueError("the copy broke off")
    assert os.path.exists(null)


def test_a_copy_appears_only_whole(tmp_path: Path) -> None:
    out = tmp_path / "copy.log"
    with pytest.raises(ValueError), published_whole(str(out)) as target:
        Path(target).write_text("half")
        raise ValueError("the copy broke off")
    assert list(tmp_path.iterdir()) == []  # neither the copy nor its part file
    with published_whole(str(out)) as target:
        assert Path(target).parent == tmp_path and Path(target).suffix == ".log"
        Path(target).write_text("whole")
    assert out.read_text() == "whole" and list(tmp_path.iterdir()) == [out]
    with pytest.raises(RtuSniffError, match="appeared while rtusniff was writing"), \
            published_whole(str(out)) as target:
        Path(target).write_text("second")
    assert out.read_text() == "whole" and list(tmp_path.iterdir()) == [out]


@pytest.mark.parametrize("command", ["convert", "cut"])
def test_a_failed_copy_leaves_nothing_and_deletes_nothing(cli: Cli, tmp_path: Path, command: str) -> None:
    broken = broken_copy_of_the_sample(tmp_path)
    out = tmp_path / "out.log"
    argv = ["convert", str(broken), str(out)] if command == "convert" else \
        ["cut", str(broken), "--from", "0s", "--to", "10s", "-o", str(out)]
    result = cli(*argv)
    assert result.code not in (0, 1) and result.err.startswith("error: "), result.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken.log"]
    if os.name == "posix":
        kept = tmp_path / "kept.log"
        kept.write_text("precious")
        link = tmp_path / "link.log"
        link.symlink_to(kept)
        result = cli(*[str(link) if word == str(out) else word for word in argv], "--force")
        assert result.code != 0 and kept.read_text() == "precious" and link.is_symlink()
        null = cli(*["/dev/null" if word == str(out) else word for word in argv], "--force")
        assert null.code != 0 and Path("/dev/null").exists()


def test_force_replaces_a_plain_file_whole(cli: Cli, tmp_path: Path) -> None:
    out = tmp_path / "copy.mcap"
    out.write_bytes(b"old")
    assert cli("convert", str(SAMPLE), str(out)).code == 11 and out.read_bytes() == b"old"
    assert cli("convert", str(SAMPLE), str(out), "--force").code == 0
    assert cli("analyze", str(out)).code == 0 and sorted(p.name for p in tmp_path.iterdir()) == ["copy.mcap"]


def test_rotation_never_writes_over_a_file(tmp_path: Path) -> None:
    """A rotation whose next name was taken meanwhile stops with an error; the file stays."""
    path = tmp_path / "site.log"
    taken = tmp_path / "site-0002.log"
    taken.write_text("another recording")
    recorder = Recorder(str(path), CaptureInfo(LineSettings.parse("19200 8N1"), TimingQuality.HOST),
                        Rotation(max_bytes=10), flush_interval_s=0.01)
    recorder.start()
    recorder.add(Chunk(1_700_000_000_000_000_000, bytes(range(40))))
    recorder.stop()
    assert recorder.error is not None and "exists" in str(recorder.error)
    assert taken.read_text() == "another recording"
    assert (tmp_path / "site-0001.log").exists()


def test_capture_refuses_a_name_an_earlier_rotation_used(cli: Cli, tmp_path: Path) -> None:
    (tmp_path / "site-0001.mcap").write_bytes(b"yesterday")
    result = cli("capture", "/dev/ttyNOPE", "--line", "19200", "8N1", "-o", str(tmp_path / "site.mcap"),
                 "--rotate", "1h")
    assert result.code == 11 and "earlier rotation" in result.err
    assert (tmp_path / "site-0001.mcap").read_bytes() == b"yesterday"


def test_an_export_that_fails_leaves_nothing_and_names_the_file(cli: Cli, tmp_path: Path) -> None:
    """Times before 1970 (a logic analyzer's clock starts at 0) cannot go into MCAP, pcap or
    pcapng: one error naming the file, exit 11, and no output left half written."""
    early = tmp_path / "early.log"
    early.write_text("# rtu-capture v1\n# line: 19200 8E1\n# timing: exact\n0.001 02030C1E0004276C\n"
                     "0.010 0203080028025801F4000052B0\n")
    result = cli("export", str(early), "--mcap", str(tmp_path / "x.mcap"), "--rrd", str(tmp_path / "x.rrd"))
    assert result.code == 11 and result.err.count("\n") == 1
    assert result.err.startswith(f"error: {tmp_path / 'x.mcap'}: a frame starts 0.003583 s before 1970")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["early.log"]
    # Nor in pcap or pcapng, whose times are unsigned too (they were wrapped to 2106, or a traceback).
    for name in ("x.pcap", "x.pcapng"):
        refused = cli("export", str(early), "--pcap", str(tmp_path / name))
        assert refused.code == 11 and "frame #0 starts -0.003583 s from 1970" in refused.err, refused.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["early.log"]

"""Adding a function code is one codec (``decoders/modbus/codecs.py``): with it, a device's own
code is framed by its length rule, read as requests and responses, and paired, where without it
the same bytes are frames of no known role found by CRC search. The registry is changed in a
fresh interpreter before the framer builds its rule tables from it, as an entry in the source
would be (``docs/architecture.md``, "Adding a function code")."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from decoders.crc import crc_bytes
from decoders.modbus.codecs import CODECS, LAYOUTS

ROOT = Path(__file__).resolve().parent.parent
#: A device's own FC 100: a 6-byte request, an answer with a byte count at position 2.
REGISTER = """
from decoders.modbus import codecs
from decoders.modbus.layouts import Layout, counted, fixed
codecs.CODECS[100] = codecs.Codec(Layout(fixed(6), counted(2, 5)))
codecs.LAYOUTS[100] = codecs.CODECS[100].layout
"""
ANALYZE = """
import sys
from sniffer.cli import main
main(["analyze", sys.argv[1], "--format", "jsonl"])
"""


def _capture(folder: Path) -> Path:
    """Six exchanges of FC 100 in one host read: no silence cuts them, content must."""
    data = b""
    for value in range(6):
        request = bytes([5, 100, 0x01, value])
        answer = bytes([5, 100, 3, 0xAA, 0xBB, value])
        data += request + crc_bytes(request) + answer + crc_bytes(answer)
    capture = folder / "fc100.log"
    capture.write_text(f"# rtu-capture v1\n# line: 19200 8E1\n# timing: host\n1700000000.0 {data.hex(' ')}\n")
    return capture


def _frames(capture: Path, *, registered: bool) -> list[dict[str, object]]:
    script = (REGISTER if registered else "") + ANALYZE
    done = subprocess.run([sys.executable, "-c", script, str(capture)], cwd=ROOT, capture_output=True, text=True,
                          check=True)
    return [record for record in map(json.loads, done.stdout.splitlines()) if record["kind"] == "frame"]


def test_the_registry_is_every_table_of_a_function_code() -> None:
    assert {code: codec.layout for code, codec in CODECS.items()} == LAYOUTS
    assert 100 not in CODECS


def test_a_device_s_own_function_code_is_one_codec(tmp_path: Path) -> None:
    capture = _capture(tmp_path)
    without = _frames(capture, registered=False)
    assert [len(bytes.fromhex(str(frame["hex"]))) for frame in without] == [6, 8] * 6
    assert {frame["role"] for frame in without} == {"unknown"}
    registered = _frames(capture, registered=True)
    assert [frame["hex"] for frame in registered] == [frame["hex"] for frame in without]
    assert [frame["role"] for frame in registered] == ["request", "response"] * 6
    assert [frame["request_index"] for frame in registered[1::2]] == [0, 2, 4, 6, 8, 10]
    assert all(frame["crc_ok"] and frame["flags"] == [] for frame in registered)

"""Adding a function code is one codec (``decoders/modbus/codecs.py``): with it, a device's own
code is framed by its length rule, read as requests and responses, and paired, where without it
the same bytes are frames of no known role found by CRC search. The registry is changed in a
fresh interpreter before the framer builds its rule tables from it, as an entry in the source
would be (``docs/architecture.md``, "Adding a function code")."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import astuple
from pathlib import Path

from decoders.crc import crc_bytes
from decoders.modbus.annotate import Annotator
from decoders.modbus.codecs import BULK_SHAPES, CODECS, LAYOUTS, NOT_IN_BULK
from tests.property.test_annotation_cache import matched

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


def test_what_is_decoded_in_bulk_is_each_codec_s_to_say() -> None:
    """The bulk decoder finds its frames by the shape the registry gives their function, and by
    nothing else: FC 3 taken out of the bulk shapes is decoded one by one, to the same."""
    assert BULK_SHAPES[:256].tolist() == [CODECS[code].bulk if code in CODECS else NOT_IN_BULK
                                          for code in range(256)]
    exchanges = []
    for value in range(4):
        request, answer = bytes([7, 3, 0, 10, 0, 1]), bytes([7, 3, 2, 0, value])
        write = bytes([7, 6, 0, 20, 0, value])
        exchanges += [adu for part in (request, answer, write, write) for adu in [part + crc_bytes(part)]]
    (batch,) = [batch for batch in matched(exchanges) if len(batch)]

    def decoded() -> tuple[list[int], list[str], list[list[tuple[object, ...]]]]:
        annotated = Annotator(None).annotate_columnar(batch)
        columnar = annotated.columnar
        functions = [] if columnar is None else sorted(set(columnar.function.tolist()))
        return functions, annotated.summaries(), [list(map(astuple, params))
                                                  for params in annotated.message_params()]

    functions, summaries, params = decoded()
    assert functions == [3, 6]
    BULK_SHAPES[3] = NOT_IN_BULK
    try:
        assert decoded() == ([6], summaries, params)
    finally:
        BULK_SHAPES[3] = CODECS[3].bulk


#: A device's own FC 100 read like FC 3 (a request for a span of registers, answered by a byte
#: count and the words), decoded in bulk: its registry entries, as they would be in the source.
BULK_READ_CODE = """
from decoders.modbus import codecs, codes, columnar
from decoders.modbus.layouts import Layout, counted, fixed
from decoders.modbus.pdu_parse import read_request, registers_response
codecs.CODECS[100] = codecs.Codec(Layout(fixed(8), counted(2, 5)), read_request, registers_response, codecs.BULK_READ)
codecs.LAYOUTS[100], codecs.BULK_SHAPES[100] = codecs.CODECS[100].layout, codecs.BULK_READ
codes.MAX_QUANTITY[100] = columnar.MOST[100] = 125
codes.TABLE_NAMES[100] = "HR"
from decoders.crc import crc_bytes
from decoders.modbus.annotate import Annotator
from tests.property.test_annotation_cache import matched
exchanges = [part + crc_bytes(part) for value in range(3)
             for part in (bytes([7, 100, 0, 10, 0, 2]), bytes([7, 100, 4, 0, value, 1, 2]))]
(batch,) = [batch for batch in matched(exchanges) if len(batch)]
bulk, plain = Annotator(None).annotate_columnar(batch), Annotator(None).annotate_batch(batch)
print(len(bulk.columnar), bulk.summaries() == [decoding.summary for decoding in plain.decodings])
print([[(param.address, param.raw) for param in params] for params in bulk.message_params()]
      == [[(param.address, param.raw) for param in decoding.params] for decoding in plain.decodings])
print(bulk.summaries()[1])
"""


def test_a_device_s_own_read_is_decoded_in_bulk_by_its_shape() -> None:
    done = subprocess.run([sys.executable, "-c", BULK_READ_CODE], cwd=ROOT, capture_output=True, text=True, check=True)
    assert done.stdout.splitlines() == ["6 True", "True", "HR = 0000 0102 (2 registers)"]

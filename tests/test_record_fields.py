"""Every spelling of the frame record agrees with the one table of its fields
(``sniffer/encoding/fields.py``): the dict, the JSONL encoder, the MCAP rows, the MCAP
JSON schema and the field tables of docs/jsonl-output.md."""

from __future__ import annotations

import json
import re
from pathlib import Path

from decoders.decoded_batch import AnnotatedBatch
from decoders.modbus.annotate import Annotator
from decoders.pipeline import Decoder
from sniffer.encoding.fields import FRAME_FIELD_NAMES, FRAME_FIELDS, OPTIONAL_FRAME_FIELD_NAMES
from sniffer.encoding.records import FrameRecordEncoder
from sniffer.exports.mcap_export import FRAME_SCHEMA
from sniffer.io.registry import open_reader
from tests.conftest import SAMPLE_LOG
from tests.oracles import frame_record

DOCS = Path(__file__).resolve().parent.parent / "docs" / "jsonl-output.md"


#: A capture whose frames carry every optional field (UART errors, as a logic analyzer's has).
MARKED_CAPTURE = """# rtu-capture v1
# line: 19200 8E1
# timing: exact
# channels: TX RX
1700000000.000000000 00
# uart-errors: 0 framing
# channel: TX
1700000000.008000000 02 03 00 00 00 02 C4 38
# channel: RX
1700000000.020000000 02 03 04 00 2A 00 07 79 37
# uart-errors: 3 parity
"""


def annotated_batches(path: Path = SAMPLE_LOG) -> list[tuple[AnnotatedBatch, tuple[str, ...]]]:
    """The capture's annotated batches, each with the capture's channel names."""
    reader = open_reader(str(path))
    assert reader.info.line is not None
    decoder, annotator = Decoder(reader.info.line, reader.info.timing), Annotator()
    batches = [m for chunks in reader.batches() for m in decoder.feed(chunks)] + decoder.flush()
    reader.close()
    return [(annotator.annotate_batch(b), reader.info.channels) for b in batches if len(b)]


def every_batch(tmp_path: Path) -> list[tuple[AnnotatedBatch, tuple[str, ...]]]:
    marked = tmp_path / "marked.log"
    marked.write_text(MARKED_CAPTURE)
    return annotated_batches() + annotated_batches(marked)


def test_the_dict_has_the_fields_in_order(tmp_path: Path) -> None:
    optional_seen = set()
    for batch, channels in every_batch(tmp_path):
        for message in batch:
            names = tuple(frame_record(message, channels))
            assert names[: len(FRAME_FIELD_NAMES)] == FRAME_FIELD_NAMES
            extra = names[len(FRAME_FIELD_NAMES) :]
            assert extra == tuple(name for name in OPTIONAL_FRAME_FIELD_NAMES if name in extra)
            optional_seen.update(extra)
    assert optional_seen == set(OPTIONAL_FRAME_FIELD_NAMES)


def test_the_jsonl_encoder_and_the_mcap_rows_have_the_fields(tmp_path: Path) -> None:
    for batch, channels in every_batch(tmp_path):
        reference = [frame_record(message, channels) for message in batch]
        encoder, fixed_encoder = FrameRecordEncoder(), FrameRecordEncoder(exact=False)
        encoder.channels = fixed_encoder.channels = channels
        exact = bytes(encoder.rows(batch, end=b"\n").data).decode().splitlines()
        assert [json.loads(line) for line in exact] == reference
        assert [tuple(json.loads(line)) for line in exact] == [tuple(record) for record in reference]
        fixed = bytes(fixed_encoder.rows(batch, end=b"\n").data).decode().splitlines()
        assert [sorted(json.loads(line)) for line in fixed] == [sorted(record) for record in reference]


def test_the_mcap_schema_has_the_fields_and_their_types() -> None:
    properties = FRAME_SCHEMA["properties"]
    assert sorted(properties) == sorted(FRAME_FIELD_NAMES + OPTIONAL_FRAME_FIELD_NAMES)
    assert sorted(FRAME_SCHEMA["required"]) == sorted(FRAME_FIELD_NAMES)
    for field in FRAME_FIELDS:
        declared = properties[field.name]["type"]
        assert tuple(declared if isinstance(declared, list) else [declared]) == field.types, field.name


def test_the_documentation_lists_every_field() -> None:
    documented = re.findall(r"^\| `(\w+)` \|", DOCS.read_text(), re.MULTILINE)
    every = set(FRAME_FIELD_NAMES + OPTIONAL_FRAME_FIELD_NAMES)
    assert every <= set(documented), every - set(documented)

"""Every spelling of the frame record agrees with the one table of its fields
(``sniffer/encoding/fields.py``): the dict, the JSONL encoder, the MCAP rows, the MCAP
JSON schema and the field tables of docs/jsonl-output.md."""

from __future__ import annotations

import json
import re
from pathlib import Path

from decoders.message import AnnotatedBatch
from decoders.modbus.annotate import Annotator
from decoders.pipeline import Decoder
from sniffer.encoding.fields import FRAME_FIELD_NAMES, FRAME_FIELDS
from sniffer.encoding.records import FrameRecordEncoder, frame_record
from sniffer.exports.mcap_export import FRAME_SCHEMA
from sniffer.io.registry import open_reader
from tests.conftest import SAMPLE_LOG

DOCS = Path(__file__).resolve().parent.parent / "docs" / "jsonl-output.md"


def annotated_batches() -> list[AnnotatedBatch]:
    reader = open_reader(str(SAMPLE_LOG))
    assert reader.info.line is not None
    decoder, annotator = Decoder(reader.info.line, reader.info.timing), Annotator()
    batches = [m for chunks in reader.batches() for m in decoder.feed(chunks)] + decoder.flush()
    reader.close()
    return [annotator.annotate_batch(b) for b in batches if len(b)]


def test_the_dict_has_the_fields_in_order() -> None:
    for batch in annotated_batches():
        for message in batch:
            assert tuple(frame_record(message)) == FRAME_FIELD_NAMES


def test_the_jsonl_encoder_and_the_mcap_rows_have_the_fields() -> None:
    for batch in annotated_batches():
        exact = bytes(FrameRecordEncoder().rows(batch, end=b"\n").data).decode().splitlines()
        assert exact and all(tuple(json.loads(line)) == FRAME_FIELD_NAMES for line in exact)
        fixed = bytes(FrameRecordEncoder(exact=False).rows(batch, end=b"\n").data).decode().splitlines()
        assert fixed and all(sorted(json.loads(line)) == sorted(FRAME_FIELD_NAMES) for line in fixed)


def test_the_mcap_schema_has_the_fields_and_their_types() -> None:
    properties = FRAME_SCHEMA["properties"]
    assert sorted(properties) == sorted(FRAME_FIELD_NAMES)
    assert FRAME_SCHEMA["required"] == list(properties)
    for field in FRAME_FIELDS:
        declared = properties[field.name]["type"]
        assert tuple(declared if isinstance(declared, list) else [declared]) == field.types, field.name


def test_the_documentation_lists_every_field() -> None:
    documented = re.findall(r"^\| `(\w+)` \|", DOCS.read_text(), re.MULTILINE)
    assert set(FRAME_FIELD_NAMES) <= set(documented), set(FRAME_FIELD_NAMES) - set(documented)

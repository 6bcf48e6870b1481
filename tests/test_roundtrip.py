"""Every reader/writer pair of the registry round-trips a capture losslessly."""

from __future__ import annotations

from itertools import product
from pathlib import Path

import pytest

from decoders.capture import Chunk
from sniffer.io.registry import all_formats, open_reader, open_writer
from tests.conftest import SAMPLE_LOG

FORMATS = sorted(all_formats())


def read_all(path: Path) -> tuple[object, list[Chunk], list[str]]:
    reader = open_reader(str(path))
    chunks = [c for b in reader.batches() for c in b.chunks()]
    reader.close()
    return reader.info, chunks, reader.late_notes


@pytest.mark.parametrize(("via", "to"), list(product(FORMATS, FORMATS)))
def test_round_trip(tmp_path: Path, via: str, to: str) -> None:
    original_info, original_chunks, _ = read_all(SAMPLE_LOG)
    paths = []
    source = SAMPLE_LOG
    for step, name in enumerate((via, to)):
        fmt = all_formats()[name]
        target = tmp_path / f"step{step}{fmt.suffixes[0]}"
        reader = open_reader(str(source))
        writer = open_writer(str(target), reader.info)
        for batch in reader.batches():
            writer.write_batch(batch)
        writer.close()
        reader.close()
        paths.append(target)
        source = target
    info, chunks, _ = read_all(paths[-1])
    assert info == original_info
    assert chunks == original_chunks


def test_text_round_trip_is_byte_identical(tmp_path: Path) -> None:
    reader = open_reader(str(SAMPLE_LOG))
    target = tmp_path / "copy.log"
    writer = open_writer(str(target), reader.info)
    for batch in reader.batches():
        writer.write_batch(batch)
    writer.close()
    assert target.read_bytes() == SAMPLE_LOG.read_bytes()

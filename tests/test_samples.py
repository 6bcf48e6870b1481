"""The shipped sample captures are what captures/make_samples.py makes."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from sniffer.io.registry import open_reader
from tests.conftest import CAPTURES


def load_generator() -> object:
    spec = importlib.util.spec_from_file_location("make_samples", CAPTURES / "make_samples.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def chunks(path: Path) -> list[object]:
    reader = open_reader(str(path))
    out = [(reader.info, c) for b in reader.batches() for c in b.chunks()]
    reader.close()
    return out


def test_samples_regenerate_identically(tmp_path: Path) -> None:
    generator = load_generator()
    written = generator.write_samples(tmp_path)  # type: ignore[attr-defined]
    assert written
    for path in written:
        shipped = CAPTURES / path.name
        assert shipped.exists(), f"{shipped.name} is not shipped"
        if path.suffix == ".log":
            assert path.read_bytes() == shipped.read_bytes(), f"{path.name} differs from the generator's output"
        else:
            assert chunks(path) == chunks(shipped)

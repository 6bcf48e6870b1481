"""Real Modbus recordings made by other people (``../shared/real/``) with their ground truth.

The logic-analyzer recordings were turned into text captures by sigrok-cli
(``sigrok-cli-text/``, one byte per line, stamped with the end of its stop bit).
sigrok's own Modbus decoder lists every frame it decoded with a correct CRC
(``sigrok-test/modbus/*.output``, sample ranges at the analyzer's rate): those
frames, mapped onto the capture's bytes by their times, are the ground truth.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from decoders.capture import Chunk, TimingQuality
from decoders.line import LineSettings
from sniffer.io.registry import open_reader

REAL = Path(__file__).resolve().parent.parent.parent / "shared" / "real"
TEXT = REAL / "sigrok-cli-text"
EXPECTED = REAL / "sigrok-test" / "modbus"
#: Text capture → sigrok-test output with sigrok's expected decode (target0_val0 has none:
#: its test.conf entry decodes the graph-tool recording).
RECORDINGS = {
    "sr_brainchild-io-16do.log": "brainchild_io_16do.output",
    "sr_flowmeter_graph_tool.log": "flowmeter_graph_tool.output",
    "sr_flowmeter_target0_val0.log": None,
    "sr_flowmeter_target_0liter_per_min.log": "flowmeter_target_0liter_per_min.output",
    "sr_flowmeter_target_15liter_per_min.log": "flowmeter_target_15liter_per_min.output",
    "sr_flowmeter_target_20liter_per_min.log": "flowmeter_target_20liter_per_min.output",
}
_RATE = re.compile(r"logic analyzer at (\d+) Hz")
_ANNOTATION = re.compile(r'^(\d+)-(\d+) modbus: (cs|sc)-([a-z-]+): "(.*)"$')
T0_NS = 1_700_000_000_000_000_000


@dataclass
class Recording:
    """A real capture: its bytes as recorded (one chunk per byte) and sigrok's frames."""

    name: str
    line: LineSettings
    chunks: list[Chunk]
    #: (first byte, one past the last byte) of every frame sigrok decoded with a correct CRC.
    frames: list[tuple[int, int]] | None

    @property
    def data(self) -> bytes:
        return b"".join(chunk.data for chunk in self.chunks)


def available() -> bool:
    return TEXT.is_dir()


def load(name: str) -> Recording:
    path = TEXT / name
    reader = open_reader(str(path))
    assert reader.info.timing is TimingQuality.EXACT and reader.info.line is not None
    chunks = [chunk for batch in reader.batches() for chunk in batch.chunks()]
    reader.close()
    expected = RECORDINGS[name]
    frames = None
    if expected is not None:
        rate_match = _RATE.search(path.read_text())
        assert rate_match is not None, path
        rate = int(rate_match.group(1))
        frames = _sigrok_frames(EXPECTED / expected, rate, chunks, reader.info.line)
    return Recording(name, reader.info.line, chunks, frames)


def _sigrok_frames(output: Path, rate: int, chunks: list[Chunk], line: LineSettings) -> list[tuple[int, int]]:
    """sigrok's CRC-correct frames as byte ranges: a frame runs from the byte whose start
    bit begins at its server-id annotation to the byte whose stop bit ends its CRC
    annotation (sigrok ends that at the last data bit: up to 3 bits before)."""
    ends = [chunk.t_end_ns for chunk in chunks for _ in chunk.data]
    starts = [end - round(line.char_time_ns) for end in ends]
    bit_ns = 1e9 / line.baud
    frames: set[tuple[int, int]] = set()
    first_sample: dict[str, int] = {}
    for text in output.read_text().splitlines():
        match = _ANNOTATION.match(text)
        if match is None:
            continue
        begin, end, side, field, value = match.groups()
        if field == "server-id":
            first_sample[side] = int(begin)
        elif field == "crc" and value == "CRC correct":
            first = _nearest(starts, T0_NS + first_sample[side] * 10**9 // rate, 3 * bit_ns)
            last = _nearest(ends, T0_NS + int(end) * 10**9 // rate, 3 * bit_ns)
            frames.add((first, last + 1))
    return sorted(frames)


def _nearest(times: list[int], moment: int, tolerance: float) -> int:
    index = min(range(len(times)), key=lambda k: abs(times[k] - moment))
    assert abs(times[index] - moment) <= tolerance, (index, times[index], moment)
    return index

"""Devices with known register maps, polled: the ground truth of ``profiles draft``.

    python -m benchmarks.device_maps [--devices 8] [--polls 60] [--seed 1]

Each device (a slave) has a random map laid out from register 0: IEEE 754 floats in either word
order (measurements moving a little from one poll to the next), 32-bit counters in either word
order (counting up through a carry of their high word), enumerations and states (a few values),
signed words around 0, plain words that vary, and texts (a serial number, a model name). A
master polls each map in reads of up to 60 registers, cut where a value ends, as PLCs poll. The
capture is written, ``profiles draft`` is run on every slave, and the share of values whose type
(and word order) the draft recovered is printed: the figure ``docs/performance.md`` quotes, and
``tests/test_profile_draft.py`` holds at 90 % or more.
"""

from __future__ import annotations

import argparse
import random
import struct
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path

from benchmarks.bench_framing import exchange
from benchmarks.bench_memory import write_capture
from benchmarks.wire_synthesis import Transmission

KINDS = ("f32 big", "f32 little", "u32 big", "u32 little", "enum", "i16", "u16", "string")
MOST_READ = 60


@dataclass
class Value:
    """One value of a map: its first register, kind (one of :data:`KINDS`), registers, state."""

    address: int
    kind: str
    registers: int
    state: float | int | str

    @property
    def expected(self) -> tuple[str, str | None]:
        """The type (and word order of a value over two registers) a draft should find."""
        if self.kind in ("enum", "u16"):
            return "u16", None
        if self.kind in ("i16", "string"):
            return self.kind, None
        kind, order = self.kind.split()
        return kind, order

    def words(self, rng: random.Random) -> list[int]:
        """Its registers now, after it moved on since the last poll."""
        kind = self.kind
        if kind.startswith("f32"):
            self.state = float(self.state) * (1 + rng.gauss(0, 0.002)) + rng.gauss(0, 0.01)
            high, low = struct.unpack(">HH", struct.pack(">f", self.state))
            return [high, low] if kind.endswith("big") else [low, high]
        if kind.startswith("u32"):
            self.state = (int(self.state) + rng.randint(1, 40)) % (1 << 32)
            high, low = int(self.state) >> 16, int(self.state) & 0xFFFF
            return [high, low] if kind.endswith("big") else [low, high]
        if kind == "enum":
            return [rng.choice((0, 1, 3, 4, 8)[: int(self.state)])]
        if kind == "i16":
            return [rng.randint(-40, 40) & 0xFFFF]
        if kind == "u16":
            return [rng.randint(0, 20000)]
        text = str(self.state).encode().ljust(2 * self.registers, b"\0")
        return list(struct.unpack(f">{self.registers}H", text))


def device_map(rng: random.Random) -> list[Value]:
    """A map of 12 to 24 values from register 0, a gap now and then."""
    values, address = [], 0
    for _ in range(rng.randint(12, 24)):
        kind = rng.choice(KINDS)
        if kind.startswith("f32"):
            value = Value(address, kind, 2, rng.uniform(1, 1000))
        elif kind.startswith("u32"):
            value = Value(address, kind, 2, 0xFFFF - rng.randint(0, 600) + (rng.randint(0, 50) << 16))
        elif kind == "string":
            text = rng.choice([f"SN-{rng.randint(0, 999999):06d}", "PUMP-CTRL V2", "FM200 rev.B", "ACME MX-7"])
            value = Value(address, kind, (len(text) + 1) // 2 + rng.randint(0, 2), text)
        else:
            value = Value(address, kind, 1, rng.randint(2, 5) if kind == "enum" else 0)
        values.append(value)
        address += value.registers + (rng.random() < 0.1)
    return values


def polls(slave: int, values: list[Value], rng: random.Random) -> list[Transmission]:
    """One poll of the whole map: reads of up to :data:`MOST_READ` registers, cut between values."""
    transmissions = []
    start = 0
    while start < len(values):
        stop = start
        while stop < len(values) and values[stop].address + values[stop].registers - values[start].address <= MOST_READ:
            stop += 1
        chosen = values[start:stop]
        first, last = chosen[0].address, chosen[-1].address + chosen[-1].registers
        words = [0] * (last - first)
        for value in chosen:
            words[value.address - first : value.address - first + value.registers] = value.words(rng)
        request = struct.pack(">BBHH", slave, 3, first, last - first)
        answer = struct.pack(f">BBB{len(words)}H", slave, 3, 2 * len(words), *words)
        transmissions += exchange(rng, request, answer)
        start = stop
    return transmissions


def write_devices(path: Path, devices: int, rounds: int, seed: int) -> dict[int, list[Value]]:
    """A capture of ``devices`` slaves polled ``rounds`` times; each slave's map."""
    rng = random.Random(seed)
    maps = {slave: device_map(rng) for slave in range(1, devices + 1)}
    traffic = [transmission for _ in range(rounds) for slave, values in maps.items()
               for transmission in polls(slave, values, rng)]
    write_capture(path, len(traffic), lambda frames, piece: traffic[piece : piece + frames])
    return maps


def recovered(maps: dict[int, list[Value]], drafts: dict[int, str]) -> tuple[int, int, list[str]]:
    """How many values each slave's draft (TOML text) typed as the map does, of how many, and
    what it missed."""
    right, missed = 0, []
    total = sum(map(len, maps.values()))
    for slave, values in maps.items():
        guessed = {entry["address"]: (entry.get("type", "u16"), entry.get("word_order"))
                   for entry in tomllib.loads(drafts[slave]).get("parameter", [])}
        for value in values:
            kind, order = value.expected
            found = guessed.get(value.address)
            if found is not None and found[0] == kind and (order is None or found[1] == order):
                right += 1
            else:
                missed.append(f"slave {slave} register {value.address}: {value.kind}, drafted {found}")
    return right, total, missed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--devices", type=int, default=8)
    parser.add_argument("--polls", type=int, default=60)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    from sniffer.cli import main as rtusniff

    with tempfile.TemporaryDirectory() as folder:
        capture = Path(folder) / "devices.mcap"
        maps = write_devices(capture, args.devices, args.polls, args.seed)
        drafts = {}
        for slave in maps:
            out = Path(folder) / f"slave{slave}.toml"
            rtusniff(["profiles", "draft", str(capture), "--slave", str(slave), "-o", str(out), "-q"])
            drafts[slave] = out.read_text()
    right, total, missed = recovered(maps, drafts)
    print(f"{args.devices} devices, {total} values, {args.polls} polls: draft recovered {right} of {total} types "
          f"({100 * right / total:.1f} %)")
    for line in missed:
        print(f"  missed: {line}")


if __name__ == "__main__":
    main()

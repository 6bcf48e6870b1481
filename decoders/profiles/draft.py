"""A profile drafted from what a slave's registers were seen to hold (``profiles draft``).

For an undocumented device the capture is the only map: every register read or written, with
the values seen. :class:`Observations` takes them frame by frame (the registers a frame carries
together, as the decoded form gives them); :func:`draft` guesses what each register, or run of
registers, holds, and says on what evidence.

The rules, and their weights:

1. **Text**: two or more registers read together whose bytes are all printable ASCII or NUL,
   at least half of them letters or digits, holding at most :data:`FEW_VALUES` texts: a
   ``string`` over them (weight :data:`TEXT_WEIGHT`, surer than any pair).
2. **A value over two registers**, where a register and the next are read together in at least
   :data:`TOGETHER` of the frames that read it (two zeros say nothing). Each reading is read
   as an ``f32`` in both word orders. A float is *plausible* where it is 0 or its magnitude
   lies in 10⁻⁶..10⁹ (a measurement), *steady* where it moves by at most :data:`STEADY` of its
   size a reading (the medians). An order in which every reading is plausible is an ``f32``
   guess weighing 3 where it moves (steadily, or where the other order is noise), 1 where it
   holds still; one more where the other order is noise; where it moves, one more where its
   low word (the mantissa's last bits) takes a new value in most readings, and the share of
   readings whose low word's high byte is new (a small or signed word beside a float's high
   word reads as a float too, but its high byte keeps to few values). A pair at an even
   address weighs :data:`ALIGNED` more (maps mostly put them there: of two cuts that weigh
   alike otherwise, the aligned one wins). A *counter* (``u32``, weight 3): in an
   order where it rises at least :data:`COUNTED` times by small steps, never goes down (but for
   a wrap), and its high word carried (without a carry two words are as good a guess).
3. Of the ways to cut each run of consecutive registers into texts, pairs and single
   registers, the one whose guesses weigh most in all is drafted: a float at 2-3 read from 0
   also reads, shifted by one, as a constant "float" at 1-2, a weaker guess.
4. **One register**: ``i16`` where it takes values just below 0 (16#F000 and up) and small
   positive ones; else ``u16``, said to be constant, or to take few values (an enumeration or
   a state: :data:`FEW_VALUES` or fewer), or to vary.

Coils and discrete inputs are drafted as ``[[coil]]`` and ``[[input]]`` with how often each was
seen on and off. The evidence of each guess is kept with it (:attr:`Guess.evidence`), and the
draft writes it as a comment above the entry.
"""

from __future__ import annotations

import math
import struct
from collections import defaultdict
from dataclasses import dataclass, field
from itertools import pairwise

from decoders.modbus.codes import COILS, DATA_TABLE, INPUTS, REGISTERS

#: A pair is read as one value where it is read together in this share of the frames or more.
TOGETHER = 0.9
#: A steady float moves by at most this share of its size per reading (the medians of both).
STEADY = 0.05
#: At most this many distinct values: an enumeration, a state, or a text's few versions.
FEW_VALUES = 6
#: The readings kept per register (the first ones): enough to tell, bounded on a long capture.
KEPT_READINGS = 4096
_SMALLEST, _LARGEST = 1e-6, 1e9
_NEGATIVE = 0xF000


@dataclass
class Seen:
    """What one register (or coil) was seen to hold: how often read and written, its values in
    order (the first :data:`KEPT_READINGS`), how often it changed, its least and greatest."""

    reads: int = 0
    writes: int = 0
    values: list[int] = field(default_factory=list)
    changes: int = 0
    least: int = 0xFFFF
    most: int = 0
    last: int | None = None

    def add(self, raw: int, *, written: bool) -> None:
        if written:
            self.writes += 1
        else:
            self.reads += 1
        if self.last is not None and raw != self.last:
            self.changes += 1
        self.last = raw
        self.least, self.most = min(self.least, raw), max(self.most, raw)
        if len(self.values) < KEPT_READINGS:
            self.values.append(raw)


class Observations:
    """The registers, coils and inputs of one slave as frames carried them."""

    def __init__(self) -> None:
        #: By table (:data:`~decoders.modbus.codes.REGISTERS`, ``COILS``, ``INPUTS``) and address.
        self.seen: dict[int, dict[int, Seen]] = {REGISTERS: {}, COILS: {}, INPUTS: {}}
        #: Registers read together: the words of each pair (address, address + 1) in frames
        #: carrying both, and the first register and words of each frame read (for texts).
        self.pairs: dict[int, list[tuple[int, int]]] = defaultdict(list)
        self.runs: list[tuple[int, tuple[int, ...]]] = []
        self.frames = 0

    def add(self, function: int, values: list[tuple[int, int]], *, written: bool) -> None:
        """One frame's values (address and raw word or bit) of the data table ``function`` names."""
        table = DATA_TABLE.get(function, REGISTERS)
        self.frames += 1
        seen = self.seen[table]
        for address, raw in values:
            seen.setdefault(address, Seen()).add(raw, written=written)
        if table != REGISTERS or written:
            return
        words = dict(values)
        for address, raw in values:
            following = words.get(address + 1)
            pairs = self.pairs[address]
            if following is not None and len(pairs) < KEPT_READINGS:
                pairs.append((raw, following))
        if len(values) > 1 and len(self.runs) < KEPT_READINGS:
            ordered = sorted(values)
            first = ordered[0][0]
            if ordered[-1][0] - first == len(ordered) - 1:  # one run of registers
                self.runs.append((first, tuple(raw for _, raw in ordered)))


@dataclass
class Guess:
    """What a register (or coil) is guessed to hold: ``kind`` (``parameter``, ``coil``,
    ``input``), its ``type`` and ``word_order``, how many ``registers``, and the evidence."""

    kind: str
    address: int
    type: str = "u16"
    word_order: str = "big"
    registers: int = 1
    access: str = "r"
    evidence: list[str] = field(default_factory=list)


def draft(observations: Observations) -> list[Guess]:
    """The guesses, register after register, then coils and inputs (see the module docstring)."""
    registers = observations.seen[REGISTERS]
    guesses: list[Guess] = []
    for guess in _registers(observations):
        guess.access = _access(registers, guess)
        guess.evidence.insert(0, _seen(registers, guess))
        guesses.append(guess)
    for table, kind in ((COILS, "coil"), (INPUTS, "input")):
        for address, seen in sorted(observations.seen[table].items()):
            on = sum(seen.values)
            guesses.append(Guess(kind, address, "bool", access="rw" if seen.writes else "r", evidence=[
                f"read {seen.reads} times, written {seen.writes}; on {on} of {len(seen.values)} times, "
                f"{seen.changes} changes"]))
    return guesses


def _registers(observations: Observations) -> list[Guess]:
    """The registers' guesses, the pairs chosen where their evidence weighs most in all: a
    float at 2-3 read from 0 also reads, shifted, as a constant "float" at 1-2 (a weak guess); of
    the ways to cut a run of registers into pairs and singles, the one whose pairs' weights
    (:func:`_pair`) add up to most wins."""
    registers = observations.seen[REGISTERS]
    addresses = sorted(registers)
    found = {address: text for address in addresses if (text := _text(observations, address)) is not None}
    # A text's tail is text too: only those that no text from the register before holds.
    texts = {address: text for address, text in found.items()
             if not (address - 1 in found and found[address - 1].registers > text.registers)}
    pairs = {address: pair for address in addresses if (pair := _pair(observations, address)) is not None}
    # best[i]: the most weight of the registers from addresses[i] on, and the step taken there.
    best: list[tuple[float, int]] = [(0.0, 1)] * (len(addresses) + 1)
    for place in range(len(addresses) - 1, -1, -1):
        address = addresses[place]
        options = []
        for guess, weight in ((texts.get(address), TEXT_WEIGHT), pairs.get(address, (None, 0.0))):
            if guess is not None and place + guess.registers <= len(addresses) and \
                    addresses[place + guess.registers - 1] == address + guess.registers - 1:
                options.append((best[place + guess.registers][0] + weight, guess.registers))
        # Last: of guesses that weigh alike, one over several registers from here wins (a text's
        # tail is a text too).
        options.append((best[place + 1][0], 1))
        best[place] = max(options, key=lambda option: option[0])
    guesses: list[Guess] = []
    place = 0
    while place < len(addresses):
        address, step = addresses[place], best[place][1]
        text, pair = texts.get(address), pairs.get(address)
        guess = (text if text is not None and text.registers == step
                 else pair[0] if pair is not None and step == 2 else _single(address, registers[address]))
        guesses.append(guess)
        place += guess.registers
    return guesses


#: What a text's guess weighs against pairs (a text is the surest guess of all).
TEXT_WEIGHT = 10.0


def _seen(registers: dict[int, Seen], guess: Guess) -> str:
    seen = [registers[address] for address in range(guess.address, guess.address + guess.registers)
            if address in registers]
    reads, writes, changes = (max(getattr(one, name) for one in seen) for name in ("reads", "writes", "changes"))
    words = " ".join(f"{one.least:04X}..{one.most:04X}" for one in seen)
    return f"read {reads} times, written {writes}, {changes} changes; words {words}"


def _access(registers: dict[int, Seen], guess: Guess) -> str:
    written = any(registers[address].writes for address in range(guess.address, guess.address + guess.registers)
                  if address in registers)
    read = any(registers[address].reads for address in range(guess.address, guess.address + guess.registers)
               if address in registers)
    return "rw" if written and read else "w" if written else "r"


def _text(observations: Observations, address: int) -> Guess | None:
    """A string starting at ``address``: the most registers from it that every frame reading
    them holds as text (printable ASCII or NUL, at least :data:`LETTERS` letters or digits and
    half its characters; at most :data:`FEW_VALUES` texts), two at least."""
    runs = [(first, words) for first, words in observations.runs if first <= address < first + len(words)]
    if not runs:
        return None
    longest = min(first + len(words) for first, words in runs) - address
    best: set[tuple[int, ...]] | None = None
    for count in range(2, longest + 1):
        texts = {words[address - first : address - first + count] for first, words in runs}
        if len(texts) > FEW_VALUES or not all(map(_printable, texts)):
            break
        best = texts
    if best is None:
        return None
    count = len(next(iter(best)))
    shown = ", ".join(repr(_string(words)) for words in sorted(best)[:3])
    return Guess("parameter", address, "string", registers=count,
                 evidence=[f"every reading of its {count} registers is text: {shown}"])


#: A text holds at least this many letters or digits.
LETTERS = 3


def _printable(words: tuple[int, ...]) -> bool:
    data = struct.pack(f">{len(words)}H", *words)
    if not all(32 <= byte < 127 or byte == 0 for byte in data):
        return False
    if data[:1] == b"\0":
        return False  # a text starts with its first character
    written = data.rstrip(b"\0")
    letters = sum(chr(byte).isalnum() for byte in written)
    return b"\0" not in written and letters >= LETTERS and 2 * letters >= len(written)


def _string(words: tuple[int, ...]) -> str:
    return struct.pack(f">{len(words)}H", *words).rstrip(b"\0").decode("ascii")


def _pair(observations: Observations, address: int) -> tuple[Guess, float] | None:
    """A value over ``address`` and the next register, where they are read together, and the
    weight of its evidence: a float that moves steadily where the other order is noise 4, that
    moves 3, that holds still 1 (2 where the other order is noise); a counter 3."""
    pairs = observations.pairs.get(address, [])
    reads = observations.seen[REGISTERS][address].reads
    if len(pairs) < 2 or len(pairs) < TOGETHER * reads:
        return None
    if all(high == 0 and low == 0 for high, low in pairs):
        return None  # zeros say nothing of a type
    floats = {order: _floats(pairs, order) for order in ("big", "little")}
    found: list[tuple[Guess, float]] = []
    for order, other in (("big", "little"), ("little", "big")):
        values = floats[order]
        if not all(map(_plausible, values)):
            continue
        noise = not all(map(_plausible, floats[other]))
        moving, steady = _moving(values), _steady(values)
        if moving and not steady and not noise:
            continue
        # A measurement's low word is its mantissa's last bits: where it moves, they take many values.
        lows = [pair[1] if order == "big" else pair[0] for pair in pairs]
        weight = (3.0 if moving else 1.0) + noise + (moving and 2 * len(set(lows)) > len(pairs))
        # And all 16 bits: its high byte too (a small word's, or a signed one's, keeps to few).
        weight += len({low >> 8 for low in lows}) / len(lows) if moving else 0.0
        weight += ALIGNED if address % 2 == 0 else 0.0
        said = ", moving steadily" if moving and steady else ", moving" if moving else ", holding still"
        evidence = [f"as f32 {order} every reading is a measurement, {min(values):.7g} to {max(values):.7g}{said}",
                    f"as f32 {other}: " + _described(floats[other])]
        found.append((Guess("parameter", address, "f32", order, 2, evidence=evidence), weight))
    for order in ("big", "little"):
        counts = [(high << 16 | low) if order == "big" else (low << 16 | high) for high, low in pairs]
        steps = [b - a if b >= a else b + (1 << 32) - a for a, b in pairwise(counts)]
        rising = sum(step > 0 for step in steps)
        carried = len({count >> 16 for count in counts}) > 1
        if carried and rising >= COUNTED and all(step < _COUNTER_STEP for step in steps):
            found.append((Guess("parameter", address, "u32", order, 2, evidence=[
                f"as u32 {order} it counts up from {counts[0]} to {counts[-1]}, by small steps, its high word "
                "carrying"]), 3.0 + (ALIGNED if address % 2 == 0 else 0.0)))
    return max(found, key=lambda item: item[1], default=None)


#: What a value over two registers at an even address weighs more: maps mostly put them there,
#: and of two cuts that weigh alike otherwise, the aligned one wins.
ALIGNED = 0.1
#: A counter rose at least this often; by less than this a reading.
COUNTED, _COUNTER_STEP = 3, 1 << 18


def _floats(pairs: list[tuple[int, int]], order: str) -> list[float]:
    return [struct.unpack(">f", struct.pack(">HH", *(pair if order == "big" else pair[::-1])))[0] for pair in pairs]


def _plausible(value: float) -> bool:
    return value == 0 or (math.isfinite(value) and _SMALLEST <= abs(value) <= _LARGEST)


def _moving(values: list[float]) -> bool:
    return len(set(values)) > 1


def _steady(values: list[float]) -> bool:
    """Whether the readings move by little of their size (the median's), a reading to the next."""
    if not all(math.isfinite(value) for value in values):
        return False
    sizes = sorted(abs(value) for value in values if value)
    steps = sorted(abs(b - a) for a, b in pairwise(values))
    return not steps or steps[len(steps) // 2] <= STEADY * (sizes[len(sizes) // 2] if sizes else 1.0)


def _described(values: list[float]) -> str:
    finite = [value for value in values if math.isfinite(value)]
    if len(finite) < len(values):
        return f"{len(values) - len(finite)} of {len(values)} readings are NaN or infinite (noise)"
    implausible = sum(not _plausible(value) for value in finite)
    return (f"{implausible} of {len(values)} readings out of 1e-6..1e9 (noise), {min(finite):.3g} to "
            f"{max(finite):.3g}" if implausible else f"{min(finite):.7g} to {max(finite):.7g}, jumping")


def _single(address: int, seen: Seen) -> Guess:
    values = seen.values
    distinct = sorted(set(values))
    if any(value >= _NEGATIVE for value in distinct) and any(value < 0x1000 for value in distinct):
        signed = [value - 0x10000 if value & 0x8000 else value for value in distinct]
        return Guess("parameter", address, "i16", evidence=[f"as i16 it lies around 0: {min(signed)} to {max(signed)}"])
    if len(distinct) == 1:
        said = f"constant {distinct[0]} (16#{distinct[0]:04X})"
    elif len(distinct) <= FEW_VALUES:
        said = f"takes {len(distinct)} values: {', '.join(map(str, distinct))} (an enumeration or a state?)"
    else:
        said = f"varies, {len(distinct)} values"
    return Guess("parameter", address, evidence=[said])

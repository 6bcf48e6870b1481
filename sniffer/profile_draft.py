"""``rtusniff profiles draft CAPTURE --slave N``: a profile drafted from a capture.

The capture is decoded as every command decodes it, registers as plain words (no profile), and
the values one slave reported or was written are gathered (:class:`DraftCollector`, a sink of
value rows); :func:`decoders.profiles.draft.draft` guesses each register's type, and the draft
is written as a profile whose every entry says in a comment what it was seen to hold and on what
evidence its type rests.
"""

from __future__ import annotations

from pathlib import Path

from decoders.profiles.draft import Guess, Observations, draft
from decoders.profiles.parse import MAX_PROFILE_BYTES
from sniffer.encoding.value_rows import ValueChoice, ValueRow, ValueRows
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.profile_text import Entry, checked_profile_text, profile_text


class DraftCollector(ValueRows):
    """The values one slave reported or was written, as :class:`Observations`."""

    def __init__(self, slave: int) -> None:
        super().__init__(ValueChoice(slaves=frozenset({slave})))
        self.observations = Observations()

    def output(self, row: ValueRow) -> None:
        # A write the slave refused says nothing of what it holds.
        values = [(param.address, param.raw) for param, valid in zip(row.params, row.valid, strict=True)
                  if valid and param.raw is not None]
        if values:
            self.observations.add(row.function, values, written=row.kind == "written")


def draft_text(collector: DraftCollector, *, capture: str, slave: int, profile_id: str, name: str) -> tuple[str, int]:
    """The drafted profile's TOML, and how many entries it has."""
    guesses = draft(collector.observations)
    source = f"drafted from {Path(capture).name}, slave {slave}"
    entries = [_entry(guess, source) for guess in guesses]
    comments = [f"Drafted by 'rtusniff profiles draft' from {Path(capture).name}, slave {slave}: "
                f"{collector.observations.frames} frames of its values.",
                "Every type below is a guess from the values seen, with its evidence: check each against "
                "the device, and give the registers their names."]
    head = {"id": profile_id, "name": name, "sources": [source]}
    text = profile_text(head, entries, comments)
    if len(text) > MAX_PROFILE_BYTES:  # thousands of registers: their evidence goes first
        for entry in entries:
            entry.comments = entry.comments[:1]
        text = profile_text(head, entries, [*comments, "Too many registers for every guess's evidence: each entry "
                                            "says what was seen of it."])
    if len(text) > MAX_PROFILE_BYTES:
        raise RtuSniffError(ErrorKind.BAD_PROFILE, f"slave {slave} has {len(entries):,} registers, coils and inputs: "
                            f"a profile of them ({len(text):,} characters) would pass the {MAX_PROFILE_BYTES:,} a "
                            "profile may hold; draft a capture of fewer of them", path=capture)
    return checked_profile_text(text, capture), len(entries)


def _entry(guess: Guess, source: str) -> Entry:
    if guess.kind != "parameter":
        label = "coil" if guess.kind == "coil" else "input"
        return Entry(guess.kind, {"address": guess.address, "code": f"{label.upper()}{guess.address}",
                                  "name": f"{label} {guess.address}", "access": guess.access, "source": source},
                     guess.evidence)
    keys: dict[str, str | int | float | bool] = {"address": guess.address, "code": f"R{guess.address}",
                                                 "name": _name(guess)}
    if guess.type != "u16":
        keys["type"] = guess.type
    if guess.type == "string":
        keys["registers"] = guess.registers
    elif guess.registers > 1:
        keys["word_order"] = guess.word_order
    keys["access"] = guess.access
    keys["source"] = source
    return Entry("parameter", keys, guess.evidence)


def _name(guess: Guess) -> str:
    last = guess.address + guess.registers - 1
    where = f"registers {guess.address}-{last}" if last > guess.address else f"register {guess.address}"
    return f"{where} ({guess.type})"

"""A profile written as TOML text: what ``profiles import`` and ``profiles draft`` write.

The text is checked by the parser that loads profiles (:func:`checked_profile_text`) before a
command writes it: a profile rtusniff writes is one rtusniff reads.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from decoders.profiles.parse import MAX_PROFILE_BYTES, ProfileError, parse_profile
from sniffer.errors import ErrorKind, RtuSniffError

Value = str | int | float | bool


@dataclass
class Entry:
    """One ``[[parameter]]``, ``[[coil]]`` or ``[[input]]`` (``kind``): its keys in order, and
    comments written above it (the evidence a draft rests on)."""

    kind: str
    keys: dict[str, Value]
    comments: list[str] = field(default_factory=list)


def toml_value(value: Value) -> str:
    """A TOML value: a string as a basic string (JSON's escapes are TOML's), a number as written."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    return repr(value) if isinstance(value, float) else str(value)


def profile_text(head: Mapping[str, Value | Sequence[str]], entries: list[Entry], comments: Sequence[str] = ()) -> str:
    """The profile's TOML: ``comments`` first, then ``[profile]`` (``head``) and every entry."""
    lines = [f"# {comment}" for comment in comments]
    lines += ["", "[profile]"] if lines else ["[profile]"]
    for key, value in head.items():
        shown = toml_value(value) if isinstance(value, str | int | float) else "[" + ", ".join(
            map(toml_value, value)) + "]"
        lines.append(f"{key} = {shown}")
    for entry in entries:
        lines += ["", *(f"# {comment}" for comment in entry.comments), f"[[{entry.kind}]]"]
        lines += [f"{key} = {toml_value(value)}" for key, value in entry.keys.items()]
    return "\n".join(lines) + "\n"


def checked_profile_text(text: str, origin: str) -> str:
    """``text`` once the profile parser reads it without fault (a fault here is rtusniff's, but
    for a profile past the size a profile may hold: too many rows)."""
    if len(text) > MAX_PROFILE_BYTES:
        raise RtuSniffError(ErrorKind.BAD_PROFILE, f"its profile would be {len(text):,} characters, past the "
                            f"{MAX_PROFILE_BYTES:,} a profile may hold: split it", path=origin)
    try:
        parse_profile(text, origin)
    except ProfileError as exc:
        raise RtuSniffError(ErrorKind.RUNTIME, f"the profile written does not read back ({exc}); please report "
                            "this with the input") from None
    return text

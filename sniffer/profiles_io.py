"""Device profiles from files: the shipped ones in decoders/profiles/data, and users' own."""

from __future__ import annotations

from functools import cache
from importlib.resources import files
from itertools import pairwise
from pathlib import Path
from typing import NamedTuple

from decoders.profiles.book import ProfileBook
from decoders.profiles.model import Parameter, Profile
from decoders.profiles.parse import ProfileError, parse_profile
from decoders.register_format import ALIASES, KINDS, WORD_ORDERS
from decoders.value_types import TYPES
from sniffer.errors import ErrorKind, RtuSniffError

DEFAULT_PROFILE = "generic"
#: The profile ``--registers`` makes for the slaves no other profile decodes.
REGISTERS_PROFILE = "--registers"
LAST_ADDRESS = 0xFFFF


class RegisterSpec(NamedTuple):
    """``--registers [FIRST[-LAST]=]TYPE[:ORDER]``: the registers ``first`` to ``last`` read as
    ``kind`` in ``order`` (``None``: ``--word-order``'s, else big)."""

    first: int
    last: int
    kind: str
    order: str | None
    text: str


def register_spec(text: str) -> RegisterSpec:
    """Parse one ``--registers`` (an ``argparse`` type: a ``ValueError`` is its message)."""
    span, _, typed = text.rpartition("=")
    kind, _, order = typed.partition(":")
    if kind not in KINDS:
        raise ValueError(f"{kind!r} is not one of {', '.join(KINDS)}")
    if order and order not in WORD_ORDERS:
        raise ValueError(f"word order {order!r} is not one of {', '.join(WORD_ORDERS)}")
    first, last = 0, LAST_ADDRESS
    if span:
        low, _, high = span.partition("-")
        if not (low.isdigit() and (high.isdigit() or not high)):
            raise ValueError(f"{span!r} is no register range: give FIRST-LAST or one address (wire addresses)")
        first, last = int(low), int(high or low)
        if not first <= last <= LAST_ADDRESS:
            raise ValueError(f"{span!r}: give addresses 0 to 65535, the first no greater than the last")
    return RegisterSpec(first, last, ALIASES.get(kind, kind), order or None, text)


def registers_profile(specs: list[RegisterSpec], word_order: str | None) -> Profile | None:
    """The profile of ``--registers``: a parameter without a name for each value of its
    types; ``None`` where none asks for more than the hex words every view shows."""
    typed = [spec for spec in specs if spec.kind != "hex"]
    if not typed:
        return None
    by_first = sorted(typed, key=lambda spec: spec.first)
    for before, spec in pairwise(by_first):  # spans in order: each after the last
        if spec.first <= before.last:
            raise RtuSniffError(ErrorKind.USAGE, f"--registers {before.text} and {spec.text} both type "
                                f"register {spec.first}")
    parameters: dict[int, Parameter] = {}
    for spec in typed:
        size = TYPES[spec.kind].registers
        count = spec.last - spec.first + 1
        if count % size:
            raise RtuSniffError(ErrorKind.USAGE, f"--registers {spec.text}: {count} registers are no whole number of "
                                f"{spec.kind} ({size} registers each)")
        order = spec.order or word_order or "big"
        signed = spec.kind == "i16"
        for address in range(spec.first, spec.last + 1, size):
            parameters[address] = Parameter(address, "", "", REGISTERS_PROFILE, signed=signed, type=spec.kind,
                                            registers=size, word_order=order)
    return Profile(REGISTERS_PROFILE, "registers typed on the command line", "slave", (REGISTERS_PROFILE,),
                   parameters)


@cache
def shipped_profiles() -> dict[str, Profile]:
    """Every profile that ships with rtusniff, by id."""
    found = {}
    folder = files("decoders.profiles").joinpath("data")
    try:
        entries = sorted(folder.iterdir(), key=lambda e: e.name)
        for entry in entries:
            if entry.name.endswith(".toml"):
                profile = parse_profile(entry.read_text(encoding="utf-8"), f"decoders/profiles/data/{entry.name}")
                found[profile.id] = profile
    except OSError as exc:
        raise RtuSniffError(ErrorKind.BAD_PROFILE, f"the shipped device profiles cannot be read ({exc.strerror}); "
                            "reinstall rtusniff", path=str(folder)) from None
    except ProfileError as exc:
        raise RtuSniffError(ErrorKind.BAD_PROFILE, str(exc)) from None
    if DEFAULT_PROFILE not in found:
        raise RtuSniffError(ErrorKind.BAD_PROFILE, f"the shipped profile {DEFAULT_PROFILE!r} is missing; "
                            "reinstall rtusniff", path=str(folder))
    return found


def profile_file_text(path: str) -> str:
    """A user's profile file's text; errors name the file."""
    try:
        return Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RtuSniffError(ErrorKind.FILE_NOT_FOUND, "no such profile file", path=path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RtuSniffError(ErrorKind.FILE_UNREADABLE, f"cannot read: {exc}", path=path) from None


def load_profile_file(path: str) -> Profile:
    """A user's profile file; errors name the file and the field."""
    text = profile_file_text(path)
    try:
        return parse_profile(text, path)
    except ProfileError as exc:
        raise RtuSniffError(ErrorKind.BAD_PROFILE, str(exc)) from None


def profile_book(choices: list[str], files_: list[str], typed: Profile | None = None) -> ProfileBook:
    """``--profile NAME`` / ``--profile SLAVE=NAME`` and ``--profile-file PATH`` → a book;
    ``typed``: the profile of ``--registers`` (:func:`registers_profile`), for the slaves none
    of those decodes."""
    known = dict(shipped_profiles())
    for path in files_:
        profile = load_profile_file(path)
        known[profile.id] = profile
    default = known[DEFAULT_PROFILE] if typed is None else typed
    per_slave: dict[int, Profile] = {}
    for choice in choices:
        slave_text, sep, name = choice.rpartition("=")
        profile = _known(known, name)
        if not sep:
            default = profile
            continue
        if not (slave_text.isascii() and slave_text.isdigit()) or not 0 <= int(slave_text) <= 247:
            raise RtuSniffError(ErrorKind.USAGE, f"--profile {choice}: the slave must be a number from 0 to 247")
        per_slave[int(slave_text)] = profile
    # A profile chosen for every slave is the user's word: identification does not override it.
    chosen_for_all = any("=" not in choice for choice in choices)
    return ProfileBook(default=default, known=known, per_slave=per_slave, automatic=not chosen_for_all)


def _known(known: dict[str, Profile], name: str) -> Profile:
    if name not in known:
        raise RtuSniffError(ErrorKind.USAGE, f"--profile: unknown profile {name!r}; known: {', '.join(sorted(known))}")
    return known[name]

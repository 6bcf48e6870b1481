"""Device profiles from files: the shipped ones in decoders/profiles/data, and users' own."""

from __future__ import annotations

from functools import cache
from importlib.resources import files
from pathlib import Path

from decoders.profiles.book import ProfileBook
from decoders.profiles.model import Profile
from decoders.profiles.parse import ProfileError, parse_profile
from sniffer.errors import ErrorKind, RtuSniffError

DEFAULT_PROFILE = "generic"


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


def load_profile_file(path: str) -> Profile:
    """A user's profile file; errors name the file and the field."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RtuSniffError(ErrorKind.FILE_NOT_FOUND, "no such profile file", path=path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RtuSniffError(ErrorKind.FILE_UNREADABLE, f"cannot read: {exc}", path=path) from None
    try:
        return parse_profile(text, path)
    except ProfileError as exc:
        raise RtuSniffError(ErrorKind.BAD_PROFILE, str(exc)) from None


def profile_book(choices: list[str], files_: list[str]) -> ProfileBook:
    """``--profile NAME`` / ``--profile SLAVE=NAME`` and ``--profile-file PATH`` → a book."""
    known = dict(shipped_profiles())
    for path in files_:
        profile = load_profile_file(path)
        known[profile.id] = profile
    default = known[DEFAULT_PROFILE]
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

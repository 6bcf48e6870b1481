"""The names of a rotation's files (``capture -o site.mcap --rotate 1h``): ``site-0001.mcap``, …

One place for the rule, used where the files are written (:mod:`sniffer.recorder`) and where
they are followed (:mod:`sniffer.io.following`).
"""

from __future__ import annotations

import glob
import re
from pathlib import Path

_ROTATED = re.compile(r"^(?P<stem>.*)-(?P<number>\d{4})(?P<suffix>\.[^./\\]+)$")


def rotated_path(path: str, number: int) -> str:
    """``capture.mcap`` → ``capture-0001.mcap``."""
    target = Path(path)
    return str(target.with_name(f"{target.stem}-{number:04d}{target.suffix}"))


def rotated_files(path: str) -> list[str]:
    """The files of a rotation of ``path`` that exist already (``capture-0001.mcap`` …), in order."""
    target = Path(path)
    pattern = f"{glob.escape(target.stem)}-[0-9][0-9][0-9][0-9]{glob.escape(target.suffix)}"
    return sorted(str(found) for found in target.parent.glob(pattern))


def next_rotated(path: str) -> str | None:
    """The file a rotation writes after ``path`` (``site-0007.mcap`` → ``site-0008.mcap``);
    ``None`` for a name that is not a rotation's."""
    found = _ROTATED.match(path)
    if found is None:
        return None
    return f"{found['stem']}-{int(found['number']) + 1:04d}{found['suffix']}"


def same_rotation(path: str, other: str) -> bool:
    """Whether ``other`` is a file of the rotation ``path`` is (or is a file of): a follower of
    ``path`` reads it, now or when the recorder opens it."""
    def base(name: str) -> tuple[str, str]:
        found = _ROTATED.match(name)
        target = Path(found["stem"] + found["suffix"]) if found else Path(name)
        return str(target.resolve().with_suffix("")), target.suffix
    return _ROTATED.match(other) is not None and base(path) == base(other)

"""How counts are said: ``1 frame``, ``2 frames``, ``1,234 frames``."""

from __future__ import annotations


def counted(count: int, noun: str, plural: str | None = None) -> str:
    """``count`` and ``noun``, in the plural unless one (``plural``: where not ``noun`` + s)."""
    return f"{count:,} {noun if count == 1 else plural or noun + 's'}"

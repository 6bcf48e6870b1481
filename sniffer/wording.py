"""How counts are said: ``1 frame``, ``2 frames``, ``1,234 frames``."""

from __future__ import annotations


def counted(count: int, noun: str) -> str:
    """``count`` and ``noun``, with an s unless one."""
    return f"{count:,} {noun if count == 1 else noun + 's'}"

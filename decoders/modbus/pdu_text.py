"""How PDU summaries write register values: big-endian words in hex, the first few of many."""

from __future__ import annotations

import struct

#: How many register values a summary shows (the rest: how many more).
HEX_WORDS_SHOWN = 8


def hex_words(values: tuple[int, ...], limit: int = HEX_WORDS_SHOWN) -> str:
    """``000F 0081``: the first ``limit`` values as 16-bit hex words, and how many more there are."""
    shown = struct.pack(f">{min(len(values), limit)}H", *values[:limit]).hex(" ", 2).upper()
    return shown + (f" … (+{len(values) - limit})" if len(values) > limit else "")


def registers(count: int) -> str:
    """``1 register``, ``8 registers``: how a summary counts an answer's words."""
    return f"{count} register" if count == 1 else f"{count} registers"

"""The installed rtusniff's name and version, as outputs and ``--version`` state them.

Read from the package's metadata at the first call, not at import: ``importlib.metadata``
costs tens of ms to import, which every command would pay at start for a line only some
outputs write.
"""

from __future__ import annotations

from functools import cache


@cache
def tool_version() -> str:
    """``rtusniff X.Y.Z``."""
    from importlib.metadata import version  # noqa: PLC0415 - slow to import, see above

    return f"rtusniff {version('rtusniff')}"


@cache
def version_number() -> str:
    """``X.Y.Z``."""
    return tool_version().removeprefix("rtusniff ")

"""The installed rtusniff's name and version, as outputs and ``--version`` state them.

The version is written once, here (``pyproject.toml`` reads it as the package's version, so
the wheel's metadata says the same): asked of the installed metadata instead
(``importlib.metadata.version``), it would cost every export's start the import of that
module and a search of the path's distributions.
"""

from __future__ import annotations

#: The package's version (``pyproject.toml``: ``[tool.setuptools.dynamic]``).
VERSION = "0.1.0"


def tool_version() -> str:
    """``rtusniff X.Y.Z``."""
    return f"rtusniff {VERSION}"


def version_number() -> str:
    """``X.Y.Z``."""
    return VERSION

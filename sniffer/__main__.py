"""``python -m sniffer`` is ``rtusniff``."""

from sniffer.cli import entry_point

entry_point()

"""Capture readers and writers, chosen by file suffix through :mod:`sniffer.io.registry`."""

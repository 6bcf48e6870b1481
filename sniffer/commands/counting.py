"""One capture counted as ``stats`` counts it, with how it was read: a side of ``compare``, and the
baseline of ``report --baseline``."""

from __future__ import annotations

import argparse
from contextlib import ExitStack

from decoders.capture import CaptureInfo
from decoders.line import LineSettings
from decoders.stats import Statistics
from sniffer.library import Capture
from sniffer.progress import progress_for
from sniffer.sinks import Sink
from sniffer.views.compare_view import Side


class _Counted(Sink):
    """Asks for the statistics, and remembers how the capture was read."""

    wants_statistics = True
    timing = ""
    line = ""

    def start(self, source: str, info: CaptureInfo, line: LineSettings) -> None:
        self.timing = info.timing.value
        self.line = line.format()


def counted_capture(args: argparse.Namespace, path: str) -> Side:
    """``path`` read with the decoding options of ``args`` (its window too), counted."""
    one = argparse.Namespace(**{**vars(args), "capture": [path]})
    with ExitStack() as stack:
        capture = Capture(one, stack)
        counted = _Counted()
        progress = stack.enter_context(progress_for(one, capture.reader, streaming=False))
        statistics: Statistics = capture.decode([progress.sink, counted])
    return Side(path, counted.line, counted.timing, statistics)

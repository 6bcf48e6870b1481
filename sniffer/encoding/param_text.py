"""The ``params`` array of a frame record, written straight from runs of registers or coils.

For registers no profile names every param record is the same text but for the address and the
value. Each address's start (``,{"address":…,"raw":``) and each value's end (``…,"unit":null}``)
is formatted once, in two tables of 65 536 (built at first use: 10 ms and 5 MB each), and a run
is two slices interleaved and joined. Raw values are 16-bit words or coil bits, so a value is its
own index. ``python -m benchmarks.bench_param_text`` times this against a ``%``-template per run
length and against ends kept in a dict as values come: the tables are the fastest, or within
a third of it (read requests of 2 to 4 registers), for every run length, with values that
repeat (a plant) and values that never do (the polling benchmark).
Exactly the JSON of :func:`sniffer.encoding.records.param_record` (the tests compare both).
"""

from __future__ import annotations

from collections.abc import Sequence

from decoders.modbus.param_runs import ParamRun

#: The end of a param record without a value (a read request names registers without).
_NO_VALUE = 'null,"value":null,"unit":null}'
_WORDS = 1 << 16

_starts: list[str] = []
_value_ends: list[str] = []


def runs_json(runs: tuple[ParamRun, ...]) -> str:
    """The ``params`` array of the registers or coils of ``runs``, no profile naming them."""
    if len(runs) == 1:  # most frames
        return f"[{run_text(runs[0])}]"
    return "[" + ",".join(text for text in map(run_text, runs) if text) + "]"


def run_text(run: ParamRun) -> str:
    """The param records of one run, comma-separated, without brackets."""
    address, count, values = run
    if not _starts:
        _starts.extend(map(_start, range(_WORDS)))
        _value_ends.extend(f'{value},"value":{value},"unit":null}}' for value in range(_WORDS))
    if count == 1 and address < _WORDS:  # a single register or coil: no list to interleave
        return _starts[address][1:] + (_NO_VALUE if values is None else _value_ends[values[0]])
    if count <= 0:
        return ""
    return "".join(_run_pieces(address, count, values))[1:]


def _run_pieces(address: int, count: int, values: Sequence[int] | None) -> list[str]:
    """The run's pieces: each param's start then its end (each start begins with a comma)."""
    if address + count > _WORDS:  # not on a wire (16-bit addresses): spelt one by one
        heads = [_start(a) for a in range(address, address + count)]
    else:
        heads = _starts[address : address + count]
    pieces: list[str] = [""] * (2 * count)
    pieces[::2] = heads
    pieces[1::2] = [_NO_VALUE] * count if values is None else map(_value_ends.__getitem__, values)
    return pieces


def _start(address: int) -> str:
    return f',{{"address":{address},"code":null,"name":null,"raw":'

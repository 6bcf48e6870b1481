"""The ``params`` array of a frame record, written straight from runs of registers or coils.

For registers no profile names every param record is the same text but for the address and the
value. Each address's start (``,{"address":…,"raw":``) and each value's end (``…,"unit":null}``)
is formatted once, kept, and a run is two slices interleaved and joined: about 60 ns a register
against 300 for formatting it and 1 µs for a param object turned into a dict and encoded.
Exactly the JSON of :func:`sniffer.encoding.records.param_record` (the tests compare both).
"""

from __future__ import annotations

from collections.abc import Sequence

from decoders.modbus.param_runs import ParamRun

#: The end of a param record without a value (a read request names registers without).
_NO_VALUE = 'null,"value":null,"unit":null}'
_ADDRESSES = 1 << 16


class _ValueEnds(dict[int, str]):
    """A value's end of a param record, formatted the first time it is asked for."""

    def __missing__(self, value: int) -> str:
        end = self[value] = f'{value},"value":{value},"unit":null}}'
        return end


_starts: list[str] = []
_value_ends = _ValueEnds()


def runs_json(runs: tuple[ParamRun, ...]) -> str:
    """The ``params`` array of the registers or coils of ``runs``, no profile naming them."""
    pieces: list[str] = []
    for run in runs:
        count = run.size
        if count <= 0:
            continue
        pieces += _run_pieces(run.address, count, run.values)
    return "[" + "".join(pieces)[1:] + "]"


def _run_pieces(address: int, count: int, values: Sequence[int] | None) -> list[str]:
    """The run's pieces: each param's start then its end (each start begins with a comma)."""
    starts = _address_starts()
    if address + count > _ADDRESSES:  # not on a wire (16-bit addresses): spelt one by one
        heads = [_start(a) for a in range(address, address + count)]
    else:
        heads = starts[address : address + count]
    pieces: list[str] = [""] * (2 * count)
    pieces[::2] = heads
    pieces[1::2] = [_NO_VALUE] * count if values is None else list(map(_value_ends.__getitem__, values))
    return pieces


def _address_starts() -> list[str]:
    if not _starts:
        _starts.extend(map(_start, range(_ADDRESSES)))
    return _starts


def _start(address: int) -> str:
    return f',{{"address":{address},"code":null,"name":null,"raw":'

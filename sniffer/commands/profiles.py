"""``rtusniff profiles``: the device profiles, listed, shown, or a user's file checked."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from decoders.profiles.model import Parameter, Profile
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.profiles_io import load_profile_file, shipped_profiles
from sniffer.views.layout import Cells, Column, Layout

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "profiles",
        help="list the device profiles, show one, or check a profile file of your own",
        description="Device profiles name and scale the registers of drives rtusniff knows. "
        "'profiles' lists them, 'profiles show NAME|FILE' prints one, 'profiles check FILE' validates yours.",
    )
    parser.add_argument("action", nargs="?", choices=["list", "show", "check"], default="list")
    parser.add_argument("target", nargs="?", help="profile name or TOML file (show), TOML file (check)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from rich.console import Console  # noqa: PLC0415 - rich: tens of ms to import, only for a terminal

    # No rich markup: profile texts and paths hold brackets ("[address_formula]", "([Profil])"). Into a
    # pipe every line whole (soft wrap): a script reads a row a line.
    console = Console(highlight=False, markup=False)
    console.soft_wrap = not console.is_terminal
    if args.action == "list":
        console.print(_list_table(shipped_profiles()))
        return 0
    if args.target is None:
        wanted = "profile name" if args.action == "show" else "TOML file"
        raise RtuSniffError(ErrorKind.USAGE, f"profiles {args.action}: give a {wanted}")
    if args.action == "check":
        profile = load_profile_file(args.target)
        named_bits = profile.coils or profile.inputs
        bits = f"{len(profile.coils)} coils, {len(profile.inputs)} discrete inputs, " if named_bits else ""
        console.print(f"{args.target}: profile {profile.id!r} is valid: {len(profile.parameters)} parameters, {bits}"
                      f"{len(profile.bitfields)} bit fields, {len(profile.exceptions)} exception notes", soft_wrap=True)
        return 0
    known = shipped_profiles()
    if args.target.endswith(".toml") and args.target not in known:  # a file of one's own
        _show(console, load_profile_file(args.target))
        return 0
    if args.target not in known:
        raise RtuSniffError(ErrorKind.USAGE, f"unknown profile {args.target!r}; known: {', '.join(sorted(known))} "
                            "(or a .toml file)")
    _show(console, known[args.target])
    return 0


def _list_table(profiles: dict[str, Profile]) -> Table:
    from rich.table import Table  # noqa: PLC0415 - rich: only when the command runs

    table = Table(title="device profiles (use with --profile NAME or --profile SLAVE=NAME)", title_justify="left")
    for header in ("name", "device", "role", "parameters", "identified by product code"):
        table.add_column(header)
    for profile in profiles.values():
        table.add_row(profile.id, profile.name, profile.role, str(len(profile.parameters)),
                      ", ".join(profile.product_codes))
    return table


def _show(console: Console, profile: Profile) -> None:
    from rich.text import Text  # noqa: PLC0415 - rich: only when the command runs

    console.print(Text.assemble((profile.id, "bold"), f": {profile.name} ({profile.role})"))
    for source in profile.sources:
        console.print(f"  source: {source}")
    for note in profile.notes:
        console.print(f"  note: {note}")
    limits = profile.limits
    if limits.functions:
        console.print(f"  functions: {', '.join(map(str, limits.functions))}; broadcast: "
                      f"{', '.join(map(str, limits.broadcast_functions)) or 'none'}")
        counts = {"read": limits.read_registers, "write": limits.write_registers,
                  "FC 23 read": limits.read_write_read, "FC 23 write": limits.read_write_write}
        shown = ", ".join(f"{k} {v}" for k, v in counts.items() if v)
        if shown:
            console.print(f"  at most (registers): {shown}")
    for special in profile.specials:
        console.print(f"  16#{special.raw:04X} in a read: {special.meaning}")
    for title, named in (("parameters", profile.parameters), ("coils (FC 1, 5, 15)", profile.coils),
                         ("discrete inputs (FC 2)", profile.inputs)):
        if named:
            console.print(title)
            console.out(_parameter_lines(named, console.width if console.is_terminal else None), end="")
    for table in profile.indirections:
        console.print(f"  {table.prefix}1-{table.count}: registers {table.value_registers}.. carry the parameters "
                      f"whose addresses registers {table.address_registers}.. hold; defaults {list(table.defaults)}")
    for exception in profile.exceptions:
        scope = f" on FC {exception.function}" if exception.function else ""
        console.print(f"  exception {exception.code:02X}{scope}: {exception.explanation}")
    for bitfield in profile.bitfields.values():
        states = "; ".join(f"{s.name} (&16#{s.mask:04X} = 16#{s.value:04X})" for s in bitfield.states)
        console.print(f"  bit field {bitfield.id}: " + ", ".join(f"{b.bit}: {b.name}" for b in bitfield.bits))
        if states:
            console.print(f"    states: {states}")


#: The parameter table's columns: the address, its code and unit never cut; the name, the source
#: and the note wrap at words as the width allows (one line a row into a pipe).
PARAMETER_COLUMNS = [
    Column("address", "address", right=True), Column("hex", "hex"), Column("code", "code"),
    # The name's longest word is a bit field's ("[drivecom_status]"): as wide, so that none is split.
    Column("name", "name", flexible=True, min_width=18, max_width=30), Column("unit", "unit"),
    Column("scale", "scale", keep=40), Column("type", "type", keep=35), Column("access", "access", keep=30),
    Column("source", "source", flexible=True, min_width=12, keep=20),
    Column("note", "note", flexible=True, min_width=16, keep=10),
]


def _type(parameter: Parameter) -> str:
    """A parameter's type as the table shows it: ``i16``, ``f32 little``, ``string ×8``."""
    if parameter.registers == 1:
        return parameter.type
    size = f" ×{parameter.registers}" if parameter.type == "string" else ""
    return f"{parameter.type}{size} {parameter.word_order}"


def _parameter_lines(parameters: dict[int, Parameter], width: int | None) -> str:
    """The parameters laid out as the other tables are (:mod:`sniffer.views.layout`): at the
    terminal's width, words never split, columns that do not fit said; a row a line in a pipe."""
    rows: dict[str, list[str]] = {column.key: [] for column in PARAMETER_COLUMNS}
    for address, parameter in sorted(parameters.items()):
        scale = "" if parameter.scale == 1.0 else f"{parameter.scale:g}"
        kind = f" [{parameter.bitfield}]" if parameter.bitfield else ""
        for key, text in (("address", str(address)), ("hex", f"16#{address:04X}"), ("code", parameter.code),
                          ("name", parameter.name + kind), ("unit", parameter.unit or ""),
                          ("scale", scale), ("type", _type(parameter)), ("access", parameter.access),
                          # "manual:1097,1421" wraps between its pages, not inside a number
                          ("source", parameter.source.replace(",", ", ")), ("note", parameter.note or "")):
            rows[key].append(text)
    layout = Layout(PARAMETER_COLUMNS, width, None)
    cells = {key: Cells(texts) for key, texts in rows.items()}
    layout.measure(cells)
    lines = layout.header() + layout.lines(cells, len(parameters))
    if layout.hidden():
        lines += f"(no room at {width} columns for: {', '.join(layout.hidden())}; a pipe has all)\n"
    return lines

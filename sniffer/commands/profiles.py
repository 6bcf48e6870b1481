"""``rtusniff profiles``: the device profiles, listed, shown, a user's file checked, one imported
from a register map (:mod:`sniffer.register_map`) or drafted from a capture
(:mod:`sniffer.profile_draft`)."""

from __future__ import annotations

import argparse
import re
import sys
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING

from decoders.profiles.model import Parameter, Profile
from sniffer.commands.common import (
    add_capture_argument,
    add_decoding_options,
    add_force_option,
    add_output_option,
    add_quiet_option,
    capture_paths,
    check_outputs,
    open_output,
    source_name,
    tell_written,
)
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.library import Capture
from sniffer.profile_draft import DraftCollector, draft_text
from sniffer.profiles_io import DEFAULT_PROFILE, load_profile_file, shipped_profiles
from sniffer.register_map import MAP_ADDRESSINGS, import_map
from sniffer.views.layout import Cells, Column, Layout

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "profiles",
        help="list the device profiles, show one, check one of your own, or make one from a register map "
        "or a capture",
        description="Device profiles name and scale the registers of drives rtusniff knows. "
        "'profiles' lists them, 'profiles show NAME|FILE' prints one, 'profiles check FILE' validates yours, "
        "'profiles import MAP.csv' makes one from a register map, 'profiles draft CAPTURE --slave N' drafts one "
        "from what a slave's registers were seen to hold.",
    )
    parser.set_defaults(run=_run_list)
    actions = parser.add_subparsers(title="actions", metavar="ACTION")
    actions.add_parser("list", help="the shipped profiles (the default)").set_defaults(run=_run_list)
    show = actions.add_parser("show", help="one profile: its parameters, coils, limits, notes")
    show.add_argument("target", metavar="NAME|FILE", help="a shipped profile's name, or a .toml file")
    show.set_defaults(run=_run_show)
    check = actions.add_parser("check", help="validate a profile file, naming the field of any fault")
    check.add_argument("target", metavar="FILE")
    check.set_defaults(run=_run_check)
    _add_import(actions)
    _add_draft(actions)


def _add_import(actions: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    made = actions.add_parser(
        "import", help="a profile from a register map (CSV with a header row)",
        description="A checked profile from a register map saved as CSV (comma, semicolon or tab): columns found by "
        "their header (address and name needed; code, unit, scale, type, word order, access, registers, table read "
        "where present). A bad row is one line naming its row and column, and nothing is written (exit 12).")
    made.add_argument("map", metavar="MAP.csv")
    made.add_argument("--addressing", choices=MAP_ADDRESSINGS, default="auto",
                      help="how the map numbers registers: auto (default: Modicon references such as 40001 where "
                      "every address is one, else as sent from 0), wire (as sent, from 0), 1 (from 1), 4x")
    _add_profile_naming(made, "the map's file name")
    made.set_defaults(run=_run_import)


def _add_draft(actions: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    drafted = actions.add_parser(
        "draft", help="a profile drafted from a capture: every register a slave was read or written, its type "
        "guessed from the values seen",
        description="Every register, coil and input of one slave the capture reads or writes, with how often, its "
        "range and changes, and each register's type guessed from its values (a float in either word order, a "
        "counter, text, a signed word, an enumeration), each guess with its evidence as a comment. Registers are "
        "read as plain words (no profile applies).")
    add_capture_argument(drafted)
    drafted.add_argument("--slave", type=int, required=True, metavar="N", help="the slave whose registers to draft")
    add_decoding_options(drafted)
    _add_profile_naming(drafted, "'slaveN'")
    drafted.set_defaults(run=_run_draft)


def _add_profile_naming(parser: argparse.ArgumentParser, default: str) -> None:
    parser.add_argument("--id", metavar="ID", help=f"the profile's id, for --profile (default: {default})")
    parser.add_argument("--name", metavar="TEXT", help="the device's name (default: the id)")
    add_output_option(parser)
    add_force_option(parser)
    add_quiet_option(parser)


def _console() -> Console:
    from rich.console import Console  # noqa: PLC0415 - rich: tens of ms to import, only for a terminal

    # No rich markup: profile texts and paths hold brackets ("[address_formula]", "([Profil])"). Into a
    # pipe every line whole (soft wrap): a script reads a row a line.
    console = Console(highlight=False, markup=False)
    console.soft_wrap = not console.is_terminal
    return console


def _run_list(args: argparse.Namespace) -> int:
    _console().print(_list_table(shipped_profiles()))
    return 0


def _run_check(args: argparse.Namespace) -> int:
    profile = load_profile_file(args.target)
    named_bits = profile.coils or profile.inputs
    bits = f"{len(profile.coils)} coils, {len(profile.inputs)} discrete inputs, " if named_bits else ""
    _console().print(f"{args.target}: profile {profile.id!r} is valid: {len(profile.parameters)} parameters, {bits}"
                     f"{len(profile.bitfields)} bit fields, {len(profile.exceptions)} exception notes",
                     soft_wrap=True)
    return 0


def _run_show(args: argparse.Namespace) -> int:
    known = shipped_profiles()
    if args.target.endswith(".toml") and args.target not in known:  # a file of one's own
        _show(_console(), load_profile_file(args.target))
        return 0
    if args.target not in known:
        raise RtuSniffError(ErrorKind.USAGE, f"unknown profile {args.target!r}; known: {', '.join(sorted(known))} "
                            "(or a .toml file)")
    _show(_console(), known[args.target])
    return 0


def _run_import(args: argparse.Namespace) -> int:
    check_outputs([args.output], [args.map], force=args.force)
    profile_id = args.id or _identifier(Path(args.map).stem)
    made = import_map(args.map, profile_id=profile_id, name=args.name or profile_id, addressing=args.addressing,
                      word_order=None)
    for said in made.said if not args.quiet else ():
        print(f"{args.map}: {said}", file=sys.stderr)
    _write(args, made.text, f"profile {profile_id!r}")
    return 0


def _run_draft(args: argparse.Namespace) -> int:
    if not 0 < args.slave <= 247:
        raise RtuSniffError(ErrorKind.USAGE, "--slave: give a slave address, 1 to 247")
    check_outputs([args.output], capture_paths(args), force=args.force)
    args.profile, args.profile_file, args.registers = [DEFAULT_PROFILE], [], []  # plain words
    collector = DraftCollector(args.slave)
    with ExitStack() as stack:
        Capture(args, stack).decode([collector])
    if not collector.observations.frames:
        raise RtuSniffError(ErrorKind.NO_DATA, f"slave {args.slave} reports and is written no value in this capture",
                            path=source_name(args))
    profile_id = args.id or f"slave{args.slave}"
    text, entries = draft_text(collector, capture=source_name(args), slave=args.slave, profile_id=profile_id,
                               name=args.name or profile_id)
    _write(args, text, f"draft profile {profile_id!r}, {entries} entries")
    return 0


def _write(args: argparse.Namespace, text: str, what: str) -> None:
    with ExitStack() as stack:
        open_output(args.output, stack).write(text)
    if args.output not in (None, "-"):
        tell_written(args, [(args.output, what)])


def _identifier(stem: str) -> str:
    """A profile id from a file's name: lower case, words joined by ``-``."""
    return re.sub(r"[^a-z0-9]+", "-", stem.lower()).strip("-") or "imported"


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

"""Options shared by the subcommands that read captures."""

from __future__ import annotations

import argparse
import os
import stat
import sys
from contextlib import ExitStack
from dataclasses import replace
from typing import TextIO

from decoders.capture import CaptureInfo, TimingQuality
from decoders.line import LineSettings
from decoders.profiles.model import Profile
from decoders.register_format import WORD_ORDERS
from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.filters import parse_filters
from sniffer.io.base import CaptureReader, ReaderOptions
from sniffer.io.chain import open_capture
from sniffer.io.following import FollowingReader, followed_path, stopping_on_signals
from sniffer.io.output_files import allow_replacing, open_new_text, published_whole
from sniffer.io.pacing import PacedReader, parse_speed
from sniffer.io.registry import format_help, formats_for
from sniffer.io.rotation import same_rotation
from sniffer.many_captures import captures_in
from sniffer.pipeline import Analysis, effective_line
from sniffer.profiles_io import RegisterSpec, profile_book, register_spec, registers_profile
from sniffer.selection import add_selection_options, selection_from
from sniffer.views.clock import MODES


def add_capture_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("capture", nargs="+", metavar="CAPTURE",
                        help="capture file: text .log, native .mcap, sigrok .sr, sigrok-cli annotations, Saleae "
                        ".csv, .pcap/.pcapng (see --input-format), or - for text on stdin; several files (rotated "
                        "recordings) are read as one capture, in time order")


def capture_paths(args: argparse.Namespace) -> list[str]:
    paths: list[str] = args.capture
    return paths


def source_name(args: argparse.Namespace) -> str:
    """What the outputs call the capture: its file, or its files joined by ``+``."""
    return " + ".join(capture_paths(args))


def add_line_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--line",
        metavar="'BAUD FORMAT'",
        help="line settings, e.g. --line 19200 8E1; overrides the capture's own",
    )
    parser.add_argument(
        "--char-timing",
        action="store_true",
        help="use 1.5/3.5 character times at every baud rate instead of the fixed "
        "750/1750 µs the Modbus specification sets above 19200 Bd",
    )


def add_timing_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--timing",
        choices=[t.value for t in TimingQuality],
        help="how far the capture's times can be trusted: exact (frame boundaries from silences, "
        "checked by content) or host (boundaries from content; times are host read times); "
        "default: what the capture says",
    )


def effective_timing(info: CaptureInfo, args: argparse.Namespace) -> TimingQuality:
    return TimingQuality(args.timing) if args.timing else info.timing


def add_pcap_link_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--pcap-link", choices=["udp", "user"], default="udp",
                        help="udp (default): each frame in a UDP packet, master to slave port 502, by which Wireshark "
                        "tells every query from its response ('rtusniff wireshark setup' once, then 'wireshark -C "
                        "rtusniff FILE'); user: link type 147, the frames alone (Wireshark's DLT_USER 0 mapped to "
                        "mbrtu, which the same profile does)")


#: ``--response-timeout 0``: a limit no capture reaches (146 years; added to epoch nanoseconds in int64).
NO_TIME_LIMIT_NS = 2**62


def add_response_timeout_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--response-timeout",
        type=float,
        metavar="MS",
        help="a request not answered within MS milliseconds is a timeout; 0: no time limit (a request is a "
        "timeout only when the master moves on). Default: derived from the traffic, ten times the longest "
        "recent latency, 100 ms to 1 s",
    )


def response_timeout_ns(args: argparse.Namespace) -> int | None:
    if args.response_timeout is None:
        return None
    if not 0 <= args.response_timeout <= 600_000:
        raise RtuSniffError(ErrorKind.USAGE, "--response-timeout: give milliseconds from 0 (no limit) to 600000")
    if args.response_timeout == 0:
        return NO_TIME_LIMIT_NS
    timeout_ns: int = round(args.response_timeout * 1e6)
    return max(timeout_ns, 1)


def add_profile_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--profile",
        action="append",
        default=[],
        metavar="[SLAVE=]NAME",
        help="device profile for every slave (NAME) or for one (SLAVE=NAME), repeatable; "
        "see 'rtusniff profiles'. Without it, slaves that identify themselves (FC 43) get theirs",
    )
    parser.add_argument(
        "--profile-file",
        action="append",
        default=[],
        metavar="PATH",
        help="load a profile of your own (TOML, as the shipped ones; 'rtusniff profiles check FILE' says what is "
        "wrong with one); then name it with --profile",
    )
    parser.add_argument(
        "--registers",
        action="append",
        default=[],
        type=_register_spec,
        metavar="[FIRST-LAST=]TYPE[:ORDER]",
        help="registers of slaves without a profile read as TYPE: u16, i16, u32, i32, f32 (two registers), u64, i64, "
        f"f64 (four), or hex words; ORDER {', '.join(WORD_ORDERS)} (default big: high word first); over the wire "
        "addresses FIRST-LAST (or all, from 0), repeatable: --registers 3000-3019=f32:little",
    )
    parser.add_argument("--word-order", choices=WORD_ORDERS, default=None,
                        help="the word order of every --registers that names none")


def _register_spec(text: str) -> RegisterSpec:
    try:
        return register_spec(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def typed_registers(args: argparse.Namespace) -> Profile | None:
    """The profile ``--registers`` makes (``None``: none asked for)."""
    return registers_profile(getattr(args, "registers", []), getattr(args, "word_order", None))


def add_filter_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--filter",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="only matching frames: slave=N, function=N, role=NAME, flag=NAME, crc=ok|bad, exception=CODE, "
        "address=N or A-B, param=CODE, latency>MS (quoted in a shell: --filter 'latency>5'); repeat a key for "
        "alternatives, combine keys to narrow (statistics still count every frame of the window)",
    )


def add_time_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--time", choices=list(MODES), default="utc",
                        help="times in UTC (default), local time, or seconds since the first frame read (of the "
                        "window); also the zone of --from/--to")


def add_quiet_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no progress bar and no closing line saying what was written")


def add_decoding_options(parser: argparse.ArgumentParser) -> None:
    """Everything that says how to read and decode a capture, and which part of it."""
    add_selection_options(parser)
    add_time_option(parser)
    add_line_options(parser)
    add_timing_option(parser)
    add_response_timeout_option(parser)
    add_profile_options(parser)
    add_input_format_option(parser)
    add_channel_option(parser)


def add_jobs_option(parser: argparse.ArgumentParser) -> None:
    """For commands that spend more per frame after decoding than the decoding does (not
    ``stats``: there a second process only adds the pipe)."""
    parser.add_argument(
        "--jobs",
        default="auto",
        metavar="auto|1|2|N",
        help="processes to decode with: 2 reads, frames and pairs in a second process while this one "
        "annotates and writes (faster on two cores, same output); default auto: 2 where there are two cores "
        "(1 with --follow and for a paced replay). With --each: captures decoded at once (auto: one per core)",
    )


def add_follow_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--follow", action="store_true",
                        help="keep reading as the capture grows (a recording 'rtusniff capture -o' is still writing), "
                        "as tail -f does; ends at the recording's end or Ctrl-C")


def open_analysis(args: argparse.Namespace, stack: ExitStack) -> tuple[CaptureReader, Analysis]:
    """Open ``args.capture`` and settle how to decode it; ``--follow`` and ``--speed`` shape
    how its chunks come (:mod:`sniffer.io.following`, :mod:`sniffer.io.pacing`)."""
    book = profile_book(args.profile, args.profile_file, typed_registers(args))
    override = line_override(args)
    paths = capture_paths(args)
    follow = getattr(args, "follow", False)
    if follow and (len(paths) != 1 or paths[0] == "-"):
        raise RtuSniffError(ErrorKind.USAGE, "--follow follows one capture file (standard input is followed anyway)")
    if follow:
        stack.enter_context(stopping_on_signals())
        paths = [followed_path(paths[0])]
    reader: CaptureReader = open_capture(paths, args.input_format, reader_options(args))
    if follow:
        options = reader_options(args)
        reader = FollowingReader(reader, path=paths[0],
                                 open_next=lambda path: open_capture([path], args.input_format, options))
    stack.callback(close_reader, reader)
    speed = replay_speed(args)
    if speed is not None:
        reader = PacedReader(reader, speed)
    if override is not None and reader.info.line is not None and override.format() != reader.info.line.format():
        reader.warnings.append(f"{source_name(args)}: --line {override.format()} overrides the capture's own "
                               f"{reader.info.line.format()}")
    line = apply_char_timing(effective_line(reader.info, override, source_name(args)), args)
    analysis = Analysis(line, effective_timing(reader.info, args), response_timeout_ns(args), profiles=book)
    if hasattr(args, "start"):
        analysis = replace(analysis, selection=selection_from(args))
    if getattr(args, "filter", None):
        analysis = replace(analysis, keep=parse_filters(args.filter))
    return reader, analysis


def reader_options(args: argparse.Namespace) -> ReaderOptions:
    """What the command's options tell a capture reader: ``--line``, ``--timing``, ``--channel``."""
    return ReaderOptions(line=line_override(args), timing=TimingQuality(args.timing) if args.timing else None,
                         channels=tuple(getattr(args, "channel", None) or ()), follow=getattr(args, "follow", False),
                         invert=getattr(args, "invert", None))


def replay_speed(args: argparse.Namespace) -> float | None:
    """How fast a file is replayed: ``--speed``, 1 when a live viewer watches a file that is
    not followed, ``None`` (as fast as it decodes) otherwise."""
    text = getattr(args, "speed", None)
    if text is None:
        watched = getattr(args, "foxglove", None) is not None or getattr(args, "rerun", None) is not None
        return 1.0 if watched and not getattr(args, "follow", False) else None
    return parse_speed(text)


def close_reader(reader: CaptureReader) -> None:
    """Close ``reader`` and tell what it found worth a warning (on standard error)."""
    reader.close()
    # dict.fromkeys: each once (the decoding process sends back the warnings it inherited too).
    for warning in dict.fromkeys(reader.warnings):
        print(f"warning: {warning}", file=sys.stderr)


def check_outputs(outputs: list[str | None], inputs: list[str], *, force: bool, following: bool = False) -> None:
    """Refuse an output that is an input (the same file, also through a link or another
    spelling; a capture inside a folder read with ``--each``; the file standard input is
    redirected from; with ``--follow``, a file of the followed recording's rotation), two
    outputs that are one file, and an existing output without ``--force``: no command ever
    truncates a capture it reads. ``-`` and ``None`` are standard streams."""
    files = [path for path in outputs if path is not None and path != "-"]
    allow_replacing(files if force else [])
    sources = [found for source in inputs for found in (captures_in(source) if os.path.isdir(source) else [source])]
    for position, path in enumerate(files):
        for source in sources:
            if (source == "-" and _is_standard_input(path)) or (source != "-" and _same_file(path, source)):
                raise RtuSniffError(ErrorKind.USAGE, f"is the input {_input_name(source)}: rtusniff never writes over "
                                    "a capture it reads; choose another output", path=path)
            if following and source != "-" and same_rotation(source, path):
                raise RtuSniffError(ErrorKind.USAGE, f"is a file of the rotation --follow {source} reads; choose "
                                    "another output", path=path)
        if any(_same_file(path, other) for other in files[:position]):
            raise RtuSniffError(ErrorKind.USAGE, "named as two outputs", path=path)
        # Only files: writing to a device or a pipe (-o /dev/null) destroys nothing.
        if os.path.isfile(path) and not force:
            raise RtuSniffError(ErrorKind.OUTPUT_FAILED, "exists; add --force to overwrite it", path=path)


def _input_name(source: str) -> str:
    return "on standard input" if source == "-" else source


def _is_standard_input(path: str) -> bool:
    """Whether ``path`` is the file standard input reads (``rtusniff analyze - -o x < x``)."""
    try:
        mine, theirs = os.fstat(sys.stdin.fileno()), os.stat(path)
    except (OSError, ValueError, AttributeError):  # no such file yet, or no standard input
        return False
    return (mine.st_dev, mine.st_ino) == (theirs.st_dev, theirs.st_ino) and stat.S_ISREG(mine.st_mode)


def _same_file(a: str, b: str) -> bool:
    """Whether ``a`` and ``b`` are one file: the same inode (links, other spellings), or the
    same resolved path where one does not exist yet."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def human_size(count: int) -> str:
    """``532 bytes``, ``1.2 MB``: decimal units, as file managers show them."""
    if count < 1000:
        return f"{count} bytes"
    value = count / 1000
    for unit in ("kB", "MB", "GB"):
        if value < 1000:
            return f"{value:.1f} {unit}"
        value /= 1000
    return f"{value:.1f} TB"


def add_output_option(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    parser.add_argument("-o", "--output", help="write to this file instead of standard output")


def add_width_option(parser: argparse.ArgumentParser | argparse._ArgumentGroup, row: str = "row") -> None:
    parser.add_argument("--width", type=int, metavar="COLUMNS",
                        help=f"lay the table out for a terminal this wide, also into a pipe or a file (0: one line "
                        f"per {row}, as into a pipe)")


def add_force_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--force", action="store_true", help="overwrite an existing output file (never the input)")


def open_output(path: str | None, stack: ExitStack, *, as_it_goes: bool = False) -> TextIO:
    """Standard output, or the file ``-o`` names: written under a part name and given its own
    when the command ends well (a failed run leaves nothing that looks like a result), or
    ``as_it_goes`` under its own name from the start (``--follow``: for ``tail -f``)."""
    if path is None or path == "-":
        return sys.stdout
    try:
        target = path if as_it_goes else stack.enter_context(published_whole(path))
        return stack.enter_context(open_new_text(target))
    except OSError as exc:
        raise RtuSniffError(ErrorKind.OUTPUT_FAILED, f"cannot write: {exc.strerror}", path=path) from None


def add_channel_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--channel", action="append", metavar="NAME|NUMBER",
                        help="for a logic analyzer's recording (.sr, Saleae .csv): the probe the bus is on, by "
                        "name (matched first) or number from 1; twice for RX and TX on two probes (merged in "
                        "time order). Default: the only probe that changes")
    parser.add_argument("--invert", action=argparse.BooleanOptionalAction, default=None,
                        help="for a logic analyzer's recording: read its lines inverted (idling low), or not "
                        "(--no-invert). Default: as the first sample's level says, unless the other way reads "
                        "with clearly fewer framing errors; a warning says when a line is read inverted")


def add_input_format_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--input-format",
        choices=sorted(formats_for("read")),
        help="capture format of the input (default: from the file suffix, else from its first bytes; "
        f"text for -). {format_help('read')}",
    )


def line_override(args: argparse.Namespace) -> LineSettings | None:
    """The ``--line`` settings, or ``None`` when not given."""
    if args.line is None:
        return None
    try:
        return LineSettings.parse(args.line, char_timing=args.char_timing)
    except ValueError as exc:
        raise RtuSniffError(ErrorKind.USAGE, f"--line: {exc}") from None


def apply_char_timing(line: LineSettings, args: argparse.Namespace) -> LineSettings:
    return replace(line, char_timing=True) if args.char_timing else line


def tell_written(args: argparse.Namespace, written: list[tuple[str, str]]) -> None:
    """One line per file on standard error, ``wrote PATH: WHAT, SIZE``, unless ``--quiet``."""
    if getattr(args, "quiet", False):
        return
    for path, what in written:
        if not os.path.isfile(path):  # /dev/null, a pipe: nothing to tell
            continue
        print(f"wrote {path}: {what}, {human_size(os.path.getsize(path))}", file=sys.stderr)

"""Wireshark's extcap protocol: rtusniff as a live capture interface inside Wireshark.

Wireshark runs every program of its extcap folder (``rtusniff wireshark setup`` puts a launcher
there) and asks, as its extcap documentation defines:

* ``--extcap-interfaces``: the interfaces, one per serial port (``rtusniff:PORT``, shown as
  "Modbus RTU (rtusniff): PORT");
* ``--extcap-interface IF --extcap-dlts``: the link type the capture writes;
* ``--extcap-interface IF --extcap-config``: the options dialog (line settings, ``auto``
  included, character timing, response timeout, a recording of its own, device profiles);
* ``--capture --extcap-interface IF --fifo PATH [options]``: capture, passively as ``rtusniff
  capture`` does, and write pcapng into the FIFO as frames are framed: each frame in a UDP packet
  (read by the ``rtusniff`` profile), with its direction and rtusniff's comment, which ends with
  the frame's summary (the parameters a device profile names).

Wireshark stops a capture with SIGTERM, or by closing the FIFO: either ends it as Ctrl-C ends
``rtusniff capture``, the recording closed whole. Nothing is printed but errors: Wireshark shows
an extcap's standard error as a failure.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Iterable

from sniffer.errors import ErrorKind, RtuSniffError
from sniffer.exports.pcap_export import LINKTYPE_RAW_IP
from sniffer.stopping import TERMINATED
from sniffer.tool_version import version_number

PREFIX = "rtusniff:"
HELP_URL = "https://pypi.org/project/rtusniff/"
DEFAULT_LINE = "19200 8E1"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options Wireshark passes (see the module docstring), and the dialog's."""
    parser.add_argument("--extcap-interfaces", action="store_true", help="list the interfaces (Wireshark asks)")
    parser.add_argument("--extcap-version", metavar="VERSION", help="Wireshark's version (it says it)")
    parser.add_argument("--extcap-interface", metavar="IF", help="the interface asked about or captured")
    parser.add_argument("--extcap-dlts", action="store_true", help="the interface's link type")
    parser.add_argument("--extcap-config", action="store_true", help="the interface's options dialog")
    parser.add_argument("--extcap-capture-filter", metavar="FILTER", help="not supported: refused unless empty")
    parser.add_argument("--extcap-control-in", help=argparse.SUPPRESS)
    parser.add_argument("--extcap-control-out", help=argparse.SUPPRESS)
    parser.add_argument("--debug-file", help=argparse.SUPPRESS)
    parser.add_argument("--capture", action="store_true", help="capture into --fifo")
    parser.add_argument("--fifo", metavar="PATH", help="where Wireshark reads the capture")
    parser.add_argument("--port", action="append", default=[], metavar="PORT",
                        help="a port to list besides those the system lists (a symlink, an RS485 HAT)")
    parser.add_argument("--line", default=DEFAULT_LINE, metavar="'BAUD FORMAT'|auto")
    parser.add_argument("--char-timing", action="store_true", help="as for analyze")
    parser.add_argument("--response-timeout", type=float, metavar="MS", help="as for capture")
    parser.add_argument("--record", metavar="FILE", help="also record every byte to FILE.mcap or FILE.log")
    parser.add_argument("--profile", default="", metavar="[SLAVE=]NAME,…",
                        help="device profiles, as capture's --profile, separated by commas")


def run(args: argparse.Namespace) -> int:
    if args.extcap_interfaces:
        print("\n".join(interfaces(args.port)))
        return 0
    if not (args.extcap_dlts or args.extcap_config or args.capture):
        raise RtuSniffError(ErrorKind.USAGE, "wireshark extcap: give --extcap-interfaces, --extcap-dlts, "
                            "--extcap-config or --capture (Wireshark runs this; see 'rtusniff wireshark setup')")
    port = _port(args.extcap_interface)
    if args.extcap_dlts:
        print(f"dlt {{number={LINKTYPE_RAW_IP}}}{{name=RAW}}{{display=Modbus RTU frames in UDP (rtusniff)}}")
        return 0
    if args.extcap_config:
        print("\n".join(config()))
        return 0
    return capture(port, args)


def interfaces(extra: Iterable[str]) -> list[str]:
    from sniffer.serial_source import serial_ports  # noqa: PLC0415 - pyserial's port listing, only here

    ports = dict.fromkeys([device for device, _, _ in serial_ports()] + list(extra))
    lines = [f"extcap {{version={version_number()}}}{{help={HELP_URL}}}"]
    lines += [f"interface {{value={PREFIX}{port}}}{{display=Modbus RTU (rtusniff): {port}}}" for port in ports]
    return lines


def config() -> list[str]:
    """The options dialog. The line is a text (``editselector``, a list one can type in, is
    Wireshark 4.2's: 4.0 drops the whole option)."""
    return [
        f"arg {{number=0}}{{call=--line}}{{display=Line settings}}{{type=string}}{{default={DEFAULT_LINE}}}"
        "{required=true}{validation=^ *([0-9]+ +[5-8][NEOMSneoms][12](\\.5)?|[Aa][Uu][Tt][Oo]) *$}"
        "{tooltip=Baud rate and character format: 19200 8E1 (8 data bits, even parity, 1 stop bit), 9600 8N1, "
        "... or auto, found by listening to each usual setting}",
        "arg {number=1}{call=--char-timing}{display=Character timing at every baud rate}{type=boolflag}"
        "{tooltip=1.5/3.5 character times above 19200 Bd too, instead of the fixed 750/1750 us}",
        "arg {number=2}{call=--response-timeout}{display=Response timeout (ms)}{type=double}"
        "{tooltip=A request not answered within it is a timeout (empty: derived from the traffic)}",
        "arg {number=3}{call=--record}{display=Also record to}{type=fileselect}{mustexist=false}"
        "{tooltip=Every byte with its time, as rtusniff capture -o writes it (.mcap or .log): a new file}",
        "arg {number=4}{call=--profile}{display=Device profiles}{type=string}"
        f"{{tooltip=The drives' profiles, whose parameter names and values each packet's comment shows: "
        f"NAME for every slave or SLAVE=NAME, separated by commas ({', '.join(_profile_names())}); empty: "
        "slaves that identify themselves (FC 43) get theirs}",
    ]


def _profile_names() -> list[str]:
    from sniffer.profiles_io import shipped_profiles  # noqa: PLC0415 - the profiles, only for the dialog

    return sorted(shipped_profiles())


def _port(interface: str | None) -> str:
    if interface is None or not interface.startswith(PREFIX):
        raise RtuSniffError(ErrorKind.USAGE, f"wireshark extcap: --extcap-interface {interface!r} is not one of "
                            f"rtusniff's ({PREFIX}PORT)")
    return interface.removeprefix(PREFIX)


def capture(port: str, args: argparse.Namespace) -> int:
    from rich.console import Console  # noqa: PLC0415 - only to capture: Wireshark asks the rest often

    from sniffer.commands.capture import check_recording, line_settings  # noqa: PLC0415 - the capture's rules
    from sniffer.commands.common import response_timeout_ns  # noqa: PLC0415
    from sniffer.exports.outputs import PcapSink  # noqa: PLC0415
    from sniffer.line_probe import PROBE_SECONDS  # noqa: PLC0415
    from sniffer.live_capture import CaptureOptions, run_capture  # noqa: PLC0415
    from sniffer.profiles_io import profile_book  # noqa: PLC0415

    if args.fifo is None:
        raise RtuSniffError(ErrorKind.USAGE, "wireshark extcap: --capture needs --fifo PATH")
    if args.extcap_capture_filter:
        raise RtuSniffError(ErrorKind.USAGE, "capture filters are not supported: filter the display instead "
                            "(mbrtu.unit_id == 2)")
    record = args.record or None
    choices = [choice.strip() for choice in args.profile.replace(" ", ",").split(",") if choice.strip()]
    if record is not None:
        check_recording(record, rotating=False)
    with open(os.devnull, "w", encoding="utf-8") as quiet:
        err = Console(file=quiet)  # Wireshark shows standard error as a failure: errors alone go there
        line, guessed = line_settings(args.line, port, args.char_timing, PROBE_SECONDS, err)
        options = CaptureOptions(
            port=port, line=line, output=record, rotation=None, mode="none", duration_s=None,
            response_timeout_ns=response_timeout_ns(args), profiles=profile_book(choices, []),
            pcap=PcapSink(args.fifo, udp=True, pcapng=True), line_guessed=guessed)
        code = run_capture(options, quiet, err)
    return 0 if code == TERMINATED else code  # Wireshark's stop is SIGTERM: the capture ended as asked

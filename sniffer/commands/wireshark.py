"""``rtusniff wireshark setup`` and ``rtusniff wireshark extcap``: rtusniff inside Wireshark."""

from __future__ import annotations

import argparse
from pathlib import Path

from sniffer.errors import ErrorKind, RtuSniffError


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "wireshark", help="set Wireshark up for rtusniff's pcaps and live capture (once)",
        description="Wireshark with rtusniff: 'setup' writes the configuration profile 'rtusniff' and installs "
        "rtusniff as an extcap capture interface; 'extcap' is what Wireshark then runs.")
    parser.set_defaults(run=lambda args: parser.error("give 'setup' (or 'extcap', which Wireshark runs)"))
    commands = parser.add_subparsers(title="commands", metavar="COMMAND")
    setup = commands.add_parser(
        "setup", help="write the profile 'rtusniff' and install the extcap (never over a file of yours)",
        description="Write the Wireshark configuration profile 'rtusniff' (Modbus RTU on UDP port 502, CRC "
        "checking, DLT_USER 147 as Modbus RTU) and an extcap launcher, so that 'wireshark -C rtusniff FILE' "
        "classifies every frame of an exported pcap and each serial port is a capture interface. Refuses to "
        "replace a file it did not write.")
    setup.add_argument("--config-dir", metavar="DIR", help="Wireshark's personal configuration folder (default: "
                       "as 'tshark -G folders' says, or Wireshark's default)")
    setup.add_argument("--extcap-dir", metavar="DIR", help="Wireshark's personal extcap folder (the same)")
    setup.add_argument("--port", action="append", default=[], metavar="PORT",
                       help="a serial port to offer besides those the system lists (repeatable)")
    setup.set_defaults(run=run_setup)
    extcap = commands.add_parser("extcap", help="the extcap protocol (Wireshark runs it)",
                                 description="Wireshark's extcap protocol; Wireshark runs it through the launcher "
                                 "that 'rtusniff wireshark setup' installs.")
    from sniffer.extcap import add_arguments  # noqa: PLC0415 - with the command only

    add_arguments(extcap)
    extcap.set_defaults(run=run_extcap)


def run_setup(args: argparse.Namespace) -> int:
    from sniffer.wireshark_setup import PROFILE, Folders, install, tshark_program, wireshark_folders  # noqa: PLC0415

    tshark = tshark_program()
    found = wireshark_folders(tshark)
    folders = Folders(Path(args.config_dir) if args.config_dir else found.configuration,
                      Path(args.extcap_dir) if args.extcap_dir else found.extcap,
                      "given" if args.config_dir or args.extcap_dir else found.found_by)
    for port in args.port:
        if not port.strip():
            raise RtuSniffError(ErrorKind.USAGE, "--port: name a serial port")
    for path, what in install(folders, args.port):
        print(f"{what:9}  {path}")
    print(f"folders: {folders.found_by}")
    print(f"open an exported pcap:  wireshark -C {PROFILE} FILE.pcapng")
    print(f"capture live:           wireshark -C {PROFILE}, then the interface 'Modbus RTU (rtusniff): PORT'")
    if tshark is None:
        print("tshark was not found: the folders are Wireshark's defaults; check them in Wireshark's "
              "Help > About > Folders")
    return 0


def run_extcap(args: argparse.Namespace) -> int:
    from sniffer.extcap import run  # noqa: PLC0415

    return run(args)

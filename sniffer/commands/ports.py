"""``rtusniff ports``: the serial ports of this machine."""

from __future__ import annotations

import argparse

from sniffer.serial_source import serial_ports


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser("ports", help="list the serial ports (for capture)",
                                   description="List the serial ports pyserial finds, with their descriptions.")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from rich.console import Console  # noqa: PLC0415 - rich: tens of ms to import, only for a terminal
    from rich.table import Table  # noqa: PLC0415

    console = Console(highlight=False, markup=False)  # a description may hold brackets: "USB Serial [CH340]"
    ports = serial_ports()
    if not ports:
        console.print("no serial ports found (a USB-RS485 adapter shows up as /dev/ttyUSB0 or /dev/ttyACM0)")
        return 0
    table = Table("port", "description", "hardware id")
    for device, description, hwid in ports:
        table.add_row(device, description, hwid)
    console.print(table)
    return 0

"""``--registers``, ``--addressing``: register values and addresses in the table as a device's
manual writes them, for slaves without a profile (:mod:`decoders.register_format`; the values
are the decoding's, typed by ``--registers``'s profile). Frames a profile decodes keep its
names and units."""

from __future__ import annotations

import argparse

from decoders.decoded_batch import remarked
from decoders.message import Decoding
from decoders.register_format import ADDRESSINGS, RegisterFormat
from sniffer.views.frame_cells import SummaryOf, decoding_summary

CRC_ERROR = "CRC error: "
#: Summaries remembered per decoding (repeats share one decoding).
KEPT_SUMMARIES = 65536


def add_register_options(parser: argparse._ArgumentGroup) -> None:
    parser.add_argument("--addressing", choices=ADDRESSINGS, default="wire",
                        help="register addresses as sent (wire, from 0; default), from 1, or as Modicon 4x "
                        "references (40001 for holding register 0, 30001 input registers, 00001 coils)")


def summary_reader(args: argparse.Namespace) -> SummaryOf:
    """What the table writes for a decoding under these options."""
    if not args.registers and args.addressing == "wire":
        return decoding_summary
    registers = RegisterFormat(any(spec.kind != "hex" for spec in args.registers), args.addressing)
    known: dict[Decoding, str] = {}

    def summary(decoding: Decoding) -> str:
        text = known.get(decoding)
        if text is None:
            text = _summary(registers, decoding)
            if len(known) >= KEPT_SUMMARIES:
                known.clear()
            known[decoding] = text
        return text

    return summary


def _summary(registers: RegisterFormat, decoding: Decoding) -> str:
    if any(param.code is not None for param in decoding.params):
        return decoding_summary(decoding)
    text = registers.summary(decoding.pdu, decoding.params)
    if text is None:
        return decoding_summary(decoding)
    if decoding.summary.startswith(CRC_ERROR):
        text = CRC_ERROR + text
    return remarked(text, decoding.remarks)

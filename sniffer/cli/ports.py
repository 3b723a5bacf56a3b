"""Provides `modscope ports`: this machine's serial ports with their USB ids."""

from __future__ import annotations

import argparse
import json
from typing import TextIO

from sniffer.cli.options import SubParsers
from sniffer.live.port import list_ports
from sniffer.text import plain


def cmd_ports(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    ports = list(list_ports(include_links=True))
    if args.format == "jsonl":
        for p in ports:
            rec = {
                "device": p.device,
                "description": p.description,
                "usb_id": p.usb_id or None,
                "serial_number": p.serial_number,
                "manufacturer": p.manufacturer,
                "product": p.product,
                "location": p.location,
                "hwid": p.hwid,
            }
            out.write(json.dumps(rec) + "\n")
        return 0
    if not ports:
        err.write(
            "modscope: no serial ports found; plug in the adapter (dmesg shows whether the "
            "kernel saw it), or give a device path or URL to `modscope live` directly\n"
        )
        return 0
    width = max(len(p.device) for p in ports)
    for p in ports:
        usb = f"  USB {p.usb_id}" if p.usb_id else ""
        serial_no = f"  serial {p.serial_number}" if p.serial_number else ""
        out.write(f"{p.device:<{width}}  {plain(p.description)}{usb}{serial_no}\n")
    return 0


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "ports",
        help="list this machine's serial ports with their USB ids",
        description="List serial ports (pyserial's list_ports): device, description, USB ids.",
    )
    p.add_argument("--format", choices=("text", "jsonl"), default="text", help="output style")
    p.set_defaults(func=cmd_ports)

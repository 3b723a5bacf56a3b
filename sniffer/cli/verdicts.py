"""Provides the exit status of a command that read a capture, with the one line that says
why when nothing in it was usable (see `sniffer.session.verdict`)."""

from __future__ import annotations

from typing import TextIO

from sniffer.session.session import Session
from sniffer.session.verdict import NOTHING_USABLE, read_verdict
from sniffer.sources import Capture
from sniffer.text import plain

WHAT_MODSCOPE_READS = (
    "modscope reads Modbus serial data (RTU or ASCII) from pcap/pcapng link types 147, 250 "
    "and 252, Modbus TCP or RTU over TCP/UDP in Ethernet captures, sigrok .sr logic "
    "captures, hex dumps (socat -x, text2pcap), serial monitor and Modbus library logs, "
    "Saleae CSV exports and raw bytes"
)


def finish_read(capture: Capture, session: Session, err: TextIO) -> int:
    """The verdict on a capture read to the end: 0, 1 or 2. On 2 the reason goes to `err`
    as `modscope: error: ...`, naming the file, what it was read as and what modscope
    reads, so a wrong file never passes for an empty bus."""
    verdict = read_verdict(capture, session)
    if verdict.status != NOTHING_USABLE:
        return verdict.status
    reason = verdict.reason
    if capture.empty:
        reason = (
            f"{capture.info.path}: no Modbus serial data in it (read as "
            f"{capture.info.format}); {WHAT_MODSCOPE_READS}"
        )
    err.write(f"modscope: error: {plain(reason)}\n")
    return verdict.status

"""Provides the verdict on a capture read to the end, as capture tools give it in their exit
status: 0 everything read, 1 read with warnings (a truncated file, a skipped block), 2
nothing usable (no serial data, or bytes of which not one forms a Modbus frame)."""

from __future__ import annotations

from dataclasses import dataclass

from sniffer.session.session import Session
from sniffer.sources import Capture
from sniffer.vocab import Kind

ALL_READ = 0
READ_WITH_WARNINGS = 1
NOTHING_USABLE = 2


@dataclass(frozen=True, slots=True)
class Verdict:
    """The exit status of a read and, when it is 2, the sentence that says why."""

    status: int
    reason: str = ""


def read_verdict(capture: Capture, session: Session) -> Verdict:
    """The verdict once `session` has ingested all of `capture.chunks()`."""
    path = capture.info.path
    if capture.empty:
        return Verdict(NOTHING_USABLE, f"{path}: no serial data could be read from it")
    store = session.store
    kinds = store.kind.tobytes()  # counted as bytes: bytes.count runs in C, array.count not
    frames = len(kinds) - kinds.count(Kind.NOISE) - kinds.count(Kind.EVENT)
    frames += session.frames_before  # (a windowed session: those of the rows dropped)
    if frames == 0 and capture.data_bytes:
        return Verdict(
            NOTHING_USABLE,
            f"{path}: {capture.data_bytes:,} bytes read and not one Modbus frame among them "
            "(all noise); check the line settings (--baud, --parity, --mode) and that this "
            "is a capture of a Modbus line",
        )
    if capture.warnings or session.warnings:
        return Verdict(READ_WITH_WARNINGS)
    return Verdict(ALL_READ)

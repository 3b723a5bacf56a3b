"""Provides the exporters: frames for Wireshark (pcapng, link type 252), CSV/JSONL tables.

Wireshark export: one packet per frame, link type 252 (exported PDU) naming the `mbrtu`
dissector, so Wireshark and tshark decode it with no configuration. The packet flags
carry the direction as seen from the master: requests outbound (2), answers and
exceptions inbound (1), frames whose direction is unknown neither. A frame whose CRC
or LRC is wrong has the CRC-error bit (bit 24) set; every problem modscope found is in
the packet comment. Noise spans and source events (reconnect, data lost) go out as
packets for the `data` dissector, with a comment. Wireshark has no Modbus ASCII
dissector: an ASCII frame is exported as the equivalent RTU frame (its unit and PDU
with a computed CRC), and the comment says it was carried as ASCII with its LRC.

Tables: `frames` (the listing: text, JSONL or CSV), `transactions` (one row per request
with its answer, latency and status; answers without a request get a row too) and
`registers` (one row per register value: named by the device dictionary for bound
units, raw 16-bit words or bits for the others).
"""

from __future__ import annotations

import csv
from collections.abc import Iterable, Iterator
from typing import Any, BinaryIO, TextIO

from dissectors.envelope import open_ascii, rtu_frame
from sniffer import __version__
from sniffer.describe import Describer, FrameDetail
from sniffer.listing import FORMATS, KIND_NAMES
from sniffer.model import LineSettings
from sniffer.sources.pcapng_writer import (
    EPB_FLAG_CRC_ERROR,
    EPB_FLAG_INBOUND,
    EPB_FLAG_OUTBOUND,
    LINKTYPE_WIRESHARK_UPPER_PDU,
    PcapngWriter,
    describe_interface,
    upper_pdu_record,
)
from sniffer.store import NO_PARTNER
from sniffer.text import csv_row, json_line
from sniffer.vocab import STATUS_NAMES, Flag, Kind

WHATS = ("frames", "transactions", "registers")
EXPORT_FORMATS = (*FORMATS, "pcapng", "parquet")
EXTENSIONS = {
    ".pcapng": "pcapng",
    ".parquet": "parquet",
    ".csv": "csv",
    ".jsonl": "jsonl",
    ".ndjson": "jsonl",
    ".json": "jsonl",
    ".txt": "text",
    ".log": "text",
}
TRANSACTION_COLUMNS = (
    "request", "t", "unit", "device", "function", "name", "request_summary",
    "response", "t_response", "latency_ms", "status", "exception_code", "response_summary",
    "problems", "request_raw", "response_raw",
)  # fmt: skip
REGISTER_COLUMNS = (
    "index", "t", "unit", "device", "access", "table", "address", "name", "value",
    "value_unit", "text", "raw", "partial", "check_ok",
)  # fmt: skip


# -- Wireshark ---------------------------------------------------------------------------


def packet_for(d: FrameDetail) -> tuple[bytes, int, str]:
    """(link type 252 packet, EPB flags, comment) for one row."""
    v = d.view
    problems = list(d.problem_texts)
    if v.kind == Kind.EVENT:
        return upper_pdu_record(b"", "data"), 0, d.summary or "event"
    if v.kind == Kind.NOISE:
        return upper_pdu_record(v.raw, "data"), 0, "; ".join(problems)
    flags = 0
    if v.kind == Kind.REQUEST:
        flags |= EPB_FLAG_OUTBOUND
    elif v.kind in (Kind.RESPONSE, Kind.EXCEPTION):
        flags |= EPB_FLAG_INBOUND
    if v.flags & Flag.CHECK_BAD:
        flags |= EPB_FLAG_CRC_ERROR
    if v.mbap:  # a Modbus TCP frame as it was, MBAP header and PDU
        return upper_pdu_record(v.raw, "mbtcp"), flags, "; ".join(problems)
    if v.ascii:
        envelope = open_ascii(v.raw)
        sent, want = envelope.sent, envelope.expected
        if sent is None or want is None or len(envelope.body) < 2:
            problems.insert(0, "Modbus ASCII frame that is not hex; exported as bytes")
            return upper_pdu_record(v.raw, "data"), flags, "; ".join(problems)
        verdict = "right" if sent == want else f"wrong, expected {want:02X}"
        problems.insert(
            0, f"carried as Modbus ASCII with LRC {sent:02X} ({verdict}); CRC computed here"
        )
        return upper_pdu_record(rtu_frame(envelope.body)), flags, "; ".join(problems)
    return upper_pdu_record(v.raw), flags, "; ".join(problems)


class PcapExporter:
    """Writes rows of a session's store as link type 252 packets, flushed per packet."""

    def __init__(
        self,
        stream: BinaryIO,
        describer: Describer,
        line: LineSettings,
        *,
        name: str = "modscope",
    ) -> None:
        self.describer = describer
        self.writer = PcapngWriter(stream, application=f"modscope {__version__}")
        self.interface = self.writer.add_interface(
            LINKTYPE_WIRESHARK_UPPER_PDU, name=name, description=describe_interface(line)
        )
        self.packets = 0

    def write(self, rows: Iterable[int]) -> int:
        n = 0
        for i in rows:
            d = self.describer.detail(i)
            packet, flags, comment = packet_for(d)
            self.writer.write_packet(
                self.interface,
                max(d.view.t_end, 0.0),
                packet,
                flags=flags,
                comment=comment or None,
            )
            n += 1
        self.packets += n
        return n


# -- transactions and registers -------------------------------------------------------------


def _exception_code(d: FrameDetail) -> int | None:
    if not d.view.exception:
        return None
    found = d.dissection.field("exception_code") if d.dissection is not None else None
    return found.value if found is not None and isinstance(found.value, int) else None


def transaction_records(describer: Describer, rows: Iterable[int]) -> Iterator[dict[str, Any]]:
    """One record per request (with its answer, if any) and per answer without request."""
    store = describer.store
    for i in rows:
        kind = store.kind[i]
        if kind == Kind.REQUEST:
            req: FrameDetail | None = describer.detail(i)
            j = store.partner[i]
            resp = describer.detail(j) if j != NO_PARTNER else None
        elif kind in (Kind.RESPONSE, Kind.EXCEPTION, Kind.UNKNOWN) and (
            store.partner[i] == NO_PARTNER
        ):
            req, resp = None, describer.detail(i)
        else:
            continue
        main = req if req is not None else resp
        assert main is not None
        v = main.view
        problems = [*(req.problem_texts if req else ()), *(resp.problem_texts if resp else ())]
        latency = (resp.latency_ms if resp is not None else None) if req is not None else None
        yield {
            "request": req.view.index if req else None,
            "t": req.view.t if req else None,
            "unit": v.unit,
            "device": main.label,
            "function": v.function,
            "name": main.name,
            "request_summary": req.summary if req else "",
            "response": resp.view.index if resp else None,
            "t_response": resp.view.t if resp else None,
            "latency_ms": None if latency is None else round(latency, 3),
            "status": STATUS_NAMES[v.status] or KIND_NAMES[Kind(v.kind)],
            "exception_code": _exception_code(resp) if resp else None,
            "response_summary": resp.summary if resp else "",
            "problems": list(dict.fromkeys(problems)),
            "request_raw": req.view.raw.hex() if req else "",
            "response_raw": resp.view.raw.hex() if resp else "",
        }


def register_records(describer: Describer, rows: Iterable[int]) -> Iterator[dict[str, Any]]:
    """One record per register or bit value a frame carries (named where a dictionary
    binds the unit; raw values otherwise)."""
    store = describer.store
    for i in rows:
        if store.kind[i] not in (Kind.REQUEST, Kind.RESPONSE):
            continue
        d = describer.detail(i)
        v = d.view
        base = {"index": v.index, "t": v.t, "unit": v.unit, "device": d.label}
        if d.registers:
            for r in d.registers:
                yield {
                    **base,
                    "access": "write" if v.kind == Kind.REQUEST else "read",
                    "table": r.table,
                    "address": r.address,
                    "name": r.name,
                    "value": r.value,
                    "value_unit": r.unit,
                    "text": r.text,
                    "raw": list(r.raw),
                    "partial": r.partial,
                    "check_ok": v.check_ok,
                }
            continue
        if d.dissection is None:
            continue
        for data in d.dissection.data:
            if data.address is None:
                continue
            for k, value in enumerate(data.values):
                yield {
                    **base,
                    "access": "write" if data.write else "read",
                    "table": data.table,
                    "address": data.address + k,
                    "name": "",
                    "value": value,
                    "value_unit": "",
                    "text": str(value),
                    "raw": [value],
                    "partial": False,
                    "check_ok": v.check_ok,
                }


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.6f}".rstrip("0").rstrip(".") if value == value else "nan"
    if isinstance(value, list):
        joiner = "; " if value and isinstance(value[0], str) else " "
        return joiner.join(str(x) for x in value)
    return str(value)


def write_table(
    out: TextIO,
    fmt: str,
    columns: tuple[str, ...],
    records: Iterable[dict[str, Any]],
    *,
    raw_csv: bool = False,
) -> int:
    """Records as JSONL or CSV (with a header row). Returns the number written. CSV cells
    go through `sniffer.text.csv_cell` (formula guard unless `raw_csv`)."""
    n = 0
    if fmt == "csv":
        writer = csv.writer(out)
        writer.writerow(columns)
        for rec in records:
            writer.writerow(csv_row((_cell(rec.get(c)) for c in columns), raw=raw_csv))
            n += 1
    elif fmt == "jsonl":
        for rec in records:
            out.write(json_line(rec) + "\n")
            n += 1
    else:
        raise ValueError(f"{fmt} cannot hold this table; use csv or jsonl")
    return n

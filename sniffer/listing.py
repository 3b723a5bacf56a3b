"""Provides the frame listing: one line per row as text, a JSON object, or a CSV record."""

from __future__ import annotations

import csv
from collections.abc import Iterable
from datetime import UTC, datetime
from typing import Any, TextIO

from sniffer.describe import Describer, FrameDetail
from sniffer.model import Stamp
from sniffer.store import NO_PARTNER
from sniffer.text import csv_row, json_line
from sniffer.vocab import STATUS_NAMES, Kind

FORMATS = ("text", "jsonl", "csv")
KIND_NAMES = {
    Kind.NOISE: "noise",
    Kind.REQUEST: "request",
    Kind.RESPONSE: "response",
    Kind.EXCEPTION: "exception",
    Kind.UNKNOWN: "unknown",
    Kind.EVENT: "event",
}
CSV_COLUMNS = (
    "index",
    "t",
    "t_end",
    "direction",
    "kind",
    "unit",
    "function",
    "name",
    "length",
    "check_ok",
    "status",
    "latency_ms",
    "summary",
    "problems",
    "raw",
    "channel",
    "peer",  # network captures: the sender's ip:port
)


# JSONL `timing`: what the row times are (see sniffer.model.Stamp); "synthetic" when the
# source had none and the times were made up from the baud rate
TIMING_NAMES = {stamp: stamp.value for stamp in Stamp} | {Stamp.NONE: "synthetic"}
SYNTHETIC_HEADER = (
    "# timing: synthetic: the source has no timestamps; times below are one character "
    "time per byte, and no latency is measured"
)


def _jsonable(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.hex()
    if isinstance(value, tuple):
        return [_jsonable(v) for v in value]
    return value


def record(d: FrameDetail) -> dict[str, Any]:
    """The JSONL object of a row. Keys keep their meaning as fields are added."""
    v = d.view
    rec: dict[str, Any] = {
        "index": v.index,
        "t": v.t,
        "t_end": v.t_end,
        "raw": v.raw.hex(),
        "mode": "ascii" if v.ascii else "tcp" if v.mbap else "rtu",
        "kind": KIND_NAMES[v.kind],
        "unit": v.unit if v.kind not in (Kind.NOISE, Kind.EVENT) else None,
        "function": v.function if v.kind not in (Kind.NOISE, Kind.EVENT) else None,
        "check_ok": v.check_ok,
        "problems": list(d.problem_texts),
        "channel": v.channel,
        "direction": d.direction,
        "name": d.name,
        "summary": d.summary,
    }
    if d.problems:
        rec["problem_details"] = [
            {
                "kind": p.kind,
                "severity": p.severity,
                "text": p.text,
                "span": None if p.span is None else list(p.span),
            }
            for p in d.problems
        ]
    if d.label:
        rec["device"] = d.label
    if d.dissection is not None:
        rec["fields"] = [
            {"name": f.name, "value": _jsonable(f.value), "text": f.text, "span": list(f.span)}
            for f in d.dissection.fields
        ]
    if v.kind in (Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION, Kind.UNKNOWN) and v.status:
        req = v.index if v.kind == Kind.REQUEST or v.partner == NO_PARTNER else v.partner
        rec["transaction"] = {
            "id": req,
            "role": "request" if v.kind == Kind.REQUEST else "response",
            "latency_ms": None if d.latency_ms is None else round(d.latency_ms, 3),
            "latency_max_ms": None if d.latency_max_ms is None else round(d.latency_max_ms, 3),
            "status": STATUS_NAMES[v.status],
            "partner": None if v.partner == NO_PARTNER else v.partner,
        }
    if d.registers:
        rec["registers"] = [
            {
                "table": r.table,
                "address": r.address,
                "name": r.name,
                "value": r.value,
                "unit": r.unit,
                "text": r.text,
                "raw": list(r.raw),
                "partial": r.partial,
            }
            for r in d.registers
        ]
    return rec


def time_text(t: float, origin: float, absolute: bool) -> str:
    if absolute:
        stamp = datetime.fromtimestamp(t, tz=UTC).astimezone()
        return stamp.strftime("%H:%M:%S.%f")
    return f"{t - origin:12.6f}"


def text_line(d: FrameDetail, origin: float, absolute: bool = False, peer: str = "") -> str:
    """One row as text; `peer` (a network row's sender, `ip:port`) follows the time."""
    v = d.view
    when = time_text(v.t, origin, absolute)
    if peer:
        when += f"  {peer:<21}"
    if v.kind == Kind.EVENT:
        return f"{when}  ---  {d.summary}"
    if v.kind == Kind.NOISE:
        return f"{when}  ???  noise {len(v.raw):3d}B  {v.raw[:24].hex(' ')}"
    unit = f"u{v.unit:<3d}"
    check = "ok " if v.check_ok else "BAD"
    fc = f"{v.function:02d}{'!' if v.exception else ' '}"
    status = STATUS_NAMES[v.status]
    lat = ""
    if v.kind != Kind.REQUEST:
        if d.latency_ms is not None:
            lat = f" {d.latency_ms:7.1f}ms"
        elif d.latency_max_ms is not None:
            lat = f" {'<' + format(d.latency_max_ms, '.0f'):>7}ms"
    line = f"{when}  {d.direction}  {unit} {fc} {d.name[:28]:<28} {len(v.raw):3d}B {check} "
    line += f"{status:<9}{lat}  {d.summary}"
    if d.problems:
        line += "  [" + "; ".join(d.problem_texts) + "]"
    return line


class Lister:
    """Writes rows to a text stream in one of FORMATS, flushing after every row.

    CSV cells go through `sniffer.text.csv_row`: text that a spreadsheet would run as a
    formula gets a leading `'` unless `raw_csv` (see `csv_cell`)."""

    def __init__(
        self,
        out: TextIO,
        fmt: str,
        describer: Describer,
        *,
        absolute: bool = False,
        raw_csv: bool = False,
    ) -> None:
        if fmt not in FORMATS:
            raise ValueError(f"format must be one of {', '.join(FORMATS)}, not {fmt!r}")
        self.out = out
        self.fmt = fmt
        self.describer = describer
        self.absolute = absolute
        self.origin: float | None = None
        self.raw_csv = raw_csv
        self._csv = csv.writer(out) if fmt == "csv" else None
        if self._csv is not None:
            self._csv.writerow(CSV_COLUMNS)

    def write(self, rows: Iterable[int], flush: bool = True) -> int:
        n = 0
        store = self.describer.store
        for i in rows:
            if self.origin is None:
                self.origin = store.t[i]
                if self.fmt == "text" and store.stamps == Stamp.NONE:
                    self.out.write(SYNTHETIC_HEADER + "\n")
            d = self.describer.detail(i)
            peer = store.peers.get(store.channel[i], "") if store.peers else ""
            if self.fmt == "text":
                # with network rows about, the others name their channel in that column
                where = peer or (f"ch{store.channel[i]}" if store.peers else "")
                self.out.write(text_line(d, self.origin, self.absolute, where) + "\n")
            elif self.fmt == "jsonl":
                rec = record(d)
                rec["timing"] = TIMING_NAMES[store.stamps]
                if peer:
                    rec["peer"] = peer
                if i in store.links:
                    rec["gateway"] = store.links[i]
                self.out.write(json_line(rec) + "\n")
            else:
                assert self._csv is not None
                v = d.view
                self._csv_row(
                    (
                        v.index,
                        f"{v.t:.6f}",
                        f"{v.t_end:.6f}",
                        d.direction,
                        KIND_NAMES[v.kind],
                        v.unit,
                        v.function,
                        d.name,
                        len(v.raw),
                        v.check_ok,
                        d.status,
                        "" if d.latency_ms is None else f"{d.latency_ms:.3f}",
                        d.summary,
                        "; ".join(d.problem_texts),
                        v.raw.hex(),
                        v.channel,
                        peer,
                    )
                )
            n += 1
            if flush:
                self.out.flush()
        return n

    def _csv_row(self, cells: tuple[object, ...]) -> None:
        assert self._csv is not None
        self._csv.writerow(csv_row(cells, raw=self.raw_csv))

"""Provides Parquet tables of a capture: frames, transactions or registers, typed columns.

Columns are typed for engines (DuckDB, Polars, Spark): times as UTC timestamps
(`time`, microseconds; null for captures with relative times) beside `t` in seconds,
unit and function as small integers, latencies and values as doubles, names and kinds
as dictionary-encoded strings, raw frames as bytes. Rows are written in row groups of
`ROW_GROUP` rows as they are made, so a day's capture exports in bounded memory.

`frames` is built from the store's columns alone (no dissection: fast); its `name` is
the function's name. `transactions` and `registers` are the CSV/JSONL tables of
`modscope export`, typed. Needs pyarrow: `pip install 'modscope[analytics]'`.
"""

from __future__ import annotations

import datetime as dt
import importlib.util
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

from dissectors.functions import function_name
from sniffer.framing.pairing import measure
from sniffer.framing.store import NO_PARTNER
from sniffer.meaning.describe import Describer
from sniffer.outputs.export import register_records, transaction_records
from sniffer.outputs.listing import KIND_NAMES
from sniffer.vocab import STATUS_NAMES, Kind

ROW_GROUP = 65_536
EXTRA_HINT = "Parquet export needs pyarrow: pip install 'modscope[analytics]'"
ABSOLUTE = 86400 * 366  # times beyond a year are Unix times, not seconds from the start
_EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)


class ParquetError(Exception):
    """The table cannot be written (the message says what to do)."""


def require_pyarrow() -> None:
    if importlib.util.find_spec("pyarrow") is None:
        raise ParquetError(EXTRA_HINT)


def _schema(what: str) -> Any:
    import pyarrow as pa

    ts = pa.timestamp("us", tz="UTC")
    names = pa.dictionary(pa.int32(), pa.string())
    if what == "frames":
        fields = [
            ("index", pa.int64()),
            ("time", ts),
            ("t", pa.float64()),
            ("t_end", pa.float64()),
            ("kind", names),
            ("unit", pa.uint8()),
            ("function", pa.uint8()),
            ("exception", pa.bool_()),
            ("name", names),
            ("device", names),
            ("status", names),
            ("check_ok", pa.bool_()),
            ("length", pa.uint16()),
            ("channel", pa.uint8()),
            ("flags", pa.uint32()),
            ("partner", pa.int64()),
            ("latency_ms", pa.float64()),
            ("latency_max_ms", pa.float64()),
            ("raw", pa.binary()),
        ]
    elif what == "transactions":
        fields = [
            ("request", pa.int64()),
            ("time", ts),
            ("t", pa.float64()),
            ("unit", pa.uint8()),
            ("device", names),
            ("function", pa.uint8()),
            ("name", names),
            ("request_summary", pa.string()),
            ("response", pa.int64()),
            ("t_response", pa.float64()),
            ("latency_ms", pa.float64()),
            ("latency_max_ms", pa.float64()),
            ("status", names),
            ("exception_code", pa.uint8()),
            ("response_summary", pa.string()),
            ("answer_check_ok", pa.bool_()),
            ("problems", pa.list_(pa.string())),
            ("request_raw", pa.binary()),
            ("response_raw", pa.binary()),
        ]
    else:
        fields = [
            ("index", pa.int64()),
            ("time", ts),
            ("t", pa.float64()),
            ("unit", pa.uint8()),
            ("device", names),
            ("access", names),
            ("table", names),
            ("address", pa.uint16()),
            ("name", names),
            ("value", pa.float64()),
            ("value_text", pa.string()),
            ("value_unit", names),
            ("text", pa.string()),
            ("raw", pa.list_(pa.uint16())),
            ("partial", pa.bool_()),
            ("check_ok", pa.bool_()),
        ]
    return pa.schema(fields)


def _time(t: float | None) -> dt.datetime | None:
    if t is None or t < ABSOLUTE:
        return None
    return _EPOCH + dt.timedelta(seconds=t)


def frame_rows(describer: Describer, rows: Iterable[int]) -> Iterator[dict[str, Any]]:
    """One record per stored row, from the store's columns (no dissection)."""
    store = describer.store
    store.sync()
    label = describer.annotator.label
    for i in rows:
        kind = Kind(store.kind[i])
        framed = kind not in (Kind.NOISE, Kind.EVENT)
        fc = store.fc[i]
        j = store.partner[i]
        # the latency pair every listing gives (pairing.measure): a value, or a bound
        # where the timing gives no more, never a difference of times it cannot resolve
        latency = bound = None
        measured = measure(store, i) if j != NO_PARTNER else None
        if measured is not None:
            if measured.bound:
                bound = measured.ms
            else:
                latency = measured.ms
        view_ok = framed and not store.flags[i] & 0x11  # CHECK_BAD | NON_HEX
        yield {
            "index": i,
            "time": _time(store.t[i]),
            "t": store.t[i],
            "t_end": store.t_end[i],
            "kind": KIND_NAMES[kind],
            "unit": store.unit[i] if framed else None,
            "function": fc & 0x7F if framed else None,
            "exception": bool(fc & 0x80) if framed else None,
            "name": function_name(fc & 0x7F) if framed else KIND_NAMES[kind],
            "device": label(store.unit[i]) if framed else "",
            "status": STATUS_NAMES[store.status[i]],
            "check_ok": view_ok,
            "length": store.length[i],
            "channel": store.channel[i],
            "flags": store.flags[i],
            "partner": None if j == NO_PARTNER else j,
            "latency_ms": latency,
            "latency_max_ms": bound,
            "raw": store.raw(i),
        }


def transaction_rows(describer: Describer, rows: Iterable[int]) -> Iterator[dict[str, Any]]:
    store = describer.store
    for rec in transaction_records(describer, rows):
        j = rec["response"]
        rec["answer_check_ok"] = None if j is None else not store.flags[j] & 0x11
        rec["time"] = _time(rec["t"] if rec["t"] is not None else rec["t_response"])
        rec["request_raw"] = bytes.fromhex(rec["request_raw"]) if rec["request_raw"] else None
        rec["response_raw"] = bytes.fromhex(rec["response_raw"]) if rec["response_raw"] else None
        code = rec["exception_code"]
        rec["exception_code"] = code if isinstance(code, int) and 0 <= code < 256 else None
        yield rec


def register_rows(describer: Describer, rows: Iterable[int]) -> Iterator[dict[str, Any]]:
    for rec in register_records(describer, rows):
        value = rec["value"]
        rec["time"] = _time(rec["t"])
        rec["value_text"] = value if isinstance(value, str) else None
        rec["value"] = float(value) if isinstance(value, int | float) else None
        rec["raw"] = [w & 0xFFFF for w in rec["raw"] if isinstance(w, int)]
        yield rec


MAKERS: dict[str, Callable[[Describer, Iterable[int]], Iterator[dict[str, Any]]]] = {
    "frames": frame_rows,
    "transactions": transaction_rows,
    "registers": register_rows,
}


def write_parquet(
    path: str | Path,
    what: str,
    describer: Describer,
    rows: Iterable[int],
    *,
    row_group: int = ROW_GROUP,
) -> int:
    """Write the `what` table of `rows` to `path` in row groups; the number of rows."""
    require_pyarrow()
    import pyarrow as pa
    import pyarrow.parquet as pq

    schema = _schema(what)
    names = schema.names
    n = 0
    try:
        writer = pq.ParquetWriter(str(path), schema, compression="zstd")
    except OSError as exc:
        raise ParquetError(
            f"{path}: cannot be written ({exc}); choose a folder you can write to"
        ) from None
    with writer:
        batch: dict[str, list[Any]] = {c: [] for c in names}
        count = 0
        for rec in MAKERS[what](describer, rows):
            for c in names:
                batch[c].append(rec.get(c))
            count += 1
            if count >= row_group:
                writer.write_table(pa.table(batch, schema=schema))
                n += count
                batch = {c: [] for c in names}
                count = 0
        if count or n == 0:
            writer.write_table(pa.table(batch, schema=schema))
            n += count
    return n

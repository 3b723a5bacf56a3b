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
BATCH = 4_096  # records made into Arrow columns at a time (`ParquetTable`)
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


def frame_rows(
    describer: Describer, rows: Iterable[int], base: int = 0
) -> Iterator[dict[str, Any]]:
    """One record per stored row, from the store's columns (no dissection); rows
    numbered `base` on (a segment of a capture: `sniffer.session.streamed`)."""
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
            "index": i + base,
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
            "partner": None if j == NO_PARTNER else j + base,
            "latency_ms": latency,
            "latency_max_ms": bound,
            "raw": store.raw(i),
        }


def transaction_rows(
    describer: Describer, rows: Iterable[int], base: int = 0
) -> Iterator[dict[str, Any]]:
    store = describer.store
    for rec in transaction_records(describer, rows, base):
        j = rec["response"]
        rec["answer_check_ok"] = None if j is None else not store.flags[j - base] & 0x11
        rec["time"] = _time(rec["t"] if rec["t"] is not None else rec["t_response"])
        rec["request_raw"] = bytes.fromhex(rec["request_raw"]) if rec["request_raw"] else None
        rec["response_raw"] = bytes.fromhex(rec["response_raw"]) if rec["response_raw"] else None
        code = rec["exception_code"]
        rec["exception_code"] = code if isinstance(code, int) and 0 <= code < 256 else None
        yield rec


def register_rows(
    describer: Describer, rows: Iterable[int], base: int = 0
) -> Iterator[dict[str, Any]]:
    for rec in register_records(describer, rows, base):
        value = rec["value"]
        rec["time"] = _time(rec["t"])
        rec["value_text"] = value if isinstance(value, str) else None
        rec["value"] = float(value) if isinstance(value, int | float) else None
        rec["raw"] = [w & 0xFFFF for w in rec["raw"] if isinstance(w, int)]
        yield rec


MAKERS: dict[str, Callable[[Describer, Iterable[int], int], Iterator[dict[str, Any]]]] = {
    "frames": frame_rows,
    "transactions": transaction_rows,
    "registers": register_rows,
}


class ParquetTable:
    """The `what` table written to `path` as records come: `add` the rows of one store
    (or of each segment of a capture, numbered `base` on), then `close`. Use as a
    context manager.

    Records are made into Arrow columns `BATCH` at a time and written a row group of
    `row_group` rows at a time: a row group kept as Python lists until it was written
    put the peak of `export -o x.parquet` of issue #29's bus (1M or 3M frames) at 180 MB,
    as Arrow columns 156 MB (84 MB of it pyarrow and the process: a 10-frame export);
    2026-12-06, docs/performance.md."""

    def __init__(self, path: str | Path, what: str, *, row_group: int | None = None) -> None:
        require_pyarrow()
        import pyarrow.parquet as pq

        self.what = what
        self.schema = _schema(what)
        self.row_group = row_group or ROW_GROUP  # (read now: tests set it)
        self.rows = 0  # written so far
        self._lists: dict[str, list[Any]] = {c: [] for c in self.schema.names}
        self._listed = 0  # records in `_lists`
        self._batches: list[Any] = []  # Arrow record batches of the row group being made
        self._batched = 0  # records in `_batches`
        try:
            self._writer = pq.ParquetWriter(str(path), self.schema, compression="zstd")
        except OSError as exc:
            raise ParquetError(
                f"{path}: cannot be written ({exc}); choose a folder you can write to"
            ) from None

    def add(self, describer: Describer, rows: Iterable[int], base: int = 0) -> int:
        """The records of `rows` of `describer`'s store; how many there were."""
        names = self.schema.names
        step = min(BATCH, self.row_group)
        n = 0
        for rec in MAKERS[self.what](describer, rows, base):
            lists = self._lists  # (new ones after each batch)
            for c in names:
                lists[c].append(rec.get(c))
            n += 1
            self._listed += 1
            if self._listed >= step or self._batched + self._listed >= self.row_group:
                self._batch()
        return n

    def _batch(self) -> None:
        import pyarrow as pa

        if self._listed:
            self._batches.append(pa.RecordBatch.from_pydict(self._lists, schema=self.schema))
            self._batched += self._listed
            self._lists = {c: [] for c in self.schema.names}
            self._listed = 0
        if self._batched >= self.row_group:
            self._write()

    def _write(self) -> None:
        import pyarrow as pa

        table = pa.Table.from_batches(self._batches, schema=self.schema)
        self._writer.write_table(table, row_group_size=max(1, self._batched))
        self.rows += self._batched
        self._batches, self._batched = [], 0

    def close(self) -> int:
        """The last row group written (an empty table gets one, for its schema); the
        number of rows."""
        self._batch()
        if self._batched or self.rows == 0:
            self._write()
        self._writer.close()
        return self.rows

    def __enter__(self) -> ParquetTable:
        return self

    def __exit__(self, *exc: object) -> None:
        self._writer.close()


def write_parquet(
    path: str | Path,
    what: str,
    describer: Describer,
    rows: Iterable[int],
    *,
    row_group: int | None = None,
) -> int:
    """Write the `what` table of `rows` to `path` in row groups; the number of rows."""
    with ParquetTable(path, what, row_group=row_group) as table:
        table.add(describer, rows)
        return table.close()

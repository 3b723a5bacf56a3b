"""Provides the Parquet benchmark: pyarrow or DuckDB writing the frames table of 1M frames.

Run: python benchmarks/bench_parquet.py [--frames N]

The capture is the benchmark workload (sniffer.sources.synth's polling stream at 115200 baud,
framed and paired by a Session). Both writers get the same rows, made once by
`sniffer.outputs.parquet.frame_rows` from the store's columns, in row groups of 65,536:

- pyarrow: `pyarrow.parquet.ParquetWriter` (what `modscope export -o X.parquet` uses),
  one `write_table` per row group, zstd;
- DuckDB: the same row groups handed to DuckDB as Arrow tables and appended to a DuckDB
  table, then `COPY ... TO (FORMAT parquet, COMPRESSION zstd)`: DuckDB's own writer.
  (Feeding DuckDB without Arrow means `executemany` of Python tuples, which is far
  slower; measured once with --duckdb-tuples on 100k rows.)

Printed: time to make the rows (shared), each writer's time and file size, and a check
that DuckDB reads the same row count and the same byte total from both files.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.common import LINE, file_reads, peak_rss_mb, workload
from sniffer.outputs.parquet import ROW_GROUP, _schema, frame_rows
from sniffer.session.session import Session


def batches(session: Session, n: int) -> Iterator[dict[str, list[Any]]]:
    names = _schema("frames").names
    batch: dict[str, list[Any]] = {c: [] for c in names}
    count = 0
    for rec in frame_rows(session.describer, range(n)):
        for c in names:
            batch[c].append(rec.get(c))
        count += 1
        if count >= ROW_GROUP:
            yield batch
            batch = {c: [] for c in names}
            count = 0
    if count:
        yield batch


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--duckdb-tuples", action="store_true")
    args = parser.parse_args()
    import duckdb
    import pyarrow as pa
    import pyarrow.parquet as pq

    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, pyarrow {pa.__version__}, duckdb {duckdb.__version__}"
    )
    frames = workload(args.frames)
    session = Session(LINE)
    t = time.perf_counter()
    session.ingest(file_reads(frames))
    session.finish()
    n = len(session.store)
    print(f"framed and paired {n:,} rows in {time.perf_counter() - t:.1f} s")

    schema = _schema("frames")
    t = time.perf_counter()
    tables = [pa.table(b, schema=schema) for b in batches(session, n)]
    made = time.perf_counter() - t
    print(f"rows made (frame_rows -> Arrow row groups): {made:6.2f} s  {n / made:>10,.0f} rows/s")

    with tempfile.TemporaryDirectory() as folder:
        a_path, d_path = Path(folder, "pyarrow.parquet"), Path(folder, "duckdb.parquet")
        t = time.perf_counter()
        with pq.ParquetWriter(str(a_path), schema, compression="zstd") as writer:
            for table in tables:
                writer.write_table(table)
        a = time.perf_counter() - t
        t = time.perf_counter()
        con = duckdb.connect()
        con.register("batch", tables[0])
        con.execute("CREATE TABLE frames AS SELECT * FROM batch")
        for table in tables[1:]:
            con.register("batch", table)
            con.execute("INSERT INTO frames SELECT * FROM batch")
        con.execute(f"COPY frames TO '{d_path}' (FORMAT parquet, COMPRESSION zstd)")
        d = time.perf_counter() - t
        print(
            f"pyarrow ParquetWriter:   {a:6.2f} s  {n / a:>10,.0f} rows/s  "
            f"{a_path.stat().st_size / 1e6:6.1f} MB"
        )
        print(
            f"DuckDB COPY TO parquet:  {d:6.2f} s  {n / d:>10,.0f} rows/s  "
            f"{d_path.stat().st_size / 1e6:6.1f} MB"
        )
        check = duckdb.connect()
        for p in (a_path, d_path):
            rows, size, units = check.execute(
                f"SELECT count(*), sum(length), count(DISTINCT unit) FROM '{p}'"
            ).fetchone() or (0, 0, 0)
            print(f"  {p.name}: {rows:,} rows, {size:,} bytes of frames, {units} units")
        if args.duckdb_tuples:
            k = min(n, 100_000)
            rows_t = [tuple(r.values()) for r in frame_rows(session.describer, range(k))]
            con.execute("CREATE TABLE t2 AS SELECT * FROM frames LIMIT 0")
            t = time.perf_counter()
            marks = ", ".join("?" * len(schema.names))
            con.executemany(f"INSERT INTO t2 VALUES ({marks})", rows_t)
            e = time.perf_counter() - t
            print(f"DuckDB executemany of tuples: {k:,} rows in {e:.2f} s ({k / e:,.0f} rows/s)")
    print(f"peak memory {peak_rss_mb():.0f} MB")


if __name__ == "__main__":
    main()

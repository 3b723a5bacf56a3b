"""Provides parallel listings and exports: the selected rows of an indexed session
written by several worker processes over contiguous ranges, with the serial output's
bytes in the serial output's order.

Once the capture is indexed and the rows to write are chosen, the rows are split into
`jobs` contiguous ranges of about the same size. Workers are forked then (Linux only:
they inherit the session, the annotation and the describer as they are, nothing is
read again); worker k writes range k, exactly what the serial writer writes for those
rows but its header (the CSV header, the pcapng section and interface), to an unnamed
temporary file. Meanwhile the parent writes the header and the first range to the
output itself, then copies each worker's file after it in turn. Nothing a writer keeps
from row to row decides a later row's bytes (the text listing's time origin is the
capture's first time, set before the workers start), so the ranges join up to the
serial output.

A worker prints nothing; the parent alone shows progress, notes and warnings. A worker
that fails or dies makes the command fail (`WorkerError`, a bug: exit status 70) with
its traceback, never a short output. If the parent stops early (an error, Ctrl-C, a
closed pipe under `| head`), it kills the workers that are still running and reaps them;
the temporary files, unnamed, go with their descriptors.
"""

from __future__ import annotations

import argparse
import io
import os
import shutil
import signal
import sys
import tempfile
import traceback
from collections.abc import Callable, Sequence
from typing import IO, BinaryIO, TextIO, TypeVar

MIN_ROWS = 20_000  # fewer rows than this: one process (a fork and a copy cost ~10 ms)
MAX_AUTO = 8  # --jobs auto: at most this many processes
MIN_ROWS_ENV = "MODSCOPE_PARALLEL_MIN_ROWS"  # overrides MIN_ROWS (tests force workers)
COPY_CHUNK = 1 << 20

Out = TypeVar("Out", TextIO, BinaryIO)
# writes rows to a stream; `first`: the stream is the output itself, header and all
RangeWriter = Callable[[Out, Sequence[int], bool], int]


class WorkerError(RuntimeError):
    """A worker process failed or died: the output would be short."""


def parse_jobs(text: str) -> int | None:
    """`--jobs`: a number of processes (1: no workers), or `auto` (None)."""
    if text == "auto":
        return None
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of processes or auto") from None
    if n < 1:
        raise argparse.ArgumentTypeError("give 1 or more processes (1: no workers), or auto")
    return n


def can_fork() -> bool:
    return sys.platform == "linux" and hasattr(os, "fork")


def cpus() -> int:
    if sys.platform == "linux":
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def min_rows() -> int:
    try:
        return max(1, int(os.environ.get(MIN_ROWS_ENV, MIN_ROWS)))
    except ValueError:
        return MIN_ROWS


def workers_for(jobs: int | None, rows: int, out: IO[str] | IO[bytes]) -> int:
    """How many processes write `rows` rows to `out` with `--jobs` `jobs` (None: auto):
    1 for few rows, without fork, and, for auto, to a terminal (a human reading the
    first rows at once) or on one CPU."""
    if not can_fork() or rows < min_rows():
        return 1
    if jobs is None:
        if _isatty(out):
            return 1
        jobs = min(MAX_AUTO, cpus())
    return max(1, min(jobs, rows))


def _isatty(out: IO[str] | IO[bytes]) -> bool:
    try:
        return out.isatty()
    except (AttributeError, ValueError, OSError):
        return False


def split(rows: Sequence[int], n: int) -> list[Sequence[int]]:
    """`rows` in `n` contiguous parts whose sizes differ by one at most (larger first)."""
    size, extra = divmod(len(rows), n)
    parts: list[Sequence[int]] = []
    start = 0
    for k in range(n):
        stop = start + size + (1 if k < extra else 0)
        parts.append(rows[start:stop])
        start = stop
    return parts


class _Worker:
    """One forked process writing one range to an unnamed temporary file."""

    def __init__(self, number: int, of: int, part: Sequence[int]) -> None:
        self.number = number
        self.of = of
        self.part = part
        self.output: BinaryIO = tempfile.TemporaryFile()  # noqa: SIM115 (closed in close())
        self.report: BinaryIO = tempfile.TemporaryFile()  # noqa: SIM115
        self.pid = 0
        self.reaped = False

    def start(self, write: Callable[[BinaryIO, Sequence[int]], int]) -> None:
        pid = os.fork()
        if pid:
            self.pid = pid
            return
        # the worker: never returns into the command, never flushes the parent's streams
        code = 0
        try:
            signal.signal(signal.SIGINT, signal.SIG_DFL)  # Ctrl-C ends it quietly
            n = write(self.output, self.part)
            self.output.flush()
            self.report.write(f"{n}".encode())
        except BaseException:
            self.report.write(traceback.format_exc().encode("utf-8", "replace"))
            code = 70
        finally:
            try:
                self.report.flush()
            finally:
                os._exit(code)

    def what(self) -> str:
        rows = f"rows {self.part[0]}-{self.part[-1]}" if self.part else "no rows"
        return f"the worker writing range {self.number} of {self.of} (pid {self.pid}, {rows})"

    def finish(self) -> int:
        """Wait for the worker; its count of records, or WorkerError."""
        _, status = os.waitpid(self.pid, 0)
        self.reaped = True
        code = os.waitstatus_to_exitcode(status)
        self.report.seek(0)
        said = self.report.read().decode("utf-8", "replace")
        if code == 0 and said.isdigit():
            self.output.seek(0)
            return int(said)
        how = f"was killed by signal {-code}" if code < 0 else f"failed (exit status {code})"
        detail = f":\n{said.rstrip()}" if said and not said.isdigit() else ""
        raise WorkerError(f"{self.what()} {how}; the output is incomplete{detail}")

    def close(self) -> None:
        if self.pid and not self.reaped:
            try:
                os.kill(self.pid, signal.SIGKILL)
                os.waitpid(self.pid, 0)
            except (ProcessLookupError, ChildProcessError):
                pass
            self.reaped = True
        self.output.close()
        self.report.close()


def write_ranges(
    rows: Sequence[int],
    jobs: int,
    first: Callable[[Sequence[int]], int],
    worker: Callable[[BinaryIO, Sequence[int]], int],
    append: Callable[[BinaryIO], None],
) -> int:
    """`rows` in `jobs` ranges: the first written by `first` in this process, each other
    by `worker` (range, temporary file) in a forked process, and `append`ed (the file,
    at its start) in order after the first. Returns the sum of the counts."""
    parts = split(rows, jobs)
    workers = [_Worker(k + 1, jobs, part) for k, part in enumerate(parts) if k]
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        for w in workers:
            w.start(worker)
        n = first(parts[0])
        for w in workers:
            n += w.finish()
            append(w.output)
            w.close()
        return n
    finally:
        for w in workers:
            w.close()


def write_text(out: TextIO, rows: Sequence[int], jobs: int, write: RangeWriter[TextIO]) -> int:
    """`write(stream, rows, first)` over `rows` to the text stream `out`, by `jobs`
    processes; workers encode as `out` does."""
    if jobs <= 1 or len(rows) < 2:
        return write(out, rows, True)
    encoding = getattr(out, "encoding", None) or "utf-8"
    errors = getattr(out, "errors", None) or "strict"

    def worker(sink: BinaryIO, part: Sequence[int]) -> int:
        text = io.TextIOWrapper(sink, encoding=encoding, errors=errors, newline="")
        n = write(text, part, False)
        text.flush()
        text.detach()
        return n

    def append(src: BinaryIO) -> None:
        out.flush()
        buffer = getattr(out, "buffer", None)
        if buffer is not None:
            shutil.copyfileobj(src, buffer, COPY_CHUNK)
            buffer.flush()
            return
        while chunk := src.read(COPY_CHUNK):  # a stream with no bytes under it
            out.write(chunk.decode(encoding, errors))

    return write_ranges(rows, jobs, lambda part: write(out, part, True), worker, append)


def write_binary(
    out: BinaryIO, rows: Sequence[int], jobs: int, write: RangeWriter[BinaryIO]
) -> int:
    """`write(stream, rows, first)` over `rows` to the binary stream `out`, by `jobs`
    processes."""
    if jobs <= 1 or len(rows) < 2:
        return write(out, rows, True)

    def append(src: BinaryIO) -> None:
        out.flush()
        shutil.copyfileobj(src, out, COPY_CHUNK)
        out.flush()

    def worker(sink: BinaryIO, part: Sequence[int]) -> int:
        return write(sink, part, False)

    return write_ranges(rows, jobs, lambda part: write(out, part, True), worker, append)

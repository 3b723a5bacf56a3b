"""Provides the recorder: what the ports read, as read, in pcapng with link type 250 (RTAC serial).

Each port is an interface named after it, with the line settings in its description
(`modscope 19200 8E1 rtu`, plus `master`/`slave` when the port carries one direction),
so `modscope replay` reads the file back with its settings and frames it as live did.

One enhanced packet block per read: the packet time is when the read returned (the
chunk's `t_end`), the RTAC header time the framer's own estimate of when the first byte
began (one character time per byte earlier, never before the previous read), the event
type RX start, the flags inbound. Events become RTAC records without data: "data lost",
"port lost" and "reconnect" as capture-data-lost, line errors as framing error, parity
error or break; the packet comment says what happened. Closing a file ends each
interface with a capture-complete record at the closing time. Every block is flushed as
it is written, so a killed process loses at most the block being written.

Ring buffer: with a size or time limit the recording goes to numbered files
`NAME_00001_20250101120000.pcapng` (Wireshark's style), each complete in itself; with
`keep` only the newest files stay.

A full disk (ENOSPC), or the file size limit (EFBIG, `ulimit -f`), never leaves half a
block: each block is written whole or the file is cut back to where it began, so the
file stays readable to its last whole block. A ring buffer then frees its oldest file and
writes the block again; otherwise the recording stops with one line naming the file and
saying the disk is full (`RecordError`), and the rest of the program goes on to close
cleanly. A pipe whose reader went away (`record -w - | head`) is said to be that, not a
disk.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, TypeVar, cast

from sniffer import __version__
from sniffer.errors import UserError
from sniffer.live.port import PortSpec
from sniffer.model import Chunk
from sniffer.sources.linktypes import RTAC_CAPTURE_COMPLETE
from sniffer.sources.pcapng_writer import (
    EPB_FLAG_INBOUND,
    LINKTYPE_RTAC_SERIAL,
    RTAC_CAPTURE_DATA_LOST,
    RTAC_DATA_RX_START,
    RTAC_FRAMING_ERROR,
    RTAC_PARITY_ERROR,
    RTAC_SERIAL_BREAK,
    PcapngWriter,
    describe_interface,
    rtac_record,
)

_T = TypeVar("_T")

EVENT_TYPES = {
    "framing error": RTAC_FRAMING_ERROR,
    "parity error": RTAC_PARITY_ERROR,
    "break": RTAC_SERIAL_BREAK,
}
_SIZE = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*([kmgt]?)(i?)b?\s*$", re.IGNORECASE)
_DURATION = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*(s|sec|m|min|h|d)?\s*$", re.IGNORECASE)
_POWERS = {"": 0, "k": 1, "m": 2, "g": 3, "t": 4}
_SECONDS = {None: 1, "s": 1, "sec": 1, "m": 60, "min": 60, "h": 3600, "d": 86400}


def epb_size(data: int, comment: int = 0) -> int:
    """Bytes of an enhanced packet block with `data` bytes, the flags option and a
    comment of `comment` bytes (if any)."""
    options = 8 + (4 + comment + (-comment % 4) if comment else 0) + 4
    return 12 + 20 + data + (-data % 4) + options


class RecordError(UserError):
    """The recording cannot be written. The message names the file and what to do."""


FULL = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)  # no room: a ring may free its oldest file


class WholeBlocks:
    """A file written in whole blocks: `write` writes all of its bytes or, failing, cuts
    the file back to where the block began and raises (see the module doc). Unbuffered,
    so nothing is left to flush at close."""

    def __init__(self, raw: BinaryIO) -> None:
        self.raw = raw
        self.good = raw.tell()  # the end of the last whole block

    def write(self, data: bytes) -> int:
        view = memoryview(data)
        done = 0
        try:
            while done < len(view):
                n = self.raw.write(view[done:])
                if not n:  # a full disk may take part of a block, then nothing
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
                done += n
        except OSError:
            with contextlib.suppress(OSError, ValueError):
                self.raw.seek(self.good)
                self.raw.truncate(self.good)
            raise
        self.good += done
        return done

    def flush(self) -> None:
        """Every write went to the file already."""

    def tell(self) -> int:
        return self.good

    def close(self) -> None:
        self.raw.close()


def open_blocks(path: Path) -> BinaryIO:
    """`path` opened for writing in whole blocks (the recorder's file)."""
    return cast("BinaryIO", WholeBlocks(path.open("wb", buffering=0)))


def write_failure(path: str | Path, exc: OSError, packets: int) -> str:
    """The one line that says why writing `path` stopped, and what to do."""
    if exc.errno == errno.EPIPE:
        return (
            f"{path}: the program reading the recording closed the pipe; the recording "
            f"stopped after {packets:,} packets"
        )
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return (
            f"{path}: the disk is full; the recording stopped after {packets:,} packets and "
            "the file ends on its last whole block; free space (or record with a ring "
            "buffer, --rotate-size and --keep) and record again"
        )
    if exc.errno == errno.EFBIG:
        return (
            f"{path}: the file reached the size limit of this process or file system "
            f"(ulimit -f); the recording stopped after {packets:,} packets, the file ends on "
            "its last whole block; record with a ring buffer (--rotate-size)"
        )
    reason = exc.strerror or str(exc)
    return f"{path}: writing failed ({reason}); check the free space on its disk"


MIN_RING_FILE = 1000  # bytes: `1k`, the smallest ring buffer file the help promises


def parse_size(text: str, minimum: int = MIN_RING_FILE) -> int:
    """`10M` -> 10,000,000 bytes; `10MiB` -> 10,485,760; `500k`; a plain number is bytes.
    Sizes are decimal (k = 1000) unless written with `i` (KiB = 1024), so the smallest
    ring buffer file, `1k`, is 1000 bytes."""
    m = _SIZE.match(text)
    if not m:
        raise ValueError(f"not a size: {text!r} (write e.g. 500k, 10M, 1G)")
    base = 1024 if m[3] else 1000
    size = int(float(m[1]) * base ** _POWERS[m[2].lower()])
    if size < minimum:
        least = "1k (1,000 bytes)" if minimum == MIN_RING_FILE else f"{minimum:,} bytes"
        raise ValueError(f"needs at least {least}, not {text!r}")
    return size


def parse_duration(text: str) -> float:
    """`30s`, `15m`, `1h`, `1d`; a plain number is seconds."""
    m = _DURATION.match(text)
    if not m:
        raise ValueError(f"not a duration: {text!r} (write e.g. 30s, 15m, 1h)")
    seconds = float(m[1]) * _SECONDS[m[2].lower() if m[2] else None]
    if seconds <= 0:
        raise ValueError(f"a duration must be positive, not {text!r}")
    return seconds


@dataclass(frozen=True, slots=True)
class Ring:
    """Ring buffer limits: start a new file past `size` bytes or `seconds`; keep `keep`."""

    size: int | None = None
    seconds: float | None = None
    keep: int | None = None

    @property
    def active(self) -> bool:
        return self.size is not None or self.seconds is not None


class Recorder:
    """Writes chunks of `ports` (their `channel` is the interface id) to `path`."""

    def __init__(
        self,
        path: str | Path,
        ports: Sequence[PortSpec],
        *,
        ring: Ring | None = None,
        stream: BinaryIO | None = None,
        opener: Callable[[Path], BinaryIO] = open_blocks,
    ) -> None:
        self.path = Path(path)
        self.ports = sorted(ports, key=lambda p: p.channel)
        self.ring = ring or Ring()
        if self.ring.keep is not None and self.ring.keep < 1:
            raise RecordError(f"--keep must be at least 1, not {self.ring.keep}")
        if self.ring.keep is not None and not self.ring.active:
            raise RecordError("--keep needs --rotate-size or --rotate-time (a ring buffer)")
        if stream is not None and self.ring.active:
            raise RecordError("a recording to a stream cannot rotate; write to a file")
        self.files: list[Path] = []  # files of this recording still on disk
        self.freed: list[Path] = []  # ring files deleted early because the disk was full
        self.stopped: str | None = None  # why writing stopped (a full disk), once it has
        self.packets = 0
        self.bytes = 0  # bus bytes recorded
        self._stream = stream
        self._opener = opener
        self._handle: BinaryIO | None = None
        self._writer: PcapngWriter | None = None
        self._interfaces: dict[int, int] = {}
        self._file_t0 = 0.0
        self._number = 0
        self._last_end: dict[int, float] = {}
        self._open_next(None)

    # -- files -----------------------------------------------------------------------------

    def _name(self, t: float | None) -> Path:
        if not self.ring.active:
            return self.path
        self._number += 1
        stamp = time.strftime("%Y%m%d%H%M%S", time.localtime(t if t is not None else time.time()))
        suffix = self.path.suffix or ".pcapng"
        return self.path.with_name(f"{self.path.stem}_{self._number:05d}_{stamp}{suffix}")

    def _open_next(self, t: float | None) -> None:
        self._close_file(t)
        if self._stream is not None:
            handle = self._stream
        else:
            path = self._name(t)
            try:
                handle = self._opener(path)
            except OSError as exc:
                reason = exc.strerror or str(exc)
                raise RecordError(
                    f"{path}: cannot be written ({reason}); choose a folder you can write to"
                ) from None
            self.files.append(path)
            self._prune()
        self._handle = handle
        self._interfaces = {}
        self._writer = None
        writer = self._retrying(lambda: PcapngWriter(handle, application=f"modscope {__version__}"))
        for spec in self.ports:
            self._interfaces[spec.channel] = self._retrying(
                lambda spec=spec: writer.add_interface(  # type: ignore[misc]
                    LINKTYPE_RTAC_SERIAL,
                    name=spec.name,
                    description=describe_interface(spec.line, spec.direction),
                )
            )
        self._writer = writer
        self._file_t0 = t if t is not None else time.time()
        self._file_bytes = handle.tell() if self._stream is None else 0

    def _retrying(self, write: Callable[[], _T]) -> _T:
        """Run `write` (one block); on a full disk a ring frees its oldest file and runs it
        again, until no older file is left. RecordError (one line) when writing stops."""
        while True:
            try:
                return write()
            except OSError as exc:
                if exc.errno in FULL and self._stream is None and len(self.files) > 1:
                    old = self.files.pop(0)
                    with contextlib.suppress(FileNotFoundError):
                        old.unlink()
                    self.freed.append(old)
                    continue
                self.stopped = write_failure(
                    self.files[-1] if self.files and self._stream is None else self.path,
                    exc,
                    self.packets,
                )
                raise RecordError(self.stopped) from None

    def _prune(self) -> None:
        keep = self.ring.keep
        while keep is not None and len(self.files) > keep:
            old = self.files.pop(0)
            with contextlib.suppress(FileNotFoundError):
                old.unlink()

    def _close_file(self, t: float | None = None) -> None:
        if self._writer is not None and self.stopped is None:
            # "capture complete" on every interface: the file shows how long it listened
            end = max(t if t is not None else time.time(), 0.0)
            with contextlib.suppress(OSError, ValueError):
                for interface in self._interfaces.values():
                    packet = rtac_record(end, b"", event=RTAC_CAPTURE_COMPLETE)
                    self._writer.write_packet(interface, end, packet, flags=EPB_FLAG_INBOUND)
        if self._handle is not None and self._stream is None:
            with contextlib.suppress(OSError):  # whole blocks: nothing is left to write
                self._handle.close()
        self._handle = None
        self._writer = None

    def close(self, t: float | None = None) -> None:
        """End the recording (at Unix time `t`, default now)."""
        self._close_file(t)

    @property
    def file_size(self) -> int:
        """Bytes in the current file (what the ring buffer's size limit looks at)."""
        return self._file_bytes

    # -- writing ---------------------------------------------------------------------------

    def _due(self, t: float) -> bool:
        ring = self.ring
        if ring.seconds is not None and t - self._file_t0 >= ring.seconds:
            return True
        return ring.size is not None and self._file_bytes >= ring.size

    def write(self, chunk: Chunk) -> None:
        if self.stopped is not None:
            raise RecordError(self.stopped)
        if self._writer is None:
            raise RecordError(f"{self.path}: the recording is closed")
        if self.ring.active and self._due(chunk.t_end):
            self._open_next(chunk.t_end)
        assert self._writer is not None
        interface = self._interfaces.get(chunk.channel)
        if interface is None:
            return  # not one of our ports
        t = max(chunk.t_end, 0.0)
        if chunk.data:
            self._retrying(lambda: self._data(interface, chunk, t))
        if chunk.event:
            self._retrying(lambda: self._event(interface, chunk, t))

    def _data(self, interface: int, chunk: Chunk, t: float) -> None:
        assert self._writer is not None
        line = next((p.line for p in self.ports if p.channel == chunk.channel), None)
        char = line.char_time if line is not None else 0.0
        start = t - len(chunk.data) * char
        last = self._last_end.get(chunk.channel)
        if last is not None and start < last:
            start = last
        start = max(min(start, t), 0.0)
        packet = rtac_record(start, chunk.data, event=RTAC_DATA_RX_START)
        self._writer.write_packet(interface, t, packet, flags=EPB_FLAG_INBOUND)
        self._last_end[chunk.channel] = t
        self.packets += 1
        self.bytes += len(chunk.data)
        self._file_bytes += epb_size(len(packet))

    def _event(self, interface: int, chunk: Chunk, t: float) -> None:
        assert self._writer is not None
        kind = EVENT_TYPES.get(chunk.event, RTAC_CAPTURE_DATA_LOST)
        comment = chunk.event + (f": {chunk.note}" if chunk.note else "")
        packet = rtac_record(t, b"", event=kind)
        self._writer.write_packet(interface, t, packet, flags=EPB_FLAG_INBOUND, comment=comment)
        self.packets += 1
        self._file_bytes += epb_size(len(packet), len(comment.encode("utf-8")))


def stdout_binary() -> BinaryIO:
    """Standard output for binary data (pcapng to a pipe)."""
    return sys.stdout.buffer

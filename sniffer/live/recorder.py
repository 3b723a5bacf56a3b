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

A full disk (ENOSPC, EDQUOT), or the file size limit (EFBIG, `ulimit -f`), never leaves
half a block: each block is written whole or the file is cut back to where it began
(`WholeBlocks`), and a file's header (section and interfaces) goes in as one write. A
ring buffer then frees its oldest file and writes the block again; otherwise the
recording stops (`RecordError`, one line naming the file and the free space or the size
limit, `Recorder.status` 1) and the file ends with its last words: on each interface a
capture-data-lost record whose comment says "recording stopped: the disk is full (0
bytes free)", then capture-complete. Room for them is held from the start: a hidden
reserve file next to the recording (`Reserve`, released when the disk fills or the
recording closes; one left by a killed recorder is removed by the next recording in
that folder), and under a file size limit the last bytes below it. The rest of the
program goes on. A pipe whose reader went away (`record -w - | head`) is said to be
that, not a disk, and is not a failure (status 0, as `live | head`).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import re
import resource
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, NoReturn, TypeVar, cast

from sniffer import __version__
from sniffer.errors import UserError
from sniffer.live.port import PortSpec
from sniffer.model import Chunk
from sniffer.session.index import sweep_unlocked
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


FULL = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)  # no room: the recording ends with its last words
STOP_WORDS = {  # what each of them is called in the one line and the last words
    errno.ENOSPC: "the disk is full",
    errno.EDQUOT: "the disk quota is used up",
    errno.EFBIG: "the file reached the size limit",
}
RESERVE_SUFFIX = ".modscope-reserve"  # the hidden file that holds a recording's last room
RESERVE_LEAST = 4096  # bytes: one block of most file systems
COMMENT_MOST = 200  # bytes of the last words' comment (the room is counted for this many)


def size_words(n: int) -> str:
    """`0 bytes`, `812 bytes`, `12 kB`, `3.4 MB`: decimal units, as `parse_size` reads them."""
    if n < 1000:
        return "1 byte" if n == 1 else f"{n:,} bytes"
    units = ("kB", "MB", "GB", "TB", "PB")
    for k, unit in enumerate(units, 1):
        value = n / 1000**k
        if value >= 999.5 and unit != units[-1]:
            continue
        return f"{value:.1f} {unit}" if value < 9.95 else f"{value:.0f} {unit}"
    raise AssertionError("unreachable")


def mount_point(path: Path) -> Path:
    """The folder where the file system that holds `path` (a file or folder) is mounted."""
    folder = path if path.is_dir() else path.parent
    folder = folder.resolve()
    device = folder.stat().st_dev
    while folder.parent != folder and folder.parent.stat().st_dev == device:
        folder = folder.parent
    return folder


def free_space(path: Path) -> tuple[int, Path] | None:
    """Bytes free to this user on the file system that holds `path` (statvfs: f_bavail x
    f_frsize) and where it is mounted; None if it cannot be asked."""
    folder = path if path.is_dir() else path.parent
    try:
        st = os.statvfs(folder)
        return st.f_bavail * st.f_frsize, mount_point(folder)
    except OSError:
        return None


def size_limit() -> int | None:
    """The file size limit of this process (`ulimit -f`, RLIMIT_FSIZE) in bytes, if any."""
    soft, _hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    return None if soft == resource.RLIM_INFINITY else soft


class WholeBlocks:
    """A file written in whole blocks: `write` writes all of its bytes or, failing, cuts
    the file back to where the block began and raises (see the module doc). Unbuffered,
    so nothing is left to flush at close.

    Under a file size limit (`ulimit -f`) it keeps the last `held` bytes below the limit
    for the recording's last words: a block that would reach into them fails with EFBIG
    as the limit itself would, until `held` is set back to 0."""

    def __init__(self, raw: BinaryIO, limit: int | None = None) -> None:
        self.raw = raw
        self.good = raw.tell()  # the end of the last whole block
        self.limit = limit  # the file size limit, if any
        self.held = 0  # bytes below the limit kept for the last words

    def write(self, data: bytes) -> int:
        if self.limit is not None and self.good + len(data) > self.limit - self.held:
            raise OSError(errno.EFBIG, os.strerror(errno.EFBIG))
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
    """`path` opened for writing in whole blocks (the recorder's file), under this
    process's file size limit."""
    return cast("BinaryIO", WholeBlocks(path.open("wb", buffering=0), size_limit()))


class Reserve:
    """Room held on a recording's file system for its last words: a hidden file of
    `size` bytes allocated next to the recording, locked while it is held, so that a
    recording stopped by a full disk can still say why. `release` frees the room.

    A killed recorder leaves its reserve behind; the next reserve made in that folder
    removes every one whose lock is free (its recorder is gone)."""

    def __init__(self, recording: Path, size: int) -> None:
        folder = recording.parent
        sweep_reserves(folder)
        fd, name = tempfile.mkstemp(prefix=f".{recording.name}.", suffix=RESERVE_SUFFIX, dir=folder)
        self.path: Path | None = Path(name)
        self._fd: int | None = fd
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # ours while we live
            try:
                os.posix_fallocate(fd, 0, size)
            except OSError as exc:
                if exc.errno in FULL:
                    raise
                _write_zeros(fd, size)  # a file system without fallocate
        except BaseException:
            self.release()
            raise

    def release(self) -> None:
        """Give the room back (the file goes; its blocks are free once it is closed)."""
        path, fd = self.path, self._fd
        self.path, self._fd = None, None
        if path is not None:
            with contextlib.suppress(OSError):
                path.unlink()
        if fd is not None:
            with contextlib.suppress(OSError):
                os.close(fd)

    @property
    def held(self) -> bool:
        return self._fd is not None


def _write_zeros(fd: int, size: int) -> None:
    zeros = bytes(min(size, 65536))
    done = 0
    while done < size:
        done += os.write(fd, zeros[: size - done])


def sweep_reserves(folder: Path) -> int:
    """Remove the reserves of recorders that died (their lock is free); how many."""
    return sweep_unlocked(folder, f".*{RESERVE_SUFFIX}")


def write_failure(path: str | Path, exc: OSError, packets: int, room: str = "") -> str:
    """The one line that says why writing `path` stopped, and what to do; `room` is what
    `room_words` said of the free space or the size limit."""
    room = f" ({room})" if room else ""
    if exc.errno == errno.EPIPE:
        return (
            f"{path}: the program reading the recording closed the pipe; the recording "
            f"stopped after {packets:,} packets"
        )
    if exc.errno == errno.ENOSPC:
        return (
            f"{path}: the disk is full{room}; the recording stopped after {packets:,} packets "
            "and the file ends with a record saying so; free space (or record with a ring "
            "buffer, --rotate-size and --keep) and record again"
        )
    if exc.errno == errno.EDQUOT:
        return (
            f"{path}: the disk quota is used up{room}; the recording stopped after "
            f"{packets:,} packets and the file ends with a record saying so; free space "
            "under your quota (or record with a ring buffer, --rotate-size and --keep) and "
            "record again"
        )
    if exc.errno == errno.EFBIG:
        return (
            f"{path}: the file reached the size limit{room} (ulimit -f, or the largest file "
            f"its file system takes); the recording stopped after {packets:,} packets and the "
            "file ends with a record saying so; record with a ring buffer (--rotate-size) "
            "under that size"
        )
    reason = exc.strerror or str(exc)
    return f"{path}: writing failed ({reason}); check the free space on its disk"


def room_words(exc: OSError, path: Path, size: int, limit: int | None) -> tuple[str, str]:
    """What a stop says of the room, and where: the free space on the file system that
    holds `path` and its mount point (`0 bytes free`, `/mnt/x`), or for EFBIG the size
    limit the file of `size` bytes reached (`limit`, the file's own, else this process's),
    and no place."""
    if exc.errno == errno.EFBIG:
        limit = limit if limit is not None else size_limit()
        if limit is not None:
            return f"{limit:,} bytes", ""
        return f"the largest file its file system takes, at {size_words(size)}", ""
    free = free_space(path)
    if free is None:
        return "", ""
    what = "free on the file system" if exc.errno == errno.EDQUOT else "free"
    return f"{size_words(free[0])} {what}", str(free[1])


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


def _on(what: str, where: str) -> str:
    return f"{what} on {where}" if what and where else what


class _Staged:
    """Where a file's header is built: its blocks are held until `commit` writes them to
    the file in one write (whole or not at all); then `write` and `flush` are the file's
    own (no extra call per block)."""

    def __init__(self) -> None:
        self.held = bytearray()
        self.write: Callable[[bytes], int] = self._hold
        self.flush: Callable[[], None] = self._nothing

    def _hold(self, data: bytes) -> int:
        self.held += data
        return len(data)

    def _nothing(self) -> None:
        pass

    def commit(self, target: BinaryIO) -> None:
        target.write(bytes(self.held))
        target.flush()
        self.write, self.flush = target.write, target.flush


class Recorder:
    """Writes chunks of `ports` (their `channel` is the interface id) to `path`."""

    def __init__(
        self,
        path: str | Path,
        ports: Sequence[PortSpec],
        *,
        ring: Ring | None = None,
        stream: BinaryIO | None = None,
        opener: Callable[[Path], BinaryIO] | None = None,
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
        self.status = 0  # the exit status the stop asks for: 1 unless none or a closed pipe
        self.packets = 0
        self.bytes = 0  # bus bytes recorded
        self._stream = stream
        self._opener = opener or open_blocks
        self._handle: BinaryIO | None = None
        self._writer: PcapngWriter | None = None
        self._interfaces: dict[int, int] = {}
        self._staged: tuple[_Staged, PcapngWriter, dict[int, int]] | None = None
        self._file_t0 = 0.0
        self._number = 0
        self._last_end: dict[int, float] = {}
        self._now: float | None = None  # the time of the last block tried: the last words' date
        # the last words: on each interface a capture-data-lost record with its comment,
        # then capture-complete; held back under a size limit, and in the reserve
        record = len(rtac_record(0.0, b""))
        self._last_words = len(self.ports) * (epb_size(record, COMMENT_MOST) + epb_size(record))
        self._reserve: Reserve | None = None
        if stream is None:
            self._reserve = self._reserve_room()
        try:
            self._open_next(None)
        except BaseException:
            self._close_file()
            self._release()
            raise

    # -- files -----------------------------------------------------------------------------

    def _reserve_room(self) -> Reserve | None:
        """The reserve for the last words (and a file's header, should the disk fill as a
        ring buffer starts its next file); None where the folder takes no such file (the
        recording's own file then says what is wrong)."""
        header = len(self._header()[0].held)
        size = max(RESERVE_LEAST, -(-(header + self._last_words) // RESERVE_LEAST) * RESERVE_LEAST)
        try:
            return Reserve(self.path, size)
        except OSError as exc:
            if exc.errno not in FULL:
                return None
            room = _on(*room_words(exc, self.path, 0, None))
            raise RecordError(
                f"{self.path}: no room to start a recording: {STOP_WORDS[exc.errno]}"
                + (f" ({room})" if room else "")
                + "; nothing recorded; free space and record again"
            ) from None

    def _release(self) -> None:
        if self._reserve is not None:
            self._reserve.release()
        if isinstance(self._handle, WholeBlocks):
            self._handle.held = 0

    def _name(self, t: float | None) -> Path:
        if not self.ring.active:
            return self.path
        self._number += 1
        stamp = time.strftime("%Y%m%d%H%M%S", time.localtime(t if t is not None else time.time()))
        suffix = self.path.suffix or ".pcapng"
        return self.path.with_name(f"{self.path.stem}_{self._number:05d}_{stamp}{suffix}")

    def _header(self) -> tuple[_Staged, PcapngWriter, dict[int, int]]:
        """A file's section and interface blocks, built but not written."""
        staged = _Staged()
        writer = PcapngWriter(cast("BinaryIO", staged), application=f"modscope {__version__}")
        interfaces = {
            spec.channel: writer.add_interface(
                LINKTYPE_RTAC_SERIAL,
                name=spec.name,
                description=describe_interface(spec.line, spec.direction),
            )
            for spec in self.ports
        }
        return staged, writer, interfaces

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
            if isinstance(handle, WholeBlocks) and self._reserve is not None:
                handle.held = self._last_words
            self.files.append(path)
            self._prune()
        self._handle = handle
        self._interfaces = {}
        self._writer = None
        self._staged = self._header()
        self._retrying(self._commit_header)
        self._file_t0 = t if t is not None else time.time()
        self._file_bytes = handle.tell() if self._stream is None else 0

    def _commit_header(self) -> None:
        """The header in one write (whole or not at all); then the file takes packets."""
        assert self._staged is not None and self._handle is not None
        staged, writer, interfaces = self._staged
        staged.commit(self._handle)
        self._staged = None
        self._writer, self._interfaces = writer, interfaces

    def _retrying(self, write: Callable[[], _T]) -> _T:
        """Run `write` (one block); on a full disk a ring frees its oldest file and runs it
        again, until no older file is left. RecordError (one line) when writing stops."""
        while True:
            try:
                return write()
            except OSError as exc:
                if (
                    exc.errno in (errno.ENOSPC, errno.EDQUOT)
                    and self._stream is None
                    and len(self.files) > 1
                ):
                    old = self.files.pop(0)
                    with contextlib.suppress(FileNotFoundError):
                        old.unlink()
                    self.freed.append(old)
                    continue
                self._stop(exc)

    def _stop(self, exc: OSError) -> NoReturn:
        """Writing failed for good: the one line, and on a full disk the file's last words
        (in the room held for them)."""
        path = self.files[-1] if self.files and self._stream is None else self.path
        handle = self._handle if self._stream is None else None
        size = handle.tell() if handle is not None else 0
        limit = handle.limit if isinstance(handle, WholeBlocks) else None
        what, where = room_words(exc, path, size, limit) if exc.errno in FULL else ("", "")
        self.stopped = write_failure(path, exc, self.packets, _on(what, where))
        self.status = 0 if exc.errno == errno.EPIPE else 1
        if exc.errno in FULL:
            self._say_last_words(exc, what)
        raise RecordError(self.stopped) from None

    def _say_last_words(self, exc: OSError, room: str) -> None:
        """On each interface a capture-data-lost record saying why the recording stopped
        (`room`: the free space or the limit), then capture-complete, written in the room
        held for them."""
        self._release()
        why = STOP_WORDS[exc.errno or errno.ENOSPC]
        comment = f"recording stopped: {why}" + (f" ({room})" if room else "")
        comment = comment.encode("utf-8")[:COMMENT_MOST].decode("utf-8", "ignore")
        with contextlib.suppress(OSError, ValueError):
            if self._writer is None and self._staged is not None:
                self._commit_header()  # the disk filled as a new file began
            writer = self._writer
            if writer is None:
                return
            # the time of the block that did not fit (now, if none came yet)
            t = max(self._now if self._now is not None else time.time(), 0.0)
            for interface in self._interfaces.values():
                lost = rtac_record(t, b"", event=RTAC_CAPTURE_DATA_LOST)
                writer.write_packet(interface, t, lost, flags=EPB_FLAG_INBOUND, comment=comment)
            for interface in self._interfaces.values():
                done = rtac_record(t, b"", event=RTAC_CAPTURE_COMPLETE)
                writer.write_packet(interface, t, done, flags=EPB_FLAG_INBOUND)

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
        """End the recording (at Unix time `t`, default now) and give back its reserve."""
        self._close_file(t)
        self._release()

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
        self._now = chunk.t_end  # the block being written: if it does not fit, the stop's time
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

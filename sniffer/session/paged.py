"""Provides `PagedStore`: a capture's rows for the TUI, most of them left in the sidecar.

A day's capture is some 30 million rows. Kept whole in memory (`FrameStore`) they take
about 65 bytes each, 2 GB. The TUI's views scan only a few narrow columns over every
row (kind, unit, function, flags, channel, partner, status: 13 bytes a row, 390 MB for
the day); the rest (offsets, lengths, times, and the bytes themselves) they need only for
the rows on screen or in the detail pane. So `PagedStore` keeps those narrow columns in
memory and reads the others from the sidecar index (`sniffer.session.index`) when a row
is looked at: a block's column unpacked whole (a block's times are some 120 KB packed), a
piece of its bytes (at most `index.PIECE`) from the capture, with a small cache.

It fills as a windowed `Session.ingest` goes (a segment at a time, `take`): each
segment's rows are in the sidecar being written by then; or, while a sidecar is read
back, a block at a time (`attach`, then `reach`). Rows a sidecar could not take (a
folder that filled up) stay in memory, a block each (`take` with no writer).

Rows are numbered in the whole capture, as in a store holding every row, and every
column reads as it would there: `raw`, `view` and the columns give the same values
(tests/session/test_paged.py holds it to that). Only the TUI uses it, for captures that get a
sidecar (`wanted`); it is filled by one thread and read by others: rows below `len()`
are complete.
"""

from __future__ import annotations

import contextlib
import os
import struct
import threading
import zlib
from array import array
from bisect import bisect_right
from collections import OrderedDict
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from sniffer.framing.store import COLUMNS, FrameStore
from sniffer.model import Stamp
from sniffer.session.index import Packed, channel_texts, shifted_partners

if TYPE_CHECKING:
    from sniffer.session.index import Writer
    from sniffer.session.session import Session

_T = TypeVar("_T", bytes, "array[Any]", Packed)

# in memory for every row: what the filters, the transactions and problems views, the
# ladder's pairing and the units pane scan
HOT: tuple[str, ...] = ("kind", "unit", "fc", "flags", "channel", "partner", "status")
# read from the sidecar for the rows looked at
COLD: tuple[str, ...] = ("offset", "length", "t", "t_end")
# bytes of pages kept
CACHE_BYTES = 32 << 20

_TYPECODES = {name: getattr(FrameStore(), name).typecode for name in COLUMNS}
_SIZES = {name: array(code).itemsize for name, code in _TYPECODES.items()}


def wanted(session: Session, live: bool, speed: float | None) -> bool:
    """Whether the TUI should page a capture's rows: a capture file read as fast as it
    can be (not a live line, not at its own speed) that gets a sidecar index."""
    return not live and speed is None and session.indexing


class _Block:
    """Where one block's rows are: in a file (`fd`, `pos`) or in memory (`columns`, the
    cold columns, and `pieces`, each channel's bytes)."""

    __slots__ = ("columns", "count", "fd", "kept", "pieces", "pos", "size", "start")

    def __init__(
        self,
        start: int,
        count: int,
        fd: int,
        pos: int,
        pieces: list[tuple[int, int, int]],
        columns: dict[str, array[Any]] | None = None,
        kept: dict[int, bytes] | None = None,
        size: int = 0,
    ) -> None:
        self.start, self.count, self.fd, self.pos, self.size = start, count, fd, pos, size
        # (channel, its bytes' first offset in the whole capture, size)
        self.pieces = pieces
        self.columns = columns
        self.kept = kept


class PagedColumn:
    """One cold column of a `PagedStore`: indexed and sliced as the store's array would
    be (rows numbered in the whole capture), read a block at a time."""

    def __init__(self, store: PagedStore, name: str) -> None:
        self.store = store
        self.name = name
        self.typecode = _TYPECODES[name]
        self.itemsize = _SIZES[name]

    def __len__(self) -> int:
        return len(self.store)

    def __getitem__(self, key: Any) -> Any:
        n = len(self.store)
        if isinstance(key, slice):
            lo, hi, step = key.indices(n)
            out = array(self.typecode)
            store = self.store
            at = lo
            while at < hi:
                block = store.block_of(at)
                values, first = store.column(block, self.name, at - block.start)
                end = min(hi - block.start, first + len(values))
                out.extend(values[at - block.start - first : end - first])
                at = block.start + end
            return out if step == 1 else out[::step]
        i = key.__index__()
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError("row out of range")
        block = self.store.block_of(i)
        values, first = self.store.column(block, self.name, i - block.start)
        return values[i - block.start - first]


class PagedStream:
    """One channel's bytes in a `PagedStore`: sliced with offsets in the whole capture."""

    def __init__(self, store: PagedStore, channel: int) -> None:
        self.store = store
        self.channel = channel
        self.starts: list[int] = []  # each piece's first offset
        self.where: list[tuple[_Block, int]] = []  # each piece's block and size
        self.size = 0

    def __len__(self) -> int:
        return self.size

    def add(self, block: _Block, start: int, size: int) -> None:
        # (in this order: a reader in another thread that finds a start finds its piece)
        self.where.append((block, size))
        self.starts.append(start)
        self.size = start + size

    def __getitem__(self, key: slice) -> bytes:
        lo, hi, _step = key.indices(self.size)
        out = []
        k = bisect_right(self.starts, lo) - 1
        while lo < hi and 0 <= k < len(self.starts):
            start = self.starts[k]
            block, size = self.where[k]
            data, first = self.store.piece(block, self.channel, lo - start)
            end = min(hi - start, size, first + len(data))
            out.append(data[lo - start - first : end - first])
            lo = start + end
            if end == size:
                k += 1
        return b"".join(out)


class PagedStore(FrameStore):
    """The rows of a capture, hot columns in memory and the rest in its sidecar."""

    def __init__(self) -> None:  # no super().__init__: the columns are made here
        for name in HOT:
            setattr(self, name, array(_TYPECODES[name]))
        for name in COLD:
            setattr(self, name, PagedColumn(self, name))
        self.streams: dict[int, PagedStream] = {}  # type: ignore[assignment]
        self.notes = {}
        self.fill_channel = 0
        self.stamps = Stamp.READ_END
        self.resolution = 0.0
        self.peers = {}
        self.servers = {}
        self.links = {}
        self._blocks: list[_Block] = []
        self._starts: list[int] = []  # each block's first row
        self._rows = 0
        self._fds: list[int] = []
        # a sidecar read back (`attach`): its descriptor, first block and blocks; or one
        # being written (`take`): the writer and a descriptor of its file
        self._file: tuple[int, int, list[Any]] | None = None
        self._writer: Writer | None = None
        self._writer_fd = -1
        self._source = -1  # the capture, which the sidecar's pieces of bytes refer to
        self._taken = 0  # blocks of either taken in
        self._next_pos = 0
        self._cache: OrderedDict[tuple[int, str | int, int], Any] = (
            OrderedDict()
        )  # block, what, page
        self._cached = 0
        self._lock = threading.Lock()
        self._last: _Block | None = None

    # -- as a FrameStore -------------------------------------------------------------------

    def __len__(self) -> int:
        return self._rows

    def sync(self) -> None:
        return None

    def __del__(self) -> None:
        self.close()

    def close(self) -> None:
        """Let go of the sidecars' descriptors (the store reads nothing after this)."""
        fds, self._fds = self._fds, []
        for fd in fds:
            with contextlib.suppress(OSError):
                os.close(fd)

    # -- filling: from a sidecar being read back -------------------------------------------

    def attach(self, path: Path, fd: int, start: int, header: Mapping[str, Any]) -> None:
        """Rows to come from the sidecar `path` (open as `fd`, its first block at
        `start`): `reach` takes them in as they are read back."""
        del path  # (the descriptor is what is read: the file may be replaced meanwhile)
        if self._rows:
            raise ValueError("a paged store takes one sidecar, before any other rows")
        own = os.dup(fd)
        self._fds.append(own)
        self._source = os.dup(int(header["capture_fd"]))
        self._fds.append(self._source)
        self._file = (own, start, list(header["blocks"]))
        self._taken = 0
        self._next_pos = start
        self.notes.update({int(i): str(text) for i, text in header["notes"].items()})
        self.stamps = Stamp[header["stamps"]]
        self.resolution = float(header["resolution"])
        self.fill_channel = int(header["fill_channel"])
        self.peers.update(channel_texts(header["peers"]))
        self.servers.update(channel_texts(header["servers"]))
        for ch, _size in header["streams"]:
            self._stream(int(ch))

    def reach(self, rows: int) -> None:
        """Take in the attached sidecar's blocks up to `rows` rows (those read back)."""
        if self._file is None:
            return
        fd, _start, blocks = self._file
        while self._rows < rows and self._taken < len(blocks):
            count, pieces, _crc, length = blocks[self._taken]
            self._place(fd, int(count), [(int(ch), int(size)) for ch, size in pieces], int(length))
            self._taken += 1

    # -- filling: as a windowed ingest writes the sidecar ------------------------------------

    def take(self, session: Session, writer: Writer | None) -> None:
        """The rows of the session's store (one segment, row `i` being row
        `session.base + i` of the capture), just written by `writer` as its last blocks;
        with no writer they are kept in memory."""
        store = session.store
        store.sync()
        self.stamps, self.resolution = store.stamps, store.resolution
        self.fill_channel = store.fill_channel
        self.peers.update(store.peers)  # (a network capture's: in place, as rows read it)
        self.servers.update(store.servers)
        base = session.base
        if base != self._rows:
            raise ValueError(f"rows {base:,} onwards given after {self._rows:,}")
        for i, text in store.notes.items():
            self.notes[base + i] = text
        if writer is None:
            self._in_memory(session)
            return
        writer.out.flush()
        if self._writer is not writer:
            if self._rows:
                raise ValueError("a paged store takes one sidecar")
            self._file = None  # (one read back and found damaged before its first block)
            self._writer, self._taken = writer, 0
            self._writer_fd = os.open(writer.tmp, os.O_RDONLY)
            self._fds.append(self._writer_fd)
            self._source = os.open(writer.path, os.O_RDONLY)
            self._fds.append(self._source)
            self._next_pos = writer.first_block
        # the segment's columns as they are in memory now (not read back from the file)
        n = len(store)
        hot = self._hot_of(store, n, base)
        at = 0
        for count, pieces, _crc, length in writer.blocks[self._taken :]:
            count = int(count)
            part = {name: values[at : at + count] for name, values in hot.items()}
            listed = [(int(c), int(z)) for c, z in pieces]
            self._place(self._writer_fd, count, listed, int(length), part)
            self._taken += 1
            at += count
        if at != n:
            raise ValueError(f"the sidecar took {at:,} rows of a segment of {n:,}")

    @staticmethod
    def _hot_of(store: FrameStore, n: int, base: int) -> dict[str, array[Any]]:
        """The hot columns of a segment's `n` rows, partners numbered in the capture."""
        hot = {name: getattr(store, name)[:n] for name in HOT}
        if base:
            partner = array("i")
            partner.frombytes(shifted_partners(memoryview(store.partner)[:n], 0, base))
            hot["partner"] = partner
        return hot

    def _in_memory(self, session: Session) -> None:
        """The session's store's rows, a block, kept here (no sidecar took them)."""
        store = session.store
        n = len(store)
        if not n:
            return
        base, bases = session.base, session.stream_base
        pieces = []
        columns: dict[str, array[Any]] = {}
        for name in COLD:
            columns[name] = array(_TYPECODES[name], getattr(store, name)[:n])
        offset = columns["offset"]
        for i in range(n):  # offsets in the whole capture, as the sidecar keeps them
            offset[i] += bases.get(store.channel[i], 0)
        kept: dict[int, bytes] = {}
        for ch, data in store.streams.items():
            at = bases.get(ch, 0)
            stream = self._stream(ch)
            stream.size = at  # (past bytes dropped that no row of ours pointed at)
            kept[ch] = bytes(data)
            pieces.append((ch, at, len(data)))
        block = _Block(self._rows, n, -1, -1, pieces, columns, kept)
        self._add_hot(block, self._hot_of(store, n, base))

    def _place(
        self,
        fd: int,
        count: int,
        pieces: list[tuple[int, int]],
        length: int,
        hot: Mapping[str, Any] | None = None,
    ) -> None:
        """The next block of the file `fd`, `count` rows carrying `pieces` (channel,
        bytes), `length` bytes packed; its hot columns `hot`, or read from the file."""
        pos = self._next_pos
        placed = []
        for ch, size in pieces:
            stream = self._stream(ch)
            placed.append((ch, stream.size, size))
        block = _Block(self._rows, count, fd, pos, placed, size=length)
        if hot is None:
            hot = {name: self._read_column(block, name) for name in HOT}
        self._add_hot(block, hot)
        self._next_pos = pos + length

    def _add_hot(self, block: _Block, hot: Mapping[str, Any]) -> None:
        """Append a block's hot columns (partners numbered in the capture) and publish
        its rows."""
        for name in HOT:
            getattr(self, name).extend(hot[name])
        for ch, start, size in block.pieces:
            if size:
                self._stream(ch).add(block, start, size)
            else:
                self._stream(ch)
        self._blocks.append(block)
        self._starts.append(block.start)
        self._rows = block.start + block.count  # last: the rows are complete now

    def _stream(self, ch: int) -> PagedStream:
        found = self.streams.get(ch)
        if found is None:
            found = self.streams[ch] = PagedStream(self, ch)
        return found

    # -- reading ---------------------------------------------------------------------------

    def block_of(self, row: int) -> _Block:
        last = self._last
        if last is not None and last.start <= row < last.start + last.count:
            return last
        block = self._blocks[bisect_right(self._starts, row) - 1]
        self._last = block
        return block

    def column(self, block: _Block, name: str, row: int) -> tuple[array[Any], int]:
        """Values of a cold column around row `row` of `block` (counted from its first):
        an array, and the row of the block its first value is (all of the block's, read
        from the file and unpacked, or kept in memory)."""
        del row
        if block.columns is not None:
            return block.columns[name], 0
        values = self._through_cache((id(block), name, 0), lambda: self._read_column(block, name))
        return values, 0

    def piece(self, block: _Block, channel: int, at: int) -> tuple[bytes, int]:
        """Bytes of `channel` that `block` carries, around its `at`-th: the bytes, and
        where they start among the block's (one of its packed pieces, or all of them)."""
        if block.kept is not None:
            return block.kept.get(channel, b""), 0
        k = next((j for j, (ch, _start, _size) in enumerate(block.pieces) if ch == channel), -1)
        if k < 0:
            return b"", 0
        packed = self._packed(block)
        firsts = [first for first, *_rest in packed.pieces[k]]
        j = bisect_right(firsts, at) - 1
        if j < 0:
            return b"", 0
        data = self._through_cache(
            (id(block), -1 - channel, j), lambda: packed.piece(k, j, self._source)
        )
        return data, firsts[j]

    def _packed(self, block: _Block) -> Packed:
        """The block as in the file, its table read (kept in the cache, packed)."""
        return self._through_cache(
            (id(block), "", 0),
            lambda: Packed(
                _pread(block.fd, block.size, block.pos), block.count, block.start, len(block.pieces)
            ),
        )

    def _through_cache(self, whose: tuple[int, str | int, int], read: Callable[[], _T]) -> _T:
        with self._lock:
            found: _T | None = self._cache.get(whose)
            if found is not None:
                self._cache.move_to_end(whose)
                return found
        value = read()
        size = len(value) * getattr(value, "itemsize", 1)
        with self._lock:
            if whose not in self._cache:
                self._cache[whose] = value
                self._cached += size
                while self._cached > CACHE_BYTES and len(self._cache) > 1:
                    _key, old = self._cache.popitem(last=False)
                    self._cached -= len(old) * getattr(old, "itemsize", 1)
        return value

    def _read_column(self, block: _Block, name: str) -> array[Any]:
        """`block`'s column `name`, unpacked (zeros for a file cut short under us: not a
        crash)."""
        values = array(_TYPECODES[name])
        try:
            values.frombytes(self._packed(block).column(name))
        except (ValueError, zlib.error, struct.error):
            values.frombytes(bytes(_SIZES[name] * block.count))
        return values

    @property
    def bytes_total(self) -> int:
        return sum(len(s) for s in self.streams.values())

    def memory_bytes(self) -> int:
        """Bytes held in memory: the hot columns, blocks kept in memory and the cache."""
        hot: int = sum(getattr(self, name).itemsize * len(getattr(self, name)) for name in HOT)
        kept = sum(
            sum(len(v) * v.itemsize for v in b.columns.values())
            + sum(len(v) for v in (b.kept or {}).values())
            for b in self._blocks
            if b.columns is not None
        )
        return hot + kept + self._cached


def _pread(fd: int, size: int, at: int) -> bytes:
    parts = []
    while size > 0:
        try:
            got = os.pread(fd, size, at)
        except OSError:
            break
        if not got:
            break
        parts.append(got)
        size -= len(got)
        at += len(got)
    return b"".join(parts)

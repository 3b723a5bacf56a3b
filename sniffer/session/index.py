"""Provides the sidecar index: a capture's framed and paired rows kept beside it.

Indexing a network capture or a text log takes minutes where reading the rows back takes
seconds, and the TUI shows the rows of a big capture from its sidecar, a page at a time.
(A serial recording framed by the compiled core reads about as fast from the capture as
from its sidecar: the commands that read a capture through once take no sidecar for it,
see `pays`.) After a capture of at least `MIN_SIZE` bytes has been indexed to its end, its rows
(the store's columns and bytes), the session's warnings and notes and the capture's own
warnings are written to `FILE.modscope-index` beside it, or, where that folder cannot be
written, to `~/.cache/modscope/index/` (`$XDG_CACHE_HOME` if set) under a name made from
the capture's path.

A sidecar is used only when all of this still holds, else the capture is indexed again
(and the sidecar rewritten):
- the capture's size, modification time and the SHA-256 of its first 64 KiB;
- the settings the rows depend on: the line settings and other read options, the
  response timeout, the function codes of the bound devices, the bindings (the
  annotator's flags are in the rows), and a fingerprint of modscope's own code.

The file: a header of JSON (with its CRC-32), then the rows in blocks of `BLOCK` rows,
each with its own CRC-32, then the per-unit latencies and request times. It is read a
block at a time (`load`): the TUI shows the first rows after the first block while the
rest is read.

A block is packed (format 3, #29: the sidecar at most a quarter of its capture, was 84-162
% of it): a table (each part's length), its columns and its share of each channel's bytes.
- Columns: each with zlib (level 1), the wider ones in byte planes (all the lowest
  bytes, then the next...: the high bytes of close values are runs); `t_end` as its
  distance from `t` and partners as their distance from their own row, both in the bits
  taken as integers (exact, one integer operation a column, `_minus`/`_add`).
- Bytes: not copied but referred to in the capture. A piece of a channel's bytes (at
  most `PIECE`) is packed with deflate given the region of the capture it was read from
  as its dictionary (at most deflate's 32 KiB window), found by looking for a row's
  bytes after those of the piece before (`_Referrer`); deflate then keeps a few bytes for
  each run of bytes read. Bytes the capture does not hold as read (text logs) pack as
  plain zlib. Each block keeps the CRC-32 of its bytes, checked when they are read back
  from the capture: a capture whose bytes changed is indexed again.
- The statistics' latencies and request times in byte planes with zlib.

A sidecar is data, never code: one that is damaged or does not fit its capture is
ignored, and the capture indexed again (a damaged block found after rows were read: the
rows are taken back, unless another thread shows them, see `load`). A sidecar is written
to a temporary file `.modscope-index-*` beside its place, locked (flock) while it is
written, then renamed: a writer killed halfway leaves its temporary file unlocked, and
the next run that looks in that folder removes it (`sweep`).

`MODSCOPE_NO_INDEX=1` (or `open_session(..., index=False)`) neither reads nor writes one.
"""

from __future__ import annotations

import contextlib
import dataclasses
import fcntl
import hashlib
import json
import mmap
import operator
import os
import struct
import sys
import tempfile
import zlib
from array import array
from bisect import bisect_left
from collections.abc import Callable, Iterator, Mapping, Sequence
from functools import cache, lru_cache
from itertools import accumulate, compress
from pathlib import Path
from typing import Any

from sniffer import __version__, core
from sniffer.analysis.stats import LATENCIES, REQUEST_TIMES, UnitStats
from sniffer.framing.columns import marking
from sniffer.framing.store import COLUMNS, NO_PARTNER, FrameStore
from sniffer.meaning.annotate import Annotator
from sniffer.model import Stamp
from sniffer.session.state import SessionState
from sniffer.sources import Capture
from sniffer.vocab import Kind

MAGIC = b"MODSCOPE-INDEX\n\0"
FORMAT = 4  # the file's layout: a sidecar of another format is ignored (indexed again)
# (4: a network capture's peers and servers kept, which format 3 lost, and with them
# the per-server table of `replay --stats` and the peer column of the TUI read back;
# the tail in pieces of TAIL_PIECE values, which format 3 unpacked whole: 253 MB for a
# day's `replay --stats` read back)
TAIL_PIECE = 1 << 16  # values a piece of the tail holds (512 KiB unpacked)
SUFFIX = ".modscope-index"
MIN_SIZE = 4 << 20  # smaller captures index in about a second: no sidecar for them
HEAD = 1 << 16  # bytes of the capture hashed to tell it from another of the same size
# a block keeps its rows' columns in the order of sniffer.framing.store.COLUMNS
_PREFIX = struct.Struct("<QI")  # the header's length and CRC-32
# rows a block: 65,536 rows are about 4 MB, little to read and check before the TUI's
# first screen, whatever the size of the capture
BLOCK = 1 << 16


# readers whose serial records the compiled core reads and frames in bulk (see `pays`)
_BULK_FORMATS = frozenset({"pcap", "pcapng"})


def pays(capture: Capture, mode: str | None) -> bool:
    """Whether a sidecar pays for a command that reads the capture through once
    (`replay`, `export`): where reading the capture costs more than reading its rows
    back. It does not for a serial recording in pcap or pcapng framed as RTU by the
    compiled core: a day of 30M frames (2026-12-07) was counted in 17.8 s with no
    sidecar, 21.7 s read back from one, and 38.0 s while writing it. It does for a
    network capture (1M Modbus TCP frames: 115 s framed, 11.5 s read back), a logic
    capture, a text log, ASCII framing and the pure-Python core. The TUI takes a sidecar
    whatever the capture: it shows the rows from it (`sniffer.session.paged`)."""
    if core.FAST is None or capture.info.network or mode == "ascii":
        return True
    return capture.info.format not in _BULK_FORMATS


def enabled() -> bool:
    return os.environ.get("MODSCOPE_NO_INDEX", "") in ("", "0")


def cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "modscope" / "index"


def sidecars(capture: Path) -> list[Path]:
    """Where a capture's sidecar may be: beside it, then in the cache folder."""
    absolute = capture.resolve()
    digest = hashlib.sha256(str(absolute).encode("utf-8", "surrogateescape")).hexdigest()
    return [
        absolute.with_name(absolute.name + SUFFIX),
        cache_dir() / f"{digest[:32]}{SUFFIX}",
    ]


TEMP_PREFIX = ".modscope-index-"


def sweep(folder: Path) -> int:
    """Remove the temporary files of sidecar writers that died (their lock is free);
    how many were removed."""
    return sweep_unlocked(folder, TEMP_PREFIX + "*")


def sweep_unlocked(folder: Path, pattern: str) -> int:
    """Remove the files of `folder` matching `pattern` whose writer died: each holds an
    exclusive flock while its writer lives, so a lock taken at once means none does
    (sidecar temporaries here, a recorder's disk reserve); how many were removed."""
    removed = 0
    try:
        names = list(folder.glob(pattern))
    except OSError:
        return 0
    for name in names:
        try:
            fd = os.open(name, os.O_RDONLY | os.O_NOFOLLOW)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # free: its writer is gone
            os.unlink(name)
            removed += 1
        except OSError:  # held: a writer is at work (BlockingIOError), or not ours to remove
            pass
        finally:
            os.close(fd)
    return removed


def _temporary(folder: Path) -> tuple[int, str]:
    """A new temporary file for a sidecar in `folder`, locked for as long as it is open
    (see `sweep`); stale ones of killed writers are removed first."""
    folder.mkdir(parents=True, exist_ok=True)
    sweep(folder)
    fd, tmp = tempfile.mkstemp(prefix=TEMP_PREFIX, dir=folder)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return fd, tmp


def identity(capture: Path) -> dict[str, Any] | None:
    """Size, modification time and the hash of the head of `capture` (None: unreadable)."""
    try:
        with capture.open("rb") as handle:
            st = os.fstat(handle.fileno())
            head = handle.read(HEAD)
    except OSError:
        return None
    return {
        "size": st.st_size,
        "mtime_ns": st.st_mtime_ns,
        "head": hashlib.sha256(head).hexdigest(),
    }


def _plain(value: Any, depth: int = 0) -> Any:
    """A JSON-able picture of settings (dataclasses, mappings, rules, callables by name)."""
    if depth > 12:
        return "..."
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return [
            type(value).__name__,
            *(_plain(getattr(value, f.name), depth + 1) for f in dataclasses.fields(value)),
        ]
    if isinstance(value, Mapping):
        items = sorted(value.items(), key=lambda kv: repr(kv[0]))
        return [[_plain(k, depth + 1), _plain(v, depth + 1)] for k, v in items]
    if isinstance(value, (list, tuple, frozenset, set)):
        items = list(value)
        if isinstance(value, (set, frozenset)):
            items.sort(key=repr)
        return [_plain(v, depth + 1) for v in items]
    if callable(value):
        return getattr(value, "__qualname__", type(value).__name__)
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return repr(value)


@cache
def code_fingerprint() -> str:
    """A hash of modscope's own source (a changed framer must not reuse old rows)."""
    digest = hashlib.sha256(__version__.encode())
    for package in ("sniffer", "dissectors"):
        module = sys.modules.get(package)
        where = getattr(module, "__file__", None)
        if where is None:
            continue
        root = Path(where).parent
        for path in sorted(root.rglob("*.py")):
            if "tui" in path.relative_to(root).parts:
                continue
            with contextlib.suppress(OSError):
                digest.update(str(path.relative_to(root)).encode())
                digest.update(path.read_bytes())
    return digest.hexdigest()


def settings_key(annotator: Annotator, options: Any, timeout: float | None) -> str:
    """What the rows of a capture depend on besides its bytes, as one hash (`annotator`:
    the session's, not yet fed: its registry and bindings)."""
    registry = annotator.registry
    picture = [
        FORMAT,
        code_fingerprint(),
        _plain(options),
        timeout,
        [[code, _plain(registry[code])] for code in sorted(registry)],
        _plain(annotator.bindings),
    ]
    return hashlib.sha256(json.dumps(picture, sort_keys=True).encode()).hexdigest()


# -------------------------------------------------------------------------- writing


def _blocks(store: FrameStore, n: int) -> list[tuple[int, int, list[list[int]]]] | None:
    """The blocks of rows: (first row, end, [[channel, bytes], ...]) where a block carries
    the bytes of each channel from where the one before stopped to the end of the last
    byte its rows point at (the last block: to the end of the stream). None: a row of a
    channel with no bytes (not written)."""
    ends = dict.fromkeys(store.streams, 0)
    out: list[tuple[int, int, list[list[int]]]] = []
    for a in range(0, max(n, 1), BLOCK):
        b = min(n, a + BLOCK)
        if b >= n:
            reach = {ch: len(data) for ch, data in store.streams.items()}
        else:
            reach = dict(ends)
            channels = store.channel[a:b].tobytes()
            present = set(channels)
            if not present <= set(reach):
                return None
            offset, length = store.offset[a:b], store.length[a:b]
            for ch in present:
                if len(present) == 1:
                    far = _bounds(_ends(offset, length), "Q")[1]
                else:
                    mask = channels.translate(marking((ch,)))
                    far = max(compress(map(operator.add, offset, length), mask))
                reach[ch] = max(reach[ch], min(far, len(store.streams[ch])))
        out.append((a, b, [[ch, reach[ch] - ends[ch]] for ch in store.streams]))
        ends = reach
    return out


def _block_parts(
    store: FrameStore, a: int, b: int, pieces: list[list[int]], starts: dict[int, int]
) -> list[memoryview]:
    """The bytes of one block: its rows' columns, then its share of each stream."""
    parts = []
    for name in COLUMNS:
        col = getattr(store, name)
        parts.append(memoryview(col).cast("B")[a * col.itemsize : b * col.itemsize])
    for ch, size in pieces:
        at = starts[ch]
        parts.append(memoryview(store.streams[ch])[at : at + size])
        starts[ch] = at + size
    return parts


def save(state: SessionState, capture: Capture, path: Path, key: str) -> Path | None:
    """Write the sidecar of `path`; its location, or None when nowhere could take it."""
    if identity(path) is None:
        return None
    for target in sidecars(path):  # (one that cannot take it: the next)
        writer = Writer(path, [target])
        writer.add(state)
        if writer.unfit:
            return None  # not for want of a place
        written = writer.close(state, capture, key)
        if written is not None:
            return written
    return None


def _publish(tmp: str, target: Path) -> None:
    """The written temporary file in its place, readable as any file the user writes."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # (mkstemp: 0600)
    os.replace(tmp, target)


def _tail(state: SessionState, spill: Spill | None = None) -> Iterator[bytes | None]:
    """The per-unit latencies and request times written after the blocks: each unit's
    values of each kind (a part) in pieces of TAIL_PIECE values, each piece packed on
    its own (`_pack_tail`) so that a reader unpacks one at a time; those of a unit whose
    values `spill` kept (a windowed replay's bounded statistics) read from it. None
    after each part."""
    for unit in state.stats.units.values():
        for which, values in ((LATENCIES, unit.latencies), (REQUEST_TIMES, unit.request_times)):
            if spill is not None and unit.tallies is not None:
                yield from spill.packed(unit.unit, which)
            else:
                for at in range(0, len(values), TAIL_PIECE):
                    yield _pack_tail(values[at : at + TAIL_PIECE])
            yield None  # (the part ends here)


def _header_of(
    state: SessionState,
    capture: Capture,
    key: str,
    who: dict[str, Any],
    *,
    spill: Spill | None = None,
    rows: int,
    streams: list[list[int]],
    blocks: list[Any],
    tail_crc: int,
    tail_sizes: list[list[int]],
    notes: dict[str, str],
) -> dict[str, Any]:
    store = state.store
    return {
        "format": FORMAT,
        "key": key,
        "capture": who,
        "rows": rows,
        "columns": {name: getattr(store, name).typecode for name in COLUMNS},
        "streams": streams,
        "blocks": blocks,
        "tail_crc32": tail_crc,
        "tail": tail_sizes,
        "notes": notes,
        "stamps": store.stamps.name,
        "resolution": store.resolution,
        "fill_channel": store.fill_channel,
        # a network channel's sender and server (ip:port), as the framers set them
        "peers": {str(ch): text for ch, text in store.peers.items()},
        "servers": {str(ch): text for ch, text in store.servers.items()},
        "mode": state.pipeline.mode,
        "session_warnings": state.warnings,
        "session_notes": state.notes,
        "chunks": state.chunks,
        "capture_warnings": capture.warnings,
        "data_bytes": capture.data_bytes,
        "channels": {str(ch): label for ch, label in capture.info.channels.items()},
        "stats": _stats_header(state, spill),
    }


# room left for the header before the first block when the blocks are written first
# (`Writer`): JSON allows the spaces that fill what it does not use; a header that does
# not fit (a capture with very many row notes) is written in front of a copy
RESERVE = 1 << 18


class Spill:
    """Each unit's latencies and request times, kept in a temporary file as a windowed
    replay counts them (`Stats.bound(spill)`) rather than in memory, for the sidecar's
    tail: `replay --stats` of a day then takes memory flat in its frames while it writes
    the sidecar (2 x 8 bytes a transaction kept before: 306 MB for a 30M-frame day of
    the project's stream, 2026-12-06), and the sidecar is the same file.

    Called as `Stats.bound`'s spill: `spill(unit, LATENCIES or REQUEST_TIMES, values)`.
    Values wait in a buffer of CHUNK per unit and kind, then go to the file as a chunk;
    `packed` reads them back a chunk at a time. The file is made beside the sidecar
    (not in /tmp, which may be memory) and is gone once closed; where it cannot be
    made the values stay in memory."""

    CHUNK = 8192  # values a buffer holds before it is written out (64 KB)

    def __init__(self, folder: Path | None) -> None:
        self.folder = folder
        self.file: Any = None
        self.buffers: dict[tuple[int, int], array[float]] = {}
        self.chunks: dict[tuple[int, int], list[tuple[int, int]]] = {}  # (at, count)
        self.counts: dict[tuple[int, int], int] = {}
        self.closed = False
        self.in_memory = False  # no file could be made: the buffers keep every value

    def __call__(self, unit: int, which: int, values: Sequence[float]) -> None:
        if self.closed:
            return
        key = (unit, which)
        buffer = self.buffers.get(key)
        if buffer is None:
            buffer = self.buffers[key] = array("d")
        buffer.extend(values)
        self.counts[key] = self.counts.get(key, 0) + len(values)
        if len(buffer) >= self.CHUNK and not self.in_memory and self._to_file(key, buffer):
            del buffer[:]

    def _to_file(self, key: tuple[int, int], values: array[float]) -> bool:
        """Write `values` as the key's next chunk; False if the file cannot be had."""
        if self.file is None:
            try:
                # (closed by `close`, as the writer finishes or gives up)
                self.file = tempfile.TemporaryFile(  # noqa: SIM115
                    prefix=TEMP_PREFIX, dir=self.folder
                )
            except OSError:
                self.in_memory = True
                return False
        at = self.file.seek(0, os.SEEK_END)
        self.file.write(values.tobytes())
        self.chunks.setdefault(key, []).append((at, len(values)))
        return True

    def count(self, unit: int, which: int) -> int:
        return self.counts.get((unit, which), 0)

    def _pieces(self, key: tuple[int, int]) -> Iterator[bytes]:
        """The key's values, a chunk at a time, in the order they came."""
        if self.file is not None:
            self.file.flush()
            for at, count in self.chunks.get(key, ()):
                self.file.seek(at)
                yield self.file.read(8 * count)
        rest = self.buffers.get(key)
        if rest:
            yield rest.tobytes()

    def packed(self, unit: int, which: int) -> Iterator[bytes]:
        """The key's values as `_tail` packs an array of them: in pieces of TAIL_PIECE
        values, each packed by `_pack_tail`, read through the chunks."""
        values: array[float] = array("d")
        for chunk in self._pieces((unit, which)):
            values.frombytes(chunk)
            while len(values) >= TAIL_PIECE:
                yield _pack_tail(values[:TAIL_PIECE])
                del values[:TAIL_PIECE]
        if values:
            yield _pack_tail(values)

    def close(self) -> None:
        self.closed = True
        if self.file is not None:
            with contextlib.suppress(OSError):
                self.file.close()
            self.file = None


class Writer:
    """The sidecar of a capture written a segment at a time, as a windowed session
    (`Session.ingest` with a window) drops them: each segment's rows as blocks of at most
    `BLOCK` rows (the last block of a segment ends with it), their offsets and partners
    numbered in the whole capture, so the file is the one `save` writes of a store
    holding every row, but for where blocks end. The header comes last, into room left
    for it at the start (`RESERVE`)."""

    def __init__(self, path: Path, targets: list[Path] | None = None) -> None:
        self.path = path
        self.out: Any = None
        self.unfit = False  # rows a sidecar cannot take (a row of a channel with no bytes)
        self.tmp = ""
        self.target: Path | None = None
        for target in sidecars(path) if targets is None else targets:
            try:
                fd, tmp = _temporary(target.parent)
            except OSError:
                continue
            self.out, self.tmp, self.target = os.fdopen(fd, "wb"), tmp, target
            break
        self.blocks: list[Any] = []
        self.first_block = len(MAGIC) + _PREFIX.size + RESERVE  # where the blocks start
        self.capture = _Referrer(path) if self.out is not None else None
        # a windowed replay's statistics, bounded, hand their values here (`Stats.bound`)
        self.spill = Spill(self.target.parent if self.target is not None else None)
        self.notes: dict[str, str] = {}
        self.rows = 0
        self.streams: dict[int, int] = {}
        try:
            if self.out is not None:
                self.out.write(MAGIC)
                self.out.write(bytes(_PREFIX.size + RESERVE))
        except OSError:
            self.abandon()

    def add(self, state: SessionState) -> None:
        """Write the rows of the session's store (`state`: a segment, or the last rows)."""
        if self.out is None or self.capture is None:
            return
        store = state.store
        store.sync()
        n = len(store)
        blocks = _blocks(store, n)
        if blocks is None:
            self.unfit = True
            self.abandon()
            return
        base, bases = state.base, state.stream_base
        starts = dict.fromkeys(store.streams, 0)
        try:
            for a, b, pieces in blocks:
                at = dict(starts)
                parts = _block_parts(store, a, b, pieces, starts)
                if base or any(bases.values()):
                    _renumber(store, a, b, parts, base, bases)
                packed = _pack_block(store, a, b, pieces, parts, at, base, bases, self.capture)
                crc = 0
                for part in packed:
                    crc = zlib.crc32(part, crc)
                    self.out.write(part)
                self.blocks.append([b - a, pieces, crc, sum(len(part) for part in packed)])
        except OSError:
            self.abandon()
            return
        self.capture.release()
        self.rows = base + n
        self.notes.update({str(base + i): text for i, text in store.notes.items()})
        for ch, data in store.streams.items():
            self.streams[ch] = bases.get(ch, 0) + len(data)

    def close(self, state: SessionState, capture: Capture, key: str) -> Path | None:
        """Finish the sidecar (after the last `add`): its location, or None."""
        out, target = self.out, self.target
        who = identity(self.path)
        if out is None or target is None or who is None:
            self.abandon()
            return None
        crc = 0
        sizes: list[list[int]] = []  # each part's pieces' lengths
        pieces: list[int] = []
        try:
            out.seek(0, os.SEEK_END)
            for piece in _tail(state, self.spill):
                if piece is None:
                    sizes.append(pieces)
                    pieces = []
                else:
                    crc = zlib.crc32(piece, crc)
                    pieces.append(len(piece))
                    out.write(piece)
        except OSError:
            self.abandon()
            return None
        header = _header_of(
            state,
            capture,
            key,
            who,
            spill=self.spill,
            rows=self.rows,
            streams=[[ch, size] for ch, size in self.streams.items()],
            blocks=self.blocks,
            tail_crc=crc,
            tail_sizes=sizes,
            notes=self.notes,
        )
        blob = json.dumps(header).encode()
        try:
            if len(blob) <= RESERVE:
                blob += b" " * (RESERVE - len(blob))
                out.seek(len(MAGIC))
                out.write(_PREFIX.pack(len(blob), zlib.crc32(blob)))
                out.write(blob)
                out.flush()
                _publish(self.tmp, target)  # while still locked (see `sweep`)
                out.close()
            else:
                self._rewrite(blob, target)
        except OSError:
            self.abandon()
            return None
        self.out = None
        if self.capture is not None:
            self.capture.close()
        self.spill.close()
        return target

    def _rewrite(self, blob: bytes, target: Path) -> None:
        """The header in front of a copy of the blocks (it did not fit its room)."""
        self.out.flush()
        fd, tmp = _temporary(target.parent)
        try:
            with os.fdopen(fd, "wb") as out, open(self.tmp, "rb") as blocks:
                out.write(MAGIC)
                out.write(_PREFIX.pack(len(blob), zlib.crc32(blob)))
                out.write(blob)
                blocks.seek(len(MAGIC) + _PREFIX.size + RESERVE)
                while piece := blocks.read(1 << 22):
                    out.write(piece)
                out.flush()
                _publish(tmp, target)
            self.out.close()
        except OSError:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise
        finally:
            with contextlib.suppress(OSError):
                os.unlink(self.tmp)

    def abandon(self) -> None:
        """No sidecar after all (a folder that filled up, a read stopped halfway)."""
        self.spill.close()
        if self.capture is not None:
            self.capture.close()
        if self.out is not None:
            with contextlib.suppress(OSError):
                self.out.close()
            with contextlib.suppress(OSError):
                os.unlink(self.tmp)
        self.out = None


def _renumber(
    store: FrameStore,
    a: int,
    b: int,
    parts: list[memoryview],
    base: int,
    bases: Mapping[int, int],
) -> None:
    """The offset and partner columns of rows `a`..`b` of a segment, in `parts`,
    replaced by their numbers in the whole capture (`base` rows and each channel's
    `bases` bytes before the segment)."""
    offset = store.offset[a:b]
    channels = store.channel[a:b]
    present = set(channels.tobytes())
    if len(present) == 1:
        shifted = _plus(offset, bases.get(next(iter(present)), 0))
    else:
        shifted = array(
            offset.typecode,
            (o + bases.get(ch, 0) for o, ch in zip(offset, channels, strict=True)),
        ).tobytes()
    parts[COLUMNS.index("offset")] = memoryview(shifted)
    if base:
        partner = shifted_partners(memoryview(store.partner)[a:b], 0, base)
        parts[COLUMNS.index("partner")] = memoryview(partner)


def shifted_partners(partner: memoryview, at_least: int, by: int) -> bytes:
    """The bytes of a block's partner column (int32) with each partner `p` at or above
    `at_least` made `p + by`, and every other one none (-1): `at_least` 0 moves rows
    numbered in a segment into the whole capture (`by` its base), `at_least` the base
    and `by` minus it the other way, a partner in a block dropped before becoming none.
    In the compiled core where it runs: a windowed sidecar shifts every partner of the
    capture, written or read back."""
    fast = core.FAST
    if fast is not None:
        return bytes(fast.shift_partners(partner, at_least, by))
    shifted = array("i", (p + by if p >= at_least else NO_PARTNER for p in partner))
    return shifted.tobytes()


def _bounds(column: array[int] | memoryview, code: str) -> tuple[int, int]:
    """The least and the greatest word of a non-empty column of typecode `code` (min and
    max, a Python int a word; in the compiled core where it runs: the sidecar's checks
    take them of every block, 17% of a day's `replay --stats` read back, 2026-12-07)."""
    fast = core.FAST
    if fast is not None:
        found: tuple[int, int] | None = fast.bounds(column, code)
        assert found is not None  # (not empty)
        return found
    return min(column), max(column)


def _plus(column: array[int] | memoryview, by: int) -> bytes:
    """The bytes of `column` (unsigned words: offsets) with `by` added to every value;
    every result must fit its word (a word never carries into the next). The column is
    taken as one big integer and `by` times a word of 1 at every row added to it: one
    addition in C rather than a Python step per offset of the capture."""
    raw = column.tobytes()
    size = column.itemsize
    total = int.from_bytes(raw, sys.byteorder) + by * _ones(len(raw) // size, size)
    return total.to_bytes(len(raw), sys.byteorder)


@lru_cache(maxsize=4)
def _ones(rows: int, size: int) -> int:
    """`rows` words of `size` bytes, each holding 1, as one integer (native order)."""
    return int.from_bytes((1).to_bytes(size, sys.byteorder) * rows, sys.byteorder)


def _stats_header(state: SessionState, spill: Spill | None = None) -> dict[str, Any]:
    """The per-unit statistics (saved: recounting them would take a pass over every
    row); the counts of values a unit's `spill` kept, for a bounded unit."""
    stats = state.stats
    base = state.base  # (a windowed session: rows numbered in the whole capture)
    return {
        "next": base + stats.next,
        "noise_bytes": stats.noise_bytes,
        "noise_spans": stats.noise_spans,
        "events": stats.events,
        "open": sorted(base + i for i in stats._open),
        "units": [
            {
                "unit": u.unit,
                "requests": u.requests,
                "responses": u.responses,
                "exceptions": {str(code): k for code, k in u.exceptions.items()},
                "timeouts": u.timeouts,
                "check_errors": u.check_errors,
                "last_seen": u.last_seen,
                "below_resolution": u.below_resolution,
                "unmeasured": u.unmeasured,
                "latencies": len(u.latencies)
                if spill is None or u.tallies is None
                else spill.count(u.unit, LATENCIES),
                "request_times": len(u.request_times)
                if spill is None or u.tallies is None
                else spill.count(u.unit, REQUEST_TIMES),
            }
            for u in stats.units.values()
        ],
    }


# -------------------------------------------------------------------------- packing

# zlib's level for everything packed: level 1 is the fastest, and the higher levels
# gain little on these columns and pieces (benchmarks/bench_index.py, docs/performance.md)
LEVEL = 1
WINDOW = 1 << 15  # deflate's window: a piece's region of the capture is at most this long
PIECE = 1 << 14  # stream bytes a piece holds at most
NEEDLE = 48  # bytes of a row looked for in the capture
_BLOCK_HEAD = struct.Struct("=II")  # the CRC-32 of the block's bytes, its channels
_SIZES = struct.Struct("=" + "I" * len(COLUMNS))  # each column's packed length
_COUNT = struct.Struct("=I")  # a channel's pieces
# a piece: its bytes, where its region of the capture is (-1: none) and how long, packed
_PIECE = struct.Struct("=IqII")
_WIDTHS = {name: array(code).itemsize for name, code in zip(COLUMNS, "QHddBBBIBiB", strict=True)}


def _planes(raw: bytes, width: int) -> bytes:
    """The bytes of `width`-byte words regrouped by their place in the word (all the
    lowest bytes, then the next...): the high bytes of small or close values are runs
    that zlib takes for almost nothing."""
    if width == 1:
        return raw
    return b"".join(raw[k::width] for k in range(width))


def _unplanes(raw: bytes, width: int) -> bytes:
    if width == 1:
        return raw
    n = len(raw) // width
    out = bytearray(len(raw))
    for k in range(width):
        out[k::width] = raw[k * n : (k + 1) * n]
    return bytes(out)


@lru_cache(maxsize=4)
def _mask(size: int) -> int:
    return (1 << (8 * size)) - 1


def _minus(raw: bytes, by: int) -> bytes:
    """`raw` (words of a column) less `by` (as many words), all the bytes taken as one
    integer modulo its size: exact both ways (`_add`), one operation in C."""
    total = (int.from_bytes(raw, sys.byteorder) - by) & _mask(len(raw))
    return total.to_bytes(len(raw), sys.byteorder)


def _add(raw: bytes, by: int) -> bytes:
    total = (int.from_bytes(raw, sys.byteorder) + by) & _mask(len(raw))
    return total.to_bytes(len(raw), sys.byteorder)


def _rows(n: int) -> int:
    """The numbers 0..n-1 as int32 words, as one integer."""
    return int.from_bytes(_counting(max(n, BLOCK))[: 4 * n], sys.byteorder)


@lru_cache(maxsize=2)
def _counting(n: int) -> bytes:
    return array("i", range(n)).tobytes()


def _pack(raw: bytes) -> bytes:
    return zlib.compress(raw, LEVEL, wbits=-15)


def _unpack(raw: bytes | memoryview, size: int) -> bytes:
    d = zlib.decompressobj(wbits=-15)
    out = d.decompress(raw, size + 1)
    if len(out) != size:
        raise ValueError("a packed part of the wrong length")
    return out


def _pack_columns(col: dict[str, bytes], n: int, first_row: int) -> list[bytes]:
    """A block's columns packed: `t_end` as its distance from `t` (the bits of the floats
    taken as integers: exact), partners as their distance from their own row (mostly
    the row before or after), the wider columns in byte planes, each with zlib."""
    out = []
    for name in COLUMNS:
        raw = col[name]
        if name == "t_end":
            raw = _minus(raw, int.from_bytes(col["t"], sys.byteorder))
        elif name == "partner":
            raw = _minus(raw, first_row * _ones(n, 4) + _rows(n))
        out.append(_pack(_planes(raw, _WIDTHS[name])))
    return out


class Packed:
    """One packed block of a sidecar: its table read, its columns and bytes unpacked
    on demand. `data`: the block as in the file (CRC-32 checked by the caller);
    `first_row`: its first row's number in the capture; `channels`: how many channels
    its bytes are in. Raises ValueError (or zlib.error) when it does not hold up."""

    def __init__(self, data: bytes, count: int, first_row: int, channels: int) -> None:
        self.data, self.count, self.first_row = data, count, first_row
        self.bytes_crc, listed = _BLOCK_HEAD.unpack_from(data, 0)
        if listed != channels:
            raise ValueError("a block of other channels")
        at = _BLOCK_HEAD.size
        sizes = _SIZES.unpack_from(data, at)
        at += _SIZES.size
        # each channel's pieces: (first stream byte in the block's share, stream bytes,
        # region, its length, packed length)
        self.pieces: list[list[tuple[int, int, int, int, int]]] = []
        for _ch in range(channels):
            (k,) = _COUNT.unpack_from(data, at)
            at += _COUNT.size
            if k > len(data):
                raise ValueError("too many pieces")
            listed_pieces = []
            first = 0
            for _ in range(k):
                size, where, span, packed = _PIECE.unpack_from(data, at)
                at += _PIECE.size
                listed_pieces.append((first, size, where, span, packed))
                first += size
            self.pieces.append(listed_pieces)
        self.columns: dict[str, tuple[int, int]] = {}
        for name, size in zip(COLUMNS, sizes, strict=True):
            self.columns[name] = (at, size)
            at += size
        self.piece_at: list[list[int]] = []
        for listed_pieces in self.pieces:
            starts = []
            for piece in listed_pieces:
                starts.append(at)
                at += piece[4]
            self.piece_at.append(starts)
        if at != len(data):
            raise ValueError("a block of another length")
        self._t: bytes | None = None

    def __len__(self) -> int:  # (what it holds in a cache)
        return len(self.data)

    def column(self, name: str) -> bytes:
        at, size = self.columns[name]
        n, width = self.count, _WIDTHS[name]
        raw = _unplanes(_unpack(memoryview(self.data)[at : at + size], n * width), width)
        if name == "t":
            self._t = raw
        elif name == "t_end":
            t = self._t if self._t is not None else self.column("t")
            raw = _add(raw, int.from_bytes(t, sys.byteorder))
        elif name == "partner":
            raw = _add(raw, self.first_row * _ones(n, 4) + _rows(n))
        return raw

    def piece(self, channel: int, k: int, capture: int) -> bytes:
        """The `k`-th piece of the block's bytes of its `channel`-th channel; `capture`:
        a descriptor of the capture its regions are in."""
        _first_byte, size, where, span, packed = self.pieces[channel][k]
        at = self.piece_at[channel][k]
        if where >= 0:
            region = _pread(capture, span, where)
            if len(region) != span:
                raise ValueError("the capture is shorter than its sidecar says")
            d = zlib.decompressobj(wbits=-15, zdict=region)
        else:
            d = zlib.decompressobj(wbits=-15)
        out = d.decompress(memoryview(self.data)[at : at + packed], size + 1)
        if len(out) != size:
            raise ValueError("a piece of the wrong length")
        return out

    def share(self, channel: int, capture: int) -> bytes:
        return b"".join(self.piece(channel, k, capture) for k in range(len(self.pieces[channel])))


def _pread(fd: int, size: int, at: int) -> bytes:
    parts = []
    while size > 0:
        got = os.pread(fd, size, at)
        if not got:
            break
        parts.append(got)
        size -= len(got)
        at += len(got)
    return b"".join(parts)


class _Referrer:
    """Where a capture holds the bytes of its channels, for pieces packed against it.

    A piece of a channel's bytes (up to `PIECE`) is packed with zlib given the region
    of the capture its bytes were read from as a dictionary: deflate then refers to the
    capture for them (3 bytes or so for each run of bytes read), and the sidecar keeps
    only those references. The region is found by looking for a row's bytes in the
    capture, after where the bytes before were found: a row of the next few, the longest
    (the most telling), its first `NEEDLE` bytes. Any region is correct (deflate checks
    nothing but gives the same bytes back from the same region): one that does not hold
    the piece's bytes (a capture that is not a byte-for-byte recording: text logs) only
    packs them worse, as plain zlib. The capture must stay as it was: a sidecar is used
    only while the capture's size, time and head are those it was written against, and
    each block's bytes carry their own CRC-32."""

    def __init__(self, path: Path) -> None:
        self.map: mmap.mmap | None = None
        self.anchors: dict[int, tuple[int, int]] = {}  # channel: (stream byte, at or after)
        self.ratios: dict[int, float] = {}
        try:
            with path.open("rb") as handle:
                self.map = mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ)
        except (OSError, ValueError):  # (an empty file cannot be mapped)
            self.map = None

    def close(self) -> None:
        if self.map is not None:
            with contextlib.suppress(BufferError):
                self.map.close()
            self.map = None

    def release(self) -> None:
        """Let go of the capture's pages this process has touched (after each segment).
        They are the kernel's page cache, clean and reclaimable, but counted in the
        process's resident size while mapped: writing a day's sidecar showed the whole
        capture in it (the TUI on 30M frames peaked at 1.89 GB against 0.78 GB with the
        sidecar of before, 2026-12-06). Pages looked at again come back from the page
        cache (a minor fault each)."""
        if self.map is not None and hasattr(mmap, "MADV_DONTNEED"):
            with contextlib.suppress(OSError, ValueError):
                self.map.madvise(mmap.MADV_DONTNEED)

    def _locate(
        self, ch: int, share: bytes, start: int, offs: Sequence[int], lens: Sequence[int], row: int
    ) -> tuple[int, int] | None:
        """A row from `row` on found in the capture: (its row, where), or None."""
        capture = self.map
        if capture is None:
            return None
        anchor_s, anchor_f = self.anchors.get(ch, (0, 0))
        # the four longest of the next 16 rows (a long row may be cut by a read's end)
        near = range(row, min(row + 16, len(offs)))
        for q in sorted(near, key=lens.__getitem__, reverse=True)[:4]:
            size = min(lens[q], NEEDLE)
            if size < 6:
                continue
            o = offs[q] - start
            low = anchor_f + max(0, offs[q] - anchor_s)  # its bytes come after those before
            far = low + (1 << 16) + min(8 * max(0, offs[q] - anchor_s), 1 << 20)
            where = capture.find(share[o : o + size], low, far)
            if where >= 0:
                return q, where
        return None

    def pieces(
        self, ch: int, share: bytes, start: int, offs: Sequence[int], lens: Sequence[int]
    ) -> list[tuple[int, int, int, bytes]]:
        """The pieces of `share` (the block's bytes of channel `ch`, from byte `start`
        of its stream), packed: (bytes, region, region's length, packed). `offs` and
        `lens`: the block's rows of the channel (offsets in the stream, lengths)."""
        end = start + len(share)
        cuts: list[tuple[int, int]] = []  # (stream byte, where in the capture or -1)
        s, where, row = start, -1, 0
        # rows that begin before the share (the answer to a row of the block before)
        row = bisect_left(offs, start)
        got = self._locate(ch, share, start, offs, lens, row) if self.map is not None else None
        ratio = self.ratios.get(ch, 2.0)
        if got is not None and offs[got[0]] > s:
            # the share's first bytes are a little before the row found: its region
            # starts early enough for them (a region too long only misses references)
            anchor_s, anchor_f = self.anchors.get(ch, (0, 0))
            early = got[1] - int(ratio * (offs[got[0]] - s)) - 256
            where = max(early, anchor_f + max(0, s - anchor_s), 0)
            if where > got[1]:
                where = -1
        while s < end:
            if got is not None and offs[got[0]] == s:
                where = got[1]
                self.anchors[ch] = (s, where)
            cuts.append((s, where))
            step = int(max(min(1024, PIECE), min(PIECE, (WINDOW - 4096) / ratio)))
            row = bisect_left(offs, s + step, row)
            got = self._locate(ch, share, start, offs, lens, row) if row < len(offs) else None
            e = offs[got[0]] if got is not None else min(end, s + PIECE)
            if got is not None and e <= s:
                got, e = None, min(end, s + PIECE)
            if got is not None and where >= 0 and got[1] > where:
                ratio = max(1.0, (got[1] - where) / (e - s))
            s, where = min(e, end), -1
        self.ratios[ch] = ratio
        out = []
        for k, (s, where) in enumerate(cuts):
            e = cuts[k + 1][0] if k + 1 < len(cuts) else end
            data = memoryview(share)[s - start : e - start]
            span = 0
            if where >= 0 and self.map is not None:
                after = cuts[k + 1][1] if k + 1 < len(cuts) else -1
                far = after + NEEDLE if after > where else where + int(ratio * len(data)) + 4096
                span = min(far - where, WINDOW, len(self.map) - where)
            if span > 0 and self.map is not None:
                region = memoryview(self.map)[where : where + span]  # (not copied)
                packer = zlib.compressobj(LEVEL, zlib.DEFLATED, -15, zdict=region)
            else:
                where, span = -1, 0
                packer = zlib.compressobj(LEVEL, zlib.DEFLATED, -15)
            out.append((len(data), where, span, packer.compress(data) + packer.flush()))
        return out


def _pack_block(
    store: FrameStore,
    a: int,
    b: int,
    pieces: list[list[int]],
    parts: list[memoryview],
    at: dict[int, int],
    base: int,
    bases: Mapping[int, int],
    referrer: _Referrer,
) -> list[bytes]:
    """Rows `a`..`b` of the store as written: the block's table, its packed columns,
    then its packed pieces of bytes. `parts` as `_block_parts` gives them (offsets and
    partners numbered in the whole capture), `at`: where each channel's share starts in
    the store's stream."""
    n = b - a
    col = {name: bytes(parts[k]) for k, name in enumerate(COLUMNS)}
    packed = _pack_columns(col, n, base + a)
    offset = memoryview(col["offset"]).cast("Q")
    length = memoryview(col["length"]).cast("H")
    channels = store.channel[a:b].tobytes()
    present = set(channels)
    table = []
    crc = 0
    packed_pieces: list[bytes] = []
    offs: Sequence[int]
    lens: Sequence[int]
    for k, (ch, _size) in enumerate(pieces):
        share = bytes(parts[len(COLUMNS) + k])
        crc = zlib.crc32(share, crc)
        if present == {ch}:
            offs, lens = offset, length
        else:
            mask = channels.translate(marking((ch,)))
            offs = array("Q", compress(offset, mask))
            lens = array("H", compress(length, mask))
        listed = referrer.pieces(ch, share, bases.get(ch, 0) + at[ch], offs, lens)
        table.append(_COUNT.pack(len(listed)))
        for size, where, span, data in listed:
            table.append(_PIECE.pack(size, where, span, len(data)))
            packed_pieces.append(data)
    head = _BLOCK_HEAD.pack(crc, len(pieces)) + _SIZES.pack(*map(len, packed))
    return [head + b"".join(table), *packed, *packed_pieces]


def _pack_tail(values: array[float]) -> bytes:
    """Latencies or request times: in byte planes, with zlib."""
    return _pack(_planes(values.tobytes(), 8))


def _unpack_tail(packed: bytes, count: int) -> array[float]:
    out = array("d")
    out.frombytes(_unplanes(_unpack(packed, 8 * count), 8))
    return out


class Tail:
    """A sidecar's tail, its CRC-32 checked, read a piece at a time: part `k` (a unit's
    latencies, then its request times, in the order `_tail` writes them) holds
    `counts[k]` values in pieces of TAIL_PIECE, `sizes[k]` their packed lengths, from
    `start` in `handle` on."""

    def __init__(self, handle: Any, start: int, sizes: list[list[int]], counts: list[int]):
        self.handle, self.sizes, self.counts = handle, sizes, counts
        self.starts = list(accumulate((sum(part) for part in sizes), initial=start))

    def part(self, k: int) -> Iterator[array[float]]:
        """Part `k`'s values, a piece at a time."""
        at, left = self.starts[k], self.counts[k]
        for size in self.sizes[k]:
            self.handle.seek(at)
            at += size
            count = min(TAIL_PIECE, left)
            left -= count
            yield _unpack_tail(self.handle.read(size), count)

    def whole(self, k: int) -> array[float]:
        """Part `k`'s values in one array."""
        out = array("d")
        for values in self.part(k):
            out.extend(values)
        return out


# -------------------------------------------------------------------------- reading


class DamagedError(Exception):
    """A block of a sidecar failed its checks after rows before it were handed out (to
    `progress` with `shown`): they stay, so the capture cannot be indexed again in the
    same session. The sidecar is not read again by this process."""


_refused: set[tuple[str, int, int]] = set()  # damaged sidecars: path, size, mtime


def _stamp(handle: Any, candidate: Path) -> tuple[str, int, int]:
    st = os.fstat(handle.fileno())
    return (str(candidate), st.st_size, st.st_mtime_ns)


Progress = Callable[[int, int], None]


def load(
    state: SessionState,
    capture: Capture,
    path: Path,
    key: str,
    progress: Progress | None = None,
    should_stop: Callable[[], bool] | None = None,
    shown: bool = False,
    segment: Callable[[], None] | None = None,
    opened: Callable[[Path, int, int, dict[str, Any]], None] | None = None,
) -> Path | None:
    """Fill a session's `state` and `capture` from a sidecar of `path` that still fits;
    its path, or None (nothing was changed) when there is none.

    `segment`: the rows are not kept. After each block but the last, `segment()` is
    called with the rows in the store (row `i` is row `state.base + i` of the capture,
    offsets counted from `state.stream_base`), then they are dropped, as a windowed
    `Session.ingest` drops its segments; the last block's rows stay. Rows handed to it
    are never taken back: a damaged block after the first raises `DamagedError`. No pair
    is cut: where the next block holds the answer to a request in the store (a block of
    a segment ends at `BLOCK` rows, wherever that is), its rows join the store's instead
    (`_awaited`), so that every row handed on is paired as in one store.

    The rows come block by block, each checked (CRC-32, rows inside their bytes) before
    it joins the store, and `progress(bytes, rows)` is called after each block, the
    first one included: rows below `rows` are complete (the annotator has seen them with
    `shown`). The statistics, warnings and notes come after the last block. A damaged
    block takes back the rows before it, unless `shown` (another thread may be showing
    them): then `DamagedError` is raised. `should_stop()` true between blocks: return with
    the rows read so far.

    `opened(path, fd, start, header)`: the sidecar found to fit, before its first block
    is read: an open descriptor of it (valid during the call: `os.dup` it to keep it),
    where its first block starts, and its header (`sniffer.session.paged.PagedStore` reads its
    rows from there)."""
    who = identity(path)
    if who is None:
        return None
    try:
        source = path.open("rb")  # (pieces of bytes are read from it)
    except OSError:
        return None
    with source:
        return _load(
            state, capture, path, key, who, source.fileno(),
            progress, should_stop, shown, segment, opened,
        )  # fmt: skip


def _load(
    state: SessionState,
    capture: Capture,
    path: Path,
    key: str,
    who: dict[str, Any],
    source: int,
    progress: Progress | None,
    should_stop: Callable[[], bool] | None,
    shown: bool,
    segment: Callable[[], None] | None,
    opened: Callable[[Path, int, int, dict[str, Any]], None] | None,
) -> Path | None:
    for candidate in sidecars(path):
        sweep(candidate.parent)  # what killed writers left (see the module doc)
        try:
            handle = candidate.open("rb")
        except OSError:
            continue
        with handle:
            try:
                stamp = _stamp(handle, candidate)
                found = None if stamp in _refused else _header(handle, key, who, stamp[1])
            except (OSError, ValueError, KeyError, TypeError, OverflowError, EOFError):
                continue
            if found is None:
                continue
            header, counts = found
            if opened is not None:  # (with the capture's descriptor, valid during the call)
                opened(candidate, handle.fileno(), handle.tell(), dict(header, capture_fd=source))
            filling = _Filling(
                state, capture, header, handle, progress, shown, who["size"], segment, source
            )
            try:
                if filling.run(should_stop):
                    tail = filling.tail(counts)
                    if tail is not None:
                        filling.finish(tail)
                        return candidate
                if filling.stopped:
                    return candidate
            except (OSError, ValueError, KeyError, TypeError, OverflowError, EOFError, zlib.error):
                pass
            _refused.add(stamp)
            if filling.handed_out:
                raise DamagedError(f"{candidate}: damaged after {len(state.store):,} rows")
            filling.undo()
    return None


def _header(
    handle: Any, key: str, who: dict[str, Any], file_size: int
) -> tuple[dict[str, Any], list[int]] | None:
    """The header of a sidecar that fits the capture and `key`, and the lengths of its
    statistics' arrays; None if it does not fit or its length is not what the header
    says."""
    if handle.read(len(MAGIC)) != MAGIC:
        return None
    prefix = handle.read(_PREFIX.size)
    if len(prefix) != _PREFIX.size:
        return None  # cut inside the header's length and CRC (#30, found by tests/fuzz)
    size, crc = _PREFIX.unpack(prefix)
    if size > 1 << 30:
        return None
    blob = handle.read(size)
    if len(blob) != size or zlib.crc32(blob) != crc:
        return None
    header = json.loads(blob)
    if header.get("format") != FORMAT or header.get("key") != key:
        return None
    if header.get("capture") != who:
        return None  # stale: the capture changed since it was indexed
    model = FrameStore()
    for name in COLUMNS:
        if header["columns"].get(name) != getattr(model, name).typecode:
            return None
    body = 0
    rows = 0
    for count, _pieces, _crc, length in header["blocks"]:
        rows += int(count)
        body += int(length)
    if rows != int(header["rows"]) or any(int(s) < 0 for _ch, s in header["streams"]):
        return None
    counts = [
        int(u[name]) for u in header["stats"]["units"] for name in ("latencies", "request_times")
    ]
    tail = [[int(length) for length in part] for part in header["tail"]]
    if len(tail) != len(counts) or any(
        len(part) != -(-count // TAIL_PIECE) or min(part, default=0) < 0
        for part, count in zip(tail, counts, strict=True)
    ):
        return None
    start = len(MAGIC) + _PREFIX.size + size
    if start + body + sum(map(sum, tail)) != file_size:
        return None  # cut short, or more than the header says
    return header, counts


class _Filling:
    """Rows going from a sidecar into a session, a block at a time."""

    def __init__(
        self,
        state: SessionState,
        capture: Capture,
        header: dict[str, Any],
        handle: Any,
        progress: Progress | None,
        shown: bool,
        capture_size: int,
        segment: Callable[[], None] | None = None,
        source: int = -1,
    ) -> None:
        self.state, self.capture, self.header, self.handle = state, capture, header, handle
        self.source = source  # the capture, where the pieces of bytes refer to
        self.first_row = 0  # the next block's first row in the capture
        self.progress, self.shown = progress, shown
        self.segment = segment
        self.notes: dict[int, str] = {}  # (with `segment`) those of rows still to come
        self.handed_out = False
        self.stopped = False
        store = state.store
        self.before = (store.stamps, store.resolution, store.fill_channel)
        self.named_before = (dict(store.peers), dict(store.servers))
        self.streams_before = {ch: len(data) for ch, data in store.streams.items()}
        self.rows = int(header["rows"])
        self.file_size = os.fstat(handle.fileno()).st_size
        self.capture_size = capture_size

    def run(self, should_stop: Callable[[], bool] | None) -> bool:
        """Read every block; False if one is damaged or `should_stop` said so."""
        header, store = self.header, self.state.store
        # what the rows need to be shown: their notes, times and bytes' channels
        notes = {int(i): str(text) for i, text in header["notes"].items()}
        if self.segment is None:
            store.notes.update(notes)
        else:
            self.notes = dict(sorted(notes.items()))
        store.stamps = Stamp[header["stamps"]]
        store.resolution = float(header["resolution"])
        store.fill_channel = int(header["fill_channel"])
        store.peers.update(channel_texts(header["peers"]))
        store.servers.update(channel_texts(header["servers"]))
        streams = {int(ch): int(size) for ch, size in header["streams"]}
        for ch in streams:
            store.stream(ch)
        reach = {ch: len(store.streams[ch]) for ch in streams}
        state = self.state
        blocks = header["blocks"]
        for k, (count, pieces, crc, length) in enumerate(blocks):
            if k and self.segment is not None and not _awaited(store):
                # the rows before go (see `load`)
                self.segment()
                _drop(state)
                self.handed_out = True
            if not self._block(int(count), pieces, int(crc), int(length), streams, reach):
                return False
            if self.progress is not None:
                done = self.capture_size * self.handle.tell() // max(1, self.file_size)
                self.progress(done, state.base + len(store))
                # rows another thread shows cannot be taken back; counted ones can
                self.handed_out = self.handed_out or (self.shown and bool(len(store)))
            if should_stop is not None and should_stop():
                self.stopped = True
                return False
        bases = state.stream_base
        return all(
            bases.get(ch, 0) + len(store.streams[ch]) == size for ch, size in streams.items()
        )

    def _block(
        self,
        count: int,
        pieces: list[list[int]],
        crc: int,
        length: int,
        streams: dict[int, int],
        reach: dict[int, int],
    ) -> bool:
        store = self.state.store
        data = self.handle.read(length)
        if len(data) != length or zlib.crc32(data) != crc:
            return False  # damaged on the way
        packed = Packed(data, count, self.first_row, len(pieces))
        self.first_row += count
        columns: dict[str, memoryview] = {}  # checked where they are, then copied once
        for name in COLUMNS:
            columns[name] = memoryview(packed.column(name)).cast(getattr(store, name).typecode)
        added: list[tuple[int, bytes]] = []
        crc = 0
        for k, (ch, piece) in enumerate(pieces):
            ch, piece = int(ch), int(piece)
            if ch not in streams or reach[ch] + piece > streams[ch]:
                return False
            share = packed.share(k, self.source)
            if len(share) != piece:
                return False
            crc = zlib.crc32(share, crc)
            added.append((ch, share))
            reach[ch] += piece
        if crc != packed.bytes_crc:
            return False  # the capture's bytes are not those the sidecar was written from
        if count and not _consistent(columns, reach, self.rows):
            return False
        state = self.state
        if state.base or any(state.stream_base.values()):
            shifted = _local(columns, state.base, state.stream_base)
            if shifted is None:
                return False  # a row before the bytes dropped with the rows before
            columns = shifted
        if self.notes:
            end = state.base + len(store) + count
            while self.notes:
                i = next(iter(self.notes))
                if i >= end:
                    break
                store.notes[i - state.base] = self.notes.pop(i)
        # into the store's own objects: views (the TUI's reader) hold on to its columns
        for ch, piece_bytes in added:
            store.streams[ch] += piece_bytes
        for name in COLUMNS:
            getattr(store, name).frombytes(columns[name].cast("B"))
        if self.shown:
            self.state.annotator.update(store)  # before the rows are handed out
        return True

    def tail(self, counts: list[int]) -> Tail | None:
        """The per-unit latencies and request times, after the last block, checked (None:
        damaged; last, not first: they grow with the capture, and the first rows should
        not wait), to be unpacked a piece at a time as they are counted."""
        start = self.handle.tell()
        sizes = [[int(length) for length in part] for part in self.header["tail"]]
        crc = 0
        left = sum(map(sum, sizes))
        while left:
            chunk = self.handle.read(min(left, 1 << 20))
            if not chunk:
                return None
            crc = zlib.crc32(chunk, crc)
            left -= len(chunk)
        if crc != self.header["tail_crc32"]:
            return None
        return Tail(self.handle, start, sizes, counts)

    def finish(self, tail: Tail) -> None:
        """What needs every row: pairing's and the annotator's state, the statistics, the
        warnings."""
        state, capture, header = self.state, self.capture, self.header
        n = len(state.store)
        state.framed_already(header["mode"])
        state.warnings[:] = [str(w) for w in header["session_warnings"]]
        state.notes[:] = [str(w) for w in header["session_notes"]]
        state.chunks = int(header["chunks"])
        capture.warnings[:] = [str(w) for w in header["capture_warnings"]]
        capture.data_bytes = int(header["data_bytes"])
        capture.finished = True
        for ch, label in header["channels"].items():
            capture.info.channels.setdefault(int(ch), str(label))
        state.annotator.update(state.store)  # all rows, or those after the last block
        # (the stamps were measured when the sidecar was written: nothing waits for them)
        state.pipeline.clock.learning = False
        _restore_stats(state, header["stats"], tail, n)

    def undo(self) -> None:
        """Take back the rows (and the little before them) of a damaged sidecar."""
        store = self.state.store
        for name in COLUMNS:
            del getattr(store, name)[:]
        for ch in list(store.streams):
            if ch in self.streams_before:
                del store.streams[ch][self.streams_before[ch] :]
            else:
                del store.streams[ch]
        store.notes.clear()
        store.stamps, store.resolution, store.fill_channel = self.before
        for named, before in zip((store.peers, store.servers), self.named_before, strict=True):
            named.clear()
            named.update(before)


def channel_texts(table: Any) -> dict[int, str]:
    """A header's table of channel -> text (`peers`, `servers`)."""
    return {int(ch): str(text) for ch, text in table.items()}


def _local(
    columns: dict[str, memoryview], base: int, bases: Mapping[int, int]
) -> dict[str, memoryview] | None:
    """A block's columns with rows and offsets numbered from the rows and bytes still
    in the store (`base` rows, each channel's `bases` bytes dropped before it); None if
    a row points at bytes already dropped."""
    offset, channel = columns["offset"], columns["channel"]
    present = set(channel.tobytes())
    if len(present) == 1:
        by = bases.get(next(iter(present)), 0)
        if _bounds(offset, "Q")[0] < by:
            return None
        shifted = _plus(offset, -by)
    else:
        local = array("Q")
        for o, ch in zip(offset, channel, strict=True):
            by = bases.get(ch, 0)
            if o < by:
                return None
            local.append(o - by)
        shifted = local.tobytes()
    # a partner in a block dropped before (a request at the end of the block before, its
    # answer here) is given as none: the rows a partner points at must exist
    out = dict(columns)  # (the typecodes the header was checked for)
    out["offset"] = memoryview(shifted).cast("Q")
    if base:
        out["partner"] = memoryview(shifted_partners(columns["partner"], base, -base)).cast("i")
    return out


def _awaited(store: FrameStore) -> bool:
    """Whether a row of `store` is paired with a row still to come (its partner, in the
    store's numbering, at or past its end: the next block's)."""
    return len(store) > 0 and _bounds(store.partner, "i")[1] >= len(store)


def _drop(state: SessionState) -> None:
    """Forget the rows in the session's store (a windowed load, see `load`): they count
    in `state.base`, their bytes in `state.stream_base`."""
    store = state.store
    state.annotator.update(store)
    kinds = store.kind.tobytes()
    state.frames_before += len(kinds) - kinds.count(Kind.NOISE) - kinds.count(Kind.EVENT)
    for ch, data in store.streams.items():
        state.stream_base[ch] = state.stream_base.get(ch, 0) + len(data)
        del data[:]
    state.base += len(store)
    for name in COLUMNS:
        del getattr(store, name)[:]
    store.notes.clear()
    state.forget_annotation()


def _ends(offset: Any, length: Any) -> memoryview:
    """Each row's `offset + length` (offsets: 8-byte words, lengths: 2-byte words), added
    as two integers of the whole column (lengths spread to 8-byte words first, by
    bytes): a sum in C rather than a Python step a row. No word carries into the next
    (an offset and a length never reach 2**64)."""
    spread = bytearray(8 * len(length))
    raw = memoryview(length).cast("B")
    low = 0 if sys.byteorder == "little" else 6  # where a word's two low bytes are
    spread[low::8] = raw[0::2]
    spread[low + 1 :: 8] = raw[1::2]
    total = int.from_bytes(memoryview(offset).cast("B"), sys.byteorder)
    total += int.from_bytes(spread, sys.byteorder)
    return memoryview(total.to_bytes(len(spread), sys.byteorder)).cast("Q")


def _consistent(
    columns: Mapping[str, array[Any] | memoryview], streams: Mapping[int, int], n: int
) -> bool:
    """Rows that point inside their bytes (`streams`: the length of each channel's bytes)
    and at rows that exist (C-speed scans)."""
    channels = set(columns["channel"].tobytes())
    if not channels <= set(streams):
        return False
    offset, length, channel = columns["offset"], columns["length"], columns["channel"]
    if len(channels) == 1:
        if _bounds(_ends(offset, length), "Q")[1] > streams[channel[0]]:
            return False
    else:
        ends = map(operator.add, offset, length)
        if any(end > streams[ch] for end, ch in zip(ends, channel, strict=True)):
            return False
    partner = columns["partner"]
    low, high = _bounds(partner, "i")
    return bool(low >= -1 and high < n and _bounds(columns["kind"], "B")[1] < 8)


def _restore_stats(state: SessionState, saved: dict[str, Any], tail: Tail, n: int) -> None:
    stats = state.stats
    units = {}
    for part, u in enumerate(saved["units"]):
        unit = UnitStats(int(u["unit"]))
        unit.requests, unit.responses = int(u["requests"]), int(u["responses"])
        unit.exceptions.update({int(code): int(k) for code, k in u["exceptions"].items()})
        unit.timeouts, unit.check_errors = int(u["timeouts"]), int(u["check_errors"])
        unit.last_seen = float(u["last_seen"])
        unit.below_resolution, unit.unmeasured = int(u["below_resolution"]), int(u["unmeasured"])
        if stats.bounded:  # (a windowed replay: counted as it counts them, `Stats.bound`)
            unit.bound(stats.spill)
            tallies = unit.tallies
            assert tallies is not None
            for values in tail.part(2 * part):  # a piece at a time: memory flat in the day
                tallies.add_latencies(values)
            for values in tail.part(2 * part + 1):
                tallies.add_requests(values)
        else:
            unit.latencies, unit.request_times = tail.whole(2 * part), tail.whole(2 * part + 1)
        units[unit.unit] = unit
    stats.units.clear()
    stats.units.update(units)
    stats.noise_bytes, stats.noise_spans = int(saved["noise_bytes"]), int(saved["noise_spans"])
    stats.events = int(saved["events"])
    base = state.base  # rows dropped before the store's (a windowed load)
    stats._open = {int(i) - base for i in saved["open"] if 0 <= int(i) - base < n}
    stats.next = min(max(0, int(saved["next"]) - base), n)
    stats.update()  # rows after `next`, if any

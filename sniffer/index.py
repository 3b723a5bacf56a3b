"""Provides the sidecar index: a capture's framed and paired rows kept beside it.

Indexing a day's capture takes tens of seconds; reading the rows back takes a moment.
After a capture of at least `MIN_SIZE` bytes has been indexed to its end, its rows
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

A sidecar is data, never code (a header of JSON and raw columns): one that is damaged or
does not fit its capture is ignored. `MODSCOPE_NO_INDEX=1` (or `open_session(...,
index=False)`) neither reads nor writes one.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import operator
import os
import struct
import sys
import tempfile
import zlib
from array import array
from collections.abc import Mapping
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sniffer import __version__
from sniffer.model import Stamp

if TYPE_CHECKING:
    from sniffer.session import Session
    from sniffer.sources import Capture

MAGIC = b"MODSCOPE-INDEX\n\0"
FORMAT = 1
SUFFIX = ".modscope-index"
MIN_SIZE = 4 << 20  # smaller captures index in about a second: no sidecar for them
HEAD = 1 << 16  # bytes of the capture hashed to tell it from another of the same size
COLUMNS: tuple[str, ...] = ("offset", "length", "t", "t_end", "kind", "unit", "fc", "flags")
COLUMNS += ("channel", "partner", "status")
_LENGTH = struct.Struct("<Q")


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


def settings_key(session: Session, options: Any, timeout: float | None) -> str:
    """What the rows of a capture depend on besides its bytes, as one hash."""
    registry = session.annotator.registry
    picture = [
        FORMAT,
        code_fingerprint(),
        _plain(options),
        timeout,
        [[code, _plain(registry[code])] for code in sorted(registry)],
        _plain(session.annotator.bindings),
    ]
    return hashlib.sha256(json.dumps(picture, sort_keys=True).encode()).hexdigest()


# -------------------------------------------------------------------------- writing


def save(session: Session, capture: Capture, path: Path, key: str) -> Path | None:
    """Write the sidecar of `path`; its location, or None when nowhere could take it."""
    who = identity(path)
    if who is None:
        return None
    store = session.store
    store.sync()
    n = len(store)
    columns = {name: getattr(store, name) for name in COLUMNS}
    streams = {str(ch): len(data) for ch, data in store.streams.items()}
    header = {
        "format": FORMAT,
        "key": key,
        "capture": who,
        "rows": n,
        "columns": {name: col.typecode for name, col in columns.items()},
        "streams": streams,
        "notes": {str(i): text for i, text in store.notes.items()},
        "stamps": store.stamps.name,
        "resolution": store.resolution,
        "fill_channel": store.fill_channel,
        "mode": session.pipeline.mode,
        "session_warnings": session.warnings,
        "session_notes": session.notes,
        "chunks": session.chunks,
        "capture_warnings": capture.warnings,
        "data_bytes": capture.data_bytes,
        "channels": {str(ch): label for ch, label in capture.info.channels.items()},
        "stats": _stats_header(session),
    }
    parts: list[Any] = [columns[name] for name in COLUMNS]
    parts += list(store.streams.values())
    for unit in session.stats.units.values():
        parts += [unit.latencies, unit.request_times]
    crc = 0
    for part in parts:
        crc = zlib.crc32(memoryview(part).cast("B"), crc)
    header["crc32"] = crc  # of everything after the header (about 1 GB/s)
    blob = json.dumps(header).encode()
    for target in sidecars(path):
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=".modscope-index-", dir=target.parent)
        except OSError:
            continue
        try:
            with os.fdopen(fd, "wb") as out:
                out.write(MAGIC)
                out.write(_LENGTH.pack(len(blob)))
                out.write(blob)
                for part in parts:
                    out.write(memoryview(part).cast("B"))
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)  # as any file the user writes (mkstemp: 0600)
            os.replace(tmp, target)
            return target
        except OSError:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
    return None


def _stats_header(session: Session) -> dict[str, Any]:
    """The per-unit statistics (recounting them costs about 0.5 us a row)."""
    stats = session.stats
    return {
        "next": stats.next,
        "noise_bytes": stats.noise_bytes,
        "noise_spans": stats.noise_spans,
        "events": stats.events,
        "open": sorted(stats._open),
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
                "latencies": len(u.latencies),
                "request_times": len(u.request_times),
            }
            for u in stats.units.values()
        ],
    }


# -------------------------------------------------------------------------- reading


def load(session: Session, capture: Capture, path: Path, key: str) -> Path | None:
    """Fill `session` and `capture` from a sidecar of `path` that still fits; its path,
    or None (nothing was changed) when there is none."""
    who = identity(path)
    if who is None:
        return None
    for candidate in sidecars(path):
        try:
            with candidate.open("rb") as handle:
                found = _read(handle, key, who)
        except (OSError, ValueError, KeyError, TypeError, OverflowError, EOFError):
            continue
        if found is not None:
            _restore(session, capture, *found)
            return candidate
    return None


def _read(
    handle: Any, key: str, who: dict[str, Any]
) -> tuple[dict[str, Any], dict[str, array[Any]], dict[int, bytearray]] | None:
    if handle.read(len(MAGIC)) != MAGIC:
        return None
    (size,) = _LENGTH.unpack(handle.read(_LENGTH.size))
    if size > 1 << 30:
        return None
    header = json.loads(handle.read(size))
    if header.get("format") != FORMAT or header.get("key") != key:
        return None
    if header.get("capture") != who:
        return None  # stale: the capture changed since it was indexed
    from sniffer.store import FrameStore

    n = int(header["rows"])
    model = FrameStore()
    columns: dict[str, array[Any]] = {}
    for name in COLUMNS:
        typecode = getattr(model, name).typecode
        if header["columns"].get(name) != typecode:
            return None
        col = array(typecode)
        col.fromfile(handle, n) if n else None
        columns[name] = col
    streams: dict[int, bytearray] = {}
    for ch, length in header["streams"].items():
        data = bytearray(handle.read(int(length)))
        if len(data) != int(length):
            return None
        streams[int(ch)] = data
    for unit in header["stats"]["units"]:
        for name in ("latencies", "request_times"):
            col = array("d")
            count = int(unit[name])
            col.fromfile(handle, count) if count else None
            unit[name] = col
    if handle.read(1):
        return None  # more than the header says: not ours
    crc = 0
    for col in columns.values():
        crc = zlib.crc32(memoryview(col).cast("B"), crc)
    for data in streams.values():
        crc = zlib.crc32(data, crc)
    for unit in header["stats"]["units"]:
        for name in ("latencies", "request_times"):
            crc = zlib.crc32(memoryview(unit[name]).cast("B"), crc)
    if crc != header.get("crc32"):
        return None  # damaged on the way
    if n and not _consistent(columns, streams, n):
        return None
    return header, columns, streams


def _consistent(columns: dict[str, array[Any]], streams: dict[int, bytearray], n: int) -> bool:
    """Rows that point inside their bytes and at rows that exist (C-speed scans)."""
    channels = set(columns["channel"].tobytes())
    if not channels <= set(streams):
        return False
    offset, length, channel = columns["offset"], columns["length"], columns["channel"]
    if len(channels) == 1:
        if max(map(operator.add, offset, length)) > len(streams[channel[0]]):
            return False
    elif any(offset[i] + length[i] > len(streams[channel[i]]) for i in range(n)):
        return False
    partner = columns["partner"]
    return bool(min(partner) >= -1 and max(partner) < n and max(columns["kind"]) < 8)


def _restore(
    session: Session,
    capture: Capture,
    header: dict[str, Any],
    columns: dict[str, array[Any]],
    streams: dict[int, bytearray],
) -> None:
    # into the store's own objects: views (the TUI's reader) hold on to its columns
    store = session.store
    store.streams.clear()
    store.streams.update(streams)
    for name, col in columns.items():
        target = getattr(store, name)
        del target[:]
        target.frombytes(memoryview(col).cast("B"))
        del col
    columns.clear()
    store.notes.clear()
    store.notes.update({int(i): str(text) for i, text in header["notes"].items()})
    store.stamps = Stamp[header["stamps"]]
    store.resolution = float(header["resolution"])
    store.fill_channel = int(header["fill_channel"])
    n = len(store)
    pipeline = session.pipeline
    pipeline.mode = header["mode"]
    pipeline.pairer.next = n
    pipeline._hint_checked = n
    session.warnings[:] = [str(w) for w in header["session_warnings"]]
    session.notes[:] = [str(w) for w in header["session_notes"]]
    session.chunks = int(header["chunks"])
    capture.warnings[:] = [str(w) for w in header["capture_warnings"]]
    capture.data_bytes = int(header["data_bytes"])
    capture.finished = True
    for ch, label in header["channels"].items():
        capture.info.channels.setdefault(int(ch), str(label))
    session.annotator.next = 0
    session.annotator.update(store)
    _restore_stats(session, header["stats"], n)


def _restore_stats(session: Session, saved: dict[str, Any], n: int) -> None:
    from sniffer.stats import UnitStats

    stats = session.stats
    stats.units.clear()
    for u in saved["units"]:
        unit = UnitStats(int(u["unit"]))
        unit.requests, unit.responses = int(u["requests"]), int(u["responses"])
        unit.exceptions.update({int(code): int(k) for code, k in u["exceptions"].items()})
        unit.timeouts, unit.check_errors = int(u["timeouts"]), int(u["check_errors"])
        unit.last_seen = float(u["last_seen"])
        unit.below_resolution, unit.unmeasured = int(u["below_resolution"]), int(u["unmeasured"])
        unit.latencies, unit.request_times = u["latencies"], u["request_times"]
        stats.units[unit.unit] = unit
    stats.noise_bytes, stats.noise_spans = int(saved["noise_bytes"]), int(saved["noise_spans"])
    stats.events = int(saved["events"])
    stats._open = {int(i) for i in saved["open"] if 0 <= int(i) < n}
    stats.next = min(int(saved["next"]), n)
    stats.update()  # rows after `next`, if any

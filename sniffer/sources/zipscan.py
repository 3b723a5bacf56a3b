"""Provides ZIP member reading that survives damage, for sigrok sessions cut short.

A complete archive is read through its central directory (`zipfile`). When that is
missing or broken (a file cut short loses it first), the members are found by walking
their local headers from the start, and a member cut short gives what its compressed
data still holds before the error.

Memory stays bounded whatever the archive claims: members are inflated a block at a
time (never more than the block size asked for at once, however well they compress),
the file itself is read from disk as needed, never held whole, and a member compressed
by any method other than stored or deflated (the two sigrok writes; zipfile inflates
bzip2 and LZMA in unbounded steps) is refused.
"""

from __future__ import annotations

import lzma
import struct
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

ZIP_ERRORS: tuple[type[Exception], ...] = (
    zipfile.BadZipFile,
    zlib.error,
    lzma.LZMAError,
    EOFError,
    OSError,
    ValueError,
    NotImplementedError,
    RuntimeError,
    KeyError,
    IndexError,
    OverflowError,
    struct.error,
)
_LOCAL = struct.Struct("<IHHHHHIIIHH")
_LOCAL_SIGNATURE = 0x04034B50
_DESCRIPTOR_SIGNATURE = b"PK\x07\x08"
_STORED, _DEFLATED = 0, 8
_METHODS = {_STORED: "stored", _DEFLATED: "deflated", 12: "bzip2", 14: "LZMA"}
READ_STEP = 1 << 20  # compressed bytes read from the file at a time
_INFLATE_STEP = 1 << 20  # bytes inflated at a time while looking for a member's end


class ArchiveError(Exception):
    """A member cannot be read (further); the message says where."""


class MemberTooLargeError(ArchiveError):
    """A member read whole holds more than the reader's limit."""


@dataclass(frozen=True, slots=True)
class _Local:
    name: str
    offset: int  # of the local header
    method: int
    start: int  # of the compressed data
    end: int  # of the compressed data, as far as the file goes
    complete: bool


def _method_error(name: str, offset: int, method: int) -> ArchiveError:
    known = _METHODS.get(method, "unknown")
    return ArchiveError(
        f"ZIP member {name!r} at byte offset {offset} uses compression method {method} "
        f"({known}); a sigrok session stores or deflates its members: re-save it with sigrok"
    )


class Archive:
    """Members of a ZIP file by name, read in blocks."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.warning = ""
        self._zip: zipfile.ZipFile | None = None
        self._file: BinaryIO | None = None
        self._locals: dict[str, _Local] = {}
        try:
            self._zip = zipfile.ZipFile(path)
            self._zip.namelist()
        except ZIP_ERRORS as exc:
            if self._zip is not None:
                self._zip.close()
            self._zip = None
            self._scan(path, exc)

    def _scan(self, path: Path, reason: Exception) -> None:
        try:
            self._file = path.open("rb")
            size = path.stat().st_size
            self._locals = {local.name: local for local in _walk_local_headers(self._file, size)}
        except OSError as exc:
            self.close()
            raise ArchiveError(f"cannot be read ({exc})") from None
        if not self._locals:
            self.close()
            raise ArchiveError(f"not a readable ZIP archive ({reason})")
        self.warning = (
            f"the ZIP directory is missing or broken ({reason}); members were found from "
            "their local headers (a file cut short?)"
        )

    def close(self) -> None:
        if self._zip is not None:
            self._zip.close()
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> Archive:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def names(self) -> list[str]:
        if self._zip is not None:
            return self._zip.namelist()
        return list(self._locals)

    def offset(self, name: str) -> int:
        """Byte offset of the member's local header in the file."""
        if self._zip is not None:
            info = self._zip.NameToInfo.get(name)
            return info.header_offset if info is not None else -1
        local = self._locals.get(name)
        return local.offset if local is not None else -1

    def read(self, name: str, limit: int) -> bytes:
        """The whole member; ArchiveError once it holds more than `limit` bytes (found
        while inflating it, whatever the archive says its size is)."""
        out = bytearray()
        for block in self.blocks(name, min(limit + 1, 1 << 20)):
            out += block
            if len(out) > limit:
                raise MemberTooLargeError(
                    f"ZIP member {name!r} at byte offset {self.offset(name)} is over "
                    f"{limit:,} bytes"
                )
        return bytes(out)

    def blocks(self, name: str, size: int) -> Iterator[bytes]:
        """The member's bytes in blocks of at most `size`; ArchiveError where it cannot
        go on."""
        if self._zip is not None:
            info = self._zip.NameToInfo.get(name)
            if info is not None and info.compress_type not in (_STORED, _DEFLATED):
                raise _method_error(name, info.header_offset, info.compress_type)
            try:
                with self._zip.open(name) as member:
                    while block := member.read(size):
                        yield block
            except ZIP_ERRORS as exc:
                raise ArchiveError(
                    f"corrupt ZIP member {name!r} at byte offset {self.offset(name)} ({exc})"
                ) from None
            return
        local = self._locals.get(name)
        if local is None:
            raise ArchiveError(f"no ZIP member {name!r}")
        yield from self._local_blocks(local, size)

    def _raw(self, local: _Local, step_size: int = READ_STEP) -> Iterator[bytes]:
        """The member's compressed bytes in steps, read from the file as they are used."""
        assert self._file is not None
        pos = local.start
        while pos < local.end:
            self._file.seek(pos)
            step = self._file.read(min(step_size, local.end - pos))
            if not step:
                return
            pos += len(step)
            yield step

    def _local_blocks(self, local: _Local, size: int) -> Iterator[bytes]:
        where = f"ZIP member {local.name!r} at byte offset {local.offset}"
        if local.method == _STORED:
            yield from self._raw(local, size)
        elif local.method == _DEFLATED:
            inflater = zlib.decompressobj(-15)
            try:
                for step in self._raw(local):
                    data = step
                    while data and not inflater.eof:
                        if out := inflater.decompress(data, size):
                            yield out
                        data = inflater.unconsumed_tail
                    if inflater.eof:
                        break
                if out := inflater.flush(size):
                    yield out
            except zlib.error as exc:
                raise ArchiveError(f"corrupt {where} ({exc})") from None
            if not inflater.eof:
                raise ArchiveError(f"{where} is cut short")
        else:
            raise _method_error(local.name, local.offset, local.method)
        if not local.complete:
            raise ArchiveError(f"{where} is cut short")


def _deflate_end(file: BinaryIO, start: int, size: int) -> int | None:
    """Where the deflate stream that begins at `start` ends (its compressed bytes are
    inflated a bounded step at a time and thrown away), or None if the file ends first."""
    inflater = zlib.decompressobj(-15)
    pos = start
    while pos < size:
        file.seek(pos)
        data = file.read(READ_STEP)
        if not data:
            return None
        pos += len(data)
        while data and not inflater.eof:
            inflater.decompress(data, _INFLATE_STEP)
            data = inflater.unconsumed_tail
        if inflater.eof:
            return pos - len(inflater.unused_data)
    return None


def _walk_local_headers(file: BinaryIO, size: int) -> Iterator[_Local]:
    """Members one after another from offset 0, as long as local headers follow."""
    pos = 0
    while pos + _LOCAL.size <= size:
        file.seek(pos)
        header = file.read(_LOCAL.size)
        if len(header) < _LOCAL.size:
            return
        fields = _LOCAL.unpack(header)
        signature, _version, flags, method = fields[:4]
        compressed, name_len, extra_len = fields[7], fields[9], fields[10]
        if signature != _LOCAL_SIGNATURE:
            return
        start = pos + _LOCAL.size + name_len + extra_len
        if start > size:
            return
        name = file.read(name_len).decode("utf-8", "replace")
        if flags & 0x08 or compressed == 0xFFFFFFFF:  # sizes follow the data
            if method != _DEFLATED:
                return
            try:
                end = _deflate_end(file, start, size)
            except zlib.error:
                return
            if end is None:
                yield _Local(name, pos, method, start, size, False)
                return
            yield _Local(name, pos, method, start, end, True)
            file.seek(end)
            pos = end + (16 if file.read(4) == _DESCRIPTOR_SIGNATURE else 12)
            continue
        end = start + compressed
        if end > size:
            yield _Local(name, pos, method, start, size, False)
            return
        yield _Local(name, pos, method, start, end, True)
        pos = end

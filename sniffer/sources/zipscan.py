"""Provides ZIP member reading that survives damage, for sigrok sessions cut short.

A complete archive is read through its central directory (`zipfile`). When that is
missing or broken (a file cut short loses it first), the members are found by walking
their local headers from the start, and a member cut short gives what its compressed
data still holds before the error.
"""

from __future__ import annotations

import lzma
import struct
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

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


class ArchiveError(Exception):
    """A member cannot be read (further); the message says where."""


@dataclass(frozen=True, slots=True)
class _Local:
    name: str
    offset: int  # of the local header
    method: int
    start: int  # of the compressed data
    end: int  # of the compressed data, as far as the file goes
    complete: bool


class Archive:
    """Members of a ZIP file by name, read in blocks."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.warning = ""
        self._zip: zipfile.ZipFile | None = None
        self._data = b""
        self._locals: dict[str, _Local] = {}
        try:
            self._zip = zipfile.ZipFile(path)
            self._zip.namelist()
        except ZIP_ERRORS as exc:
            self._zip = None
            self._scan(path, exc)

    def _scan(self, path: Path, reason: Exception) -> None:
        try:
            self._data = path.read_bytes()
        except OSError as exc:
            raise ArchiveError(f"cannot be read ({exc})") from None
        self._locals = {local.name: local for local in _walk_local_headers(self._data)}
        if not self._locals:
            raise ArchiveError(f"not a readable ZIP archive ({reason})")
        self.warning = (
            f"the ZIP directory is missing or broken ({reason}); members were found from "
            "their local headers (a file cut short?)"
        )

    def close(self) -> None:
        if self._zip is not None:
            self._zip.close()

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

    def read(self, name: str) -> bytes:
        return b"".join(self.blocks(name, 1 << 20))

    def blocks(self, name: str, size: int) -> Iterator[bytes]:
        """The member's bytes in blocks; ArchiveError where it cannot go on."""
        if self._zip is not None:
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

    def _local_blocks(self, local: _Local, size: int) -> Iterator[bytes]:
        where = f"ZIP member {local.name!r} at byte offset {local.offset}"
        raw = self._data[local.start : local.end]
        if local.method == _STORED:
            for pos in range(0, len(raw), size):
                yield raw[pos : pos + size]
        elif local.method == _DEFLATED:
            inflater = zlib.decompressobj(-15)
            try:
                for pos in range(0, len(raw), size):
                    if out := inflater.decompress(raw[pos : pos + size]):
                        yield out
                if out := inflater.flush():
                    yield out
            except zlib.error as exc:
                raise ArchiveError(f"corrupt {where} ({exc})") from None
            if not inflater.eof:
                raise ArchiveError(f"{where} is cut short")
        else:
            raise ArchiveError(f"{where} uses compression method {local.method}")
        if not local.complete:
            raise ArchiveError(f"{where} is cut short")


def _walk_local_headers(data: bytes) -> Iterator[_Local]:
    """Members one after another from offset 0, as long as local headers follow."""
    pos = 0
    while pos + _LOCAL.size <= len(data):
        fields = _LOCAL.unpack_from(data, pos)
        signature, _version, flags, method = fields[:4]
        compressed, name_len, extra_len = fields[7], fields[9], fields[10]
        if signature != _LOCAL_SIGNATURE:
            return
        start = pos + _LOCAL.size + name_len + extra_len
        if start > len(data):
            return
        name = data[pos + _LOCAL.size : pos + _LOCAL.size + name_len].decode("utf-8", "replace")
        if flags & 0x08 or compressed == 0xFFFFFFFF:  # sizes follow the data
            if method != _DEFLATED:
                return
            inflater = zlib.decompressobj(-15)
            try:
                inflater.decompress(data[start:])
            except zlib.error:
                return
            if not inflater.eof:
                yield _Local(name, pos, method, start, len(data), False)
                return
            end = len(data) - len(inflater.unused_data)
            yield _Local(name, pos, method, start, end, True)
            pos = end + (16 if data[end : end + 4] == _DESCRIPTOR_SIGNATURE else 12)
            continue
        end = start + compressed
        if end > len(data):
            yield _Local(name, pos, method, start, len(data), False)
            return
        yield _Local(name, pos, method, start, end, True)
        pos = end

"""The sidecar's packed format (#29): columns packed per block and the bytes packed
against the capture they were read from, so the sidecar is a small share of the
capture; a capture whose bytes changed under its sidecar is indexed again, and bytes
the capture does not hold as they were read still pack and read back."""

from __future__ import annotations

import os
from array import array
from pathlib import Path

import pytest

from sniffer.framing.store import COLUMNS, FrameStore
from sniffer.session import index
from tests.support.index import _ingested, _same


def test_the_sidecar_is_a_small_share_of_its_capture(capture: Path) -> None:
    fresh = _ingested(capture, index=False)
    _ingested(capture)
    side = Path(str(capture) + index.SUFFIX)
    # the bytes read are not copied but referred to in the capture; the header's room
    # (`RESERVE`) is most of what is left on a capture this small
    body = side.stat().st_size - index.RESERVE
    assert body < capture.stat().st_size // 4, (body, capture.stat().st_size)
    again = _ingested(capture)
    assert again.indexed_from is not None
    _same(fresh, again)


def test_a_capture_whose_bytes_changed_under_its_sidecar_is_indexed_again(
    capture: Path,
) -> None:
    before = _ingested(capture)
    data = bytearray(capture.read_bytes())
    st = capture.stat()
    store = before.store
    row = len(store) * 3 // 4
    frame = bytes(store.streams[0][store.offset[row] : store.offset[row] + store.length[row]])
    at = data.find(frame, index.HEAD)  # past the head that `identity` hashes
    assert at > 0 and len(frame) > 4
    for k in range(at, at + 2048):  # bytes the bus sent changed, size, time and head kept
        data[k] ^= 0x5A
    capture.write_bytes(bytes(data))
    os.utime(capture, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert index.identity(capture) is not None
    fresh = _ingested(capture, index=False)
    again = _ingested(capture)
    # the regions the sidecar refers to changed: its blocks' bytes fail their CRC-32
    assert again.indexed_from is None
    _same(fresh, again)
    assert _ingested(capture).indexed_from is not None  # rewritten


def _store(rows: int) -> FrameStore:
    store = FrameStore()
    data = bytes((k * 37 + k // 7) % 251 for k in range(rows * 9))
    store.streams[0] = bytearray(data)
    for k in range(rows):
        store.offset.append(9 * k)
        store.length.append(9)
        store.t.append(1.7e9 + k * 0.0123)
        store.t_end.append(1.7e9 + k * 0.0123 + 0.0009)
        store.kind.append(k % 3)
        store.unit.append(k % 5)
        store.fc.append(3)
        store.flags.append(k % 2)
        store.channel.append(0)
        store.partner.append(k + 1 if k % 2 == 0 else (k - 1 if k % 4 == 1 else -1))
        store.status.append(0)
    return store


@pytest.mark.parametrize("where", ["nothing", "the capture"])
def test_a_block_packs_and_unpacks_to_the_same_columns_and_bytes(
    tmp_path: Path, where: str
) -> None:
    rows = 3000
    store = _store(rows)
    capture = tmp_path / "capture.bin"
    if where == "nothing":  # a capture that does not hold the bytes as read (a text log)
        capture.write_bytes(b"# a log\n" * 5000)
    else:  # the bytes as read, 40 bytes of record around each 9
        stream = bytes(store.streams[0])
        capture.write_bytes(b"".join(b"H" * 40 + stream[k : k + 9] for k in range(0, rows * 9, 9)))
    referrer = index._Referrer(capture)
    a, b = 100, rows
    pieces = [[0, rows * 9 - 900]]
    parts = index._block_parts(store, a, b, pieces, {0: 900})
    packed = index._pack_block(store, a, b, pieces, parts, {0: 900}, 0, {}, referrer)
    referrer.close()
    data = b"".join(packed)
    block = index.Packed(data, b - a, a, 1)
    for name in COLUMNS:
        want = getattr(store, name)[a:b]
        got = array(want.typecode)
        got.frombytes(block.column(name))
        assert got == want, name
    with capture.open("rb") as handle:
        assert block.share(0, handle.fileno()) == bytes(store.streams[0][900:])
    referred = [where >= 0 for listed in block.pieces for _f, _s, where, _n, _p in listed]
    assert all(referred) if where == "the capture" else not any(referred)
    if where == "the capture":
        assert len(data) < len(store.streams[0]) // 4


def test_a_damaged_block_table_is_refused(tmp_path: Path) -> None:
    store = _store(200)
    capture = tmp_path / "capture.bin"
    capture.write_bytes(bytes(store.streams[0]))
    referrer = index._Referrer(capture)
    pieces = [[0, 200 * 9]]
    parts = index._block_parts(store, 0, 200, pieces, {0: 0})
    data = b"".join(index._pack_block(store, 0, 200, pieces, parts, {0: 0}, 0, {}, referrer))
    referrer.close()
    with pytest.raises(ValueError):
        index.Packed(data[:-1], 200, 0, 1)
    with pytest.raises(ValueError):
        index.Packed(data, 200, 0, 2)  # a block of other channels


def _resident_kb(path: Path) -> int | None:
    """kB of `path`'s mapping(s) resident in this process (/proc/self/smaps), None when
    it is not mapped."""
    found: int | None = None
    mapped = False
    for line in Path("/proc/self/smaps").read_text().splitlines():
        if line[:1].isalnum() and "-" in line.split(" ", 1)[0]:  # a mapping's first line
            mapped = line.rstrip().endswith(str(path))
        elif mapped and line.startswith("Rss:"):
            found = (found or 0) + int(line.split()[1])
    return found


@pytest.mark.skipif(not Path("/proc/self/smaps").exists(), reason="needs Linux's smaps")
def test_writing_the_sidecar_leaves_no_page_of_the_capture_resident(
    capture: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the writer maps the capture to find each piece's region; the pages it looked at
    # are the page cache's, but were counted in the process's resident size until it
    # closed: a day's capture (1.3 GB) showed in the TUI's peak memory
    seen: list[int | None] = []
    add = index.Writer.add

    def counted(self: index.Writer, state: object) -> None:
        add(self, state)  # type: ignore[arg-type]
        seen.append(_resident_kb(capture))

    monkeypatch.setattr(index.Writer, "add", counted)
    _ingested(capture)
    assert seen and all(kb is not None for kb in seen)  # mapped while written
    assert seen == [0] * len(seen)

"""What the pcapng export of a capture a segment at a time (sniffer/cli/export.py, #29)
needs of the exporter, with either core: the largest move of a packet's time found a
segment at a time (`Moves`, sniffer/_core.c: export_moved with the frame before carried
in) is that of one store of every row, and the transaction ids count from the
segment's first row (`PcapExporter.base`, export_rows' `base`), modulo 65536."""

from __future__ import annotations

import io
import random
import struct
from itertools import pairwise

import pytest

from sniffer import core
from sniffer.framing.store import COLUMNS, FrameStore
from sniffer.meaning.describe import Describer
from sniffer.model import LineSettings
from sniffer.outputs.export import Moves, PcapExporter, largest_move
from sniffer.sources.linktypes import MBAP_HEADER, parse_upper_pdu
from sniffer.vocab import Kind
from tests.core.test_core_export import random_capture
from tests.support.core import running
from tests.support.random_rows import random_store

compiled = pytest.mark.skipif(core.FAST is None, reason="the compiled core is not built")
LINE = LineSettings(baud=19200, bytesize=8, parity="E", stopbits=1, mode="rtu")


def _part(store: FrameStore, a: int, b: int) -> FrameStore:
    """Rows `a` to `b` in a store of their own (the columns `largest_move` reads)."""
    part = FrameStore(store.streams)
    for name in COLUMNS:
        getattr(part, name).extend(getattr(store, name)[a:b])
    return part


@pytest.mark.parametrize("fast", [None, core.FAST], ids=["python", "compiled"])
def test_moves_a_segment_at_a_time_are_those_of_the_whole(fast: object) -> None:
    """Random rows, many of them closer than t3.5 (a frame squeezed after another moves
    when read back), cut anywhere: the segments' moves, the frame before carried from
    one to the next, are the whole store's; taken apart they are not always."""
    apart = 0  # captures whose moves a segment at a time without the carry differ
    for seed in range(10):
        rng = random.Random(seed)
        store = random_store(rng, 300, odd_framing=True)
        cuts = [0, *sorted(rng.sample(range(1, len(store)), 30)), len(store)]
        parts = [_part(store, a, b) for a, b in pairwise(cuts)]
        with running(fast):  # type: ignore[arg-type]
            want = largest_move(store, LINE)
            moves = Moves(LINE)
            for part in parts:
                moves.add(part)
            alone = max(largest_move(part, LINE)[0] for part in parts)
        assert (moves.moved, moves.last) == want and want[1] is not None
        apart += alone != want[0]
    assert apart


@compiled
def test_both_cores_agree_on_the_moves() -> None:
    store = random_store(random.Random(3), 2000, odd_framing=True)
    for last in (None, -1.0, 1e9):
        with running(None):
            python = largest_move(store, LINE, last)
        assert largest_move(store, LINE, last) == python
    assert largest_move(FrameStore(), LINE, 2.5) == (0.0, 2.5)


_BLOCK = struct.Struct("<II")  # a pcapng block's type and length
_EPB = 6


def _ids(data: bytes) -> list[int | None]:
    """The MBAP transaction id of each packet of an export, in order (None: a packet
    for another dissector than Modbus/TCP's)."""
    ids: list[int | None] = []
    at = 0
    while at < len(data):
        kind, size = _BLOCK.unpack_from(data, at)
        if kind == _EPB:
            captured = struct.unpack_from("<I", data, at + 20)[0]
            record = parse_upper_pdu(data[at + 28 : at + 28 + captured])
            assert record is not None
            mbtcp = record.dissector == "mbtcp"
            ids.append(MBAP_HEADER.unpack_from(record.pdu)[0] if mbtcp else None)
        at += size
    return ids


@compiled
@pytest.mark.parametrize("base", [7, 65_530])
def test_transaction_ids_count_from_the_segments_first_row(base: int) -> None:
    """With `base`, the compiled core writes what the Python one writes (templates and
    rows it has none for alike), and each request's id is its row number in the
    capture, `base` plus its row in the store, modulo 65536."""
    store, annotator = random_capture(base, 600, True)
    out = []
    for fast in (None, core.FAST):
        data = io.BytesIO()
        with running(fast):
            exporter = PcapExporter(data, Describer(store, annotator), LINE)
            exporter.base = base
            exporter.write(range(len(store)))
        out.append(data.getvalue())
    assert out[0] == out[1]
    ids = _ids(out[0])
    assert len(ids) == len(store)
    requests = [i for i in range(len(store)) if store.kind[i] == Kind.REQUEST]
    assert requests and all(ids[i] in ((base + i) % 65536, None) for i in requests)
    assert sum(ids[i] == (base + i) % 65536 for i in requests) > len(requests) / 2

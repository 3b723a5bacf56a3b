"""Random frame stores for the tests that hold the column-wise scans (statistics, poll
cycle, baud check, annotation) to their row-by-row definitions.

The rows are made directly, not framed from bytes, so that every column takes values a
framer seldom gives: bad checks, ASCII and Modbus TCP frames, several channels, noise
and events anywhere, answers with and without a partner, every status, latencies that
are negative, zero, below a microsecond or long.
"""

from __future__ import annotations

import random

from dissectors.checks import ascii_frame, with_crc
from sniffer.framing.store import FrameStore
from sniffer.model import Stamp
from sniffer.vocab import Flag, Kind, Status

# requests a master repeats (reads and writes), by unit byte first
REPEATED = [
    bytes.fromhex("0103000a0002"),
    bytes.fromhex("010400000001"),
    bytes.fromhex("020100100008"),
    bytes.fromhex("020200000010"),
    bytes.fromhex("030300000002"),
    bytes.fromhex("030300010002"),
    bytes.fromhex("0308000000ff"),  # FC 8: no table, kept apart by its bytes
    bytes.fromhex("0311"),  # FC 17: too short for an address
    bytes.fromhex("002b0e0100"),  # broadcast, FC 43
]


def write_request(rng: random.Random, unit: int) -> bytes:
    """A write with random values (the same request with other values, or damaged)."""
    fc = rng.choice((5, 6, 15, 16))
    address = rng.choice((0, 20, 300, 0xFFFF))
    if fc == 5:
        value = rng.choice((b"\xff\x00", b"\x00\x00", b"\x12\x34"))
        body = bytes([unit, fc]) + address.to_bytes(2, "big") + value
    elif fc == 6:
        body = bytes([unit, fc]) + address.to_bytes(2, "big") + rng.randbytes(2)
    else:
        quantity = rng.choice((1, 2, 3, 9, 0, 200))
        need = 2 * quantity if fc == 16 else (quantity + 7) // 8
        count = need if rng.random() < 0.8 else rng.randrange(0, 12)
        data = rng.randbytes(count if rng.random() < 0.9 else max(0, count - 1))
        head = bytes([unit, fc]) + address.to_bytes(2, "big") + quantity.to_bytes(2, "big")
        body = head + bytes([count & 0xFF]) + data
    if rng.random() < 0.05:
        body = body[: rng.randrange(2, len(body))]  # cut short
    return body


def random_store(
    rng: random.Random,
    rows: int,
    *,
    channels: int = 1,
    stamps: Stamp = Stamp.READ_END,
    resolution: float = 0.016,
    odd_framing: bool = False,
) -> FrameStore:
    """`rows` random rows. `odd_framing`: some frames are ASCII or Modbus TCP."""
    store = FrameStore()
    store.stamps = stamps
    store.resolution = resolution
    t = 0.0
    open_request: dict[int, int] = {}  # channel -> row of a request waiting
    for _ in range(rows):
        channel = rng.randrange(channels)
        stream = store.stream(channel)
        t += rng.choice((0.0, 0.0, 1e-7, 0.002, 0.01, 0.25, 3.0))
        roll = rng.random()
        if roll < 0.03:
            store.add_event(t, "reconnected", channel)
            continue
        if roll < 0.08:
            offset = len(stream)
            stream += rng.randbytes(rng.randrange(1, 9))
            store.add_row(channel, offset, len(stream) - offset, t, t, int(Kind.NOISE), 0)
            continue
        waiting = open_request.get(channel)
        answer = waiting is not None and rng.random() < 0.7
        unit = rng.choice((1, 2, 3, 0, 250))
        if answer:
            assert waiting is not None
            req_raw = store.raw(waiting)
            unit = store.unit[waiting]
            fc = store.fc[waiting]
            if rng.random() < 0.1:
                body = bytes([unit, fc | 0x80, rng.choice((1, 2, 3, 4, 6))])
            elif fc == 3 and len(req_raw) >= 8:
                count = req_raw[5]
                body = bytes([unit, 3, 2 * count]) + rng.randbytes(2 * count)
            else:
                body = bytes([unit, fc]) + rng.randbytes(rng.randrange(0, 6))
            kind = Kind.EXCEPTION if body[1] & 0x80 else Kind.RESPONSE
        elif rng.random() < 0.5:
            body = rng.choice(REPEATED)
            body = bytes([unit]) + body[1:] if rng.random() < 0.5 else body
            kind = Kind.REQUEST
        else:
            body = write_request(rng, unit)
            kind = Kind.REQUEST
        if rng.random() < 0.03:
            kind = Kind.UNKNOWN
        flags = 0
        how = rng.random() if odd_framing else 1.0
        if how < 0.15:
            raw = ascii_frame(body)
            flags |= Flag.ASCII
        elif how < 0.3:
            tid = rng.randrange(0x10000).to_bytes(2, "big")
            raw = tid + b"\x00\x00" + len(body).to_bytes(2, "big") + body
            flags |= Flag.MBAP
        else:
            raw = with_crc(body)
        if rng.random() < 0.06:
            flags |= rng.choice((Flag.CHECK_BAD, Flag.NON_HEX, Flag.ENVELOPE_BAD))
        if rng.random() < 0.05:
            flags |= Flag.LINE_ERROR
        if rng.random() < 0.05:
            flags |= Flag.RETRY
        offset = len(stream)
        stream += raw
        end = t + rng.choice((0.0, 0.001, 0.004))
        store.add_row(channel, offset, len(raw), t, end, int(kind), int(flags))
        row = len(store) - 1
        if kind == Kind.REQUEST:
            open_request[channel] = row
            store.status[row] = rng.choice(list(Status))
        elif answer and waiting is not None:
            del open_request[channel]
            if rng.random() < 0.9:
                store.partner[row] = waiting
                store.partner[waiting] = row
                shift = rng.choice((0.0, -0.003, 1e-9, 0.02))
                store.t[row] = store.t_end[waiting] + shift
            store.status[row] = store.status[waiting] = rng.choice(list(Status))
    store.sync()
    return store

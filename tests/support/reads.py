"""Provides helpers shared by tests (moved from test_bulk_reads.py)."""

from __future__ import annotations

import struct
from pathlib import Path

from hypothesis import strategies as st

from sniffer.model import LineSettings
from sniffer.sources.linktypes import (
    LINKTYPE_RTAC_SERIAL,
    LINKTYPE_USER0,
    LINKTYPE_WIRESHARK_UPPER_PDU,
    RTAC_CAPTURE_DATA_LOST,
    RTAC_DATA_RX_START,
    RTAC_DATA_TX_START,
    RTAC_FRAMING_ERROR,
)
from sniffer.sources.pcapng_writer import describe_interface, rtac_record
from sniffer.sources.synth import polling_frames

T0 = 1_714_564_800.0


LINE = LineSettings(baud=19200, bytesize=8, parity="E", stopbits=1, mode="rtu")


FRAMES = [f.raw for f in polling_frames(400, line=LINE, seed=7)]


def _opt(order: str, code: int, value: bytes) -> bytes:
    return struct.pack(order + "HH", code, len(value)) + value + b"\0" * (-len(value) % 4)


def _opts(order: str, items: list[bytes]) -> bytes:
    return b"".join(items) + struct.pack(order + "HH", 0, 0) if items else b""


def _block(order: str, block_type: int, body: bytes) -> bytes:
    total = 12 + len(body)
    return struct.pack(order + "II", block_type, total) + body + struct.pack(order + "I", total)


def _shb(order: str) -> bytes:
    return _block(order, 0x0A0D0D0A, struct.pack(order + "IHHq", 0x1A2B3C4D, 1, 0, -1))


def _idb(order: str, linktype: int, described: bool) -> bytes:
    options = [_opt(order, 9, bytes([9]))]  # nanosecond stamps, as the recorder writes
    if described:
        options.append(_opt(order, 3, describe_interface(LINE).encode()))
    return _block(order, 1, struct.pack(order + "HHI", linktype, 0, 0) + _opts(order, options))


def _epb(order: str, iface: int, t: float, data: bytes, options: list[bytes]) -> bytes:
    ticks = round(t * 1e9)
    body = struct.pack(
        order + "IIIII", iface, ticks >> 32, ticks & 0xFFFFFFFF, len(data), len(data)
    )
    return _block(order, 6, body + data + b"\0" * (-len(data) % 4) + _opts(order, options))


# one packet: interface, what (data, event, sent data), EPB flags, comment, bytes, the
# header's lead over the packet time (negative: a header after the packet), time step
packet = st.tuples(
    st.integers(0, 2),
    st.sampled_from(["data", "data", "data", "event", "sent", "lost"]),
    st.sampled_from([None, None, 1, 2, 3]),
    st.sampled_from(["", "", "", "a note"]),
    st.integers(0, len(FRAMES) - 1),
    st.integers(1, 3),
    st.sampled_from([0.004, 0.004, 0.0, -0.5, 90.0]),
    st.floats(0.0, 0.3),
)


def _capture(
    order: str,
    linktypes: list[int],
    packets: list[tuple[int, str, int | None, str, int, int, float, float]],
    second_section: int,
) -> bytes:
    out = bytearray(_shb(order))
    for k, lt in enumerate(linktypes):
        out += _idb(order, lt, k == 0)
    t = T0
    for n, (iface, what, flags, comment, start, count, lead, step) in enumerate(packets):
        if n == second_section:
            out += _shb(order)
            for k, lt in enumerate(linktypes):
                out += _idb(order, lt, k == 0)
        t += step
        data = b"".join(FRAMES[start : start + count])
        event = {"data": RTAC_DATA_RX_START, "sent": RTAC_DATA_TX_START}.get(what)
        if event is None:
            event = RTAC_FRAMING_ERROR if what == "event" else RTAC_CAPTURE_DATA_LOST
            data = b""
        options = []
        if comment:
            options.append(_opt(order, 1, comment.encode()))
        if flags is not None:
            options.append(_opt(order, 2, struct.pack(order + "I", flags)))
        body = rtac_record(max(t - lead, 0.0), data, event=event)
        if linktypes[iface % len(linktypes)] != LINKTYPE_RTAC_SERIAL:
            body = data
        out += _epb(order, iface % (len(linktypes) + 1), t, body, options)
    return bytes(out)


# the interfaces of a pcapng capture: data records, plain reads, both, and a link type that
# is not batched (252, whose packets are not interpreted as reads here)
LINKTYPE_MIXES = [
    [LINKTYPE_RTAC_SERIAL],
    [LINKTYPE_RTAC_SERIAL] * 2,
    [LINKTYPE_RTAC_SERIAL, LINKTYPE_USER0],
    [LINKTYPE_USER0],
    [LINKTYPE_USER0] * 2,
    [LINKTYPE_USER0, LINKTYPE_WIRESHARK_UPPER_PDU],
]


damage = st.one_of(
    st.none(),
    st.tuples(st.just("cut"), st.integers(0, 10**6)),
    st.tuples(st.just("poke"), st.integers(0, 10**6), st.binary(min_size=1, max_size=4)),
)


def hurt_file(data: bytes, hurt: tuple[object, ...] | None) -> bytes:
    """The file cut short or with a few bytes overwritten, as `damage` drew."""
    out = bytearray(data)
    if hurt is not None and hurt[0] == "cut":
        del out[max(1, int(str(hurt[1])) % (len(out) + 1)) :]  # an empty file is refused
    elif hurt is not None:
        at = int(str(hurt[1])) % len(out)
        poke = hurt[2]
        assert isinstance(poke, bytes)
        out[at : at + len(poke)] = poke
    return bytes(out)


PCAP_MAGIC = {(False, False): 0xA1B2C3D4, (True, False): 0xA1B23C4D, (False, True): 0xA1B2CD34}


def pcap_capture(
    order: str,
    nanoseconds: bool,
    modified: bool,
    linktype: int,
    packets: list[tuple[int, str, int | None, str, int, int, float, float]],
) -> bytes:
    """A classic pcap file of the `packet` draws (one interface: no flags, no comments)."""
    magic = PCAP_MAGIC[nanoseconds, modified]
    out = bytearray(struct.pack(order + "IHHiIII", magic, 2, 4, 0, 0, 65535, linktype))
    t = T0
    for _iface, what, _flags, _comment, start, count, lead, step in packets:
        t += step
        data = b"".join(FRAMES[start : start + count])
        event = {"data": RTAC_DATA_RX_START, "sent": RTAC_DATA_TX_START}.get(what)
        if event is None:
            event = RTAC_FRAMING_ERROR if what == "event" else RTAC_CAPTURE_DATA_LOST
            data = b""
        body = rtac_record(max(t - lead, 0.0), data, event=event)
        if linktype != LINKTYPE_RTAC_SERIAL:
            body = data
        ticks = round(t * (1e9 if nanoseconds else 1e6))
        secs, frac = divmod(ticks, 10**9 if nanoseconds else 10**6)
        fields = (secs, frac, len(body), len(body)) + ((0, 0, 0, 0) if modified else ())
        out += struct.pack(order + ("IIIIIHBB" if modified else "IIII"), *fields) + body
    return bytes(out)


# the shapes a recording of reads is written in: pcapng link type 250 (RTAC records with
# the first byte's time) or 147 (the bytes alone), classic pcap of either
SHAPES = ["pcapng 250", "pcapng 147", "pcap 250", "pcap 147"]


def _recording(path: Path, reads: list[tuple[bytes, float]], shape: str = "pcapng 250") -> None:
    order = "<"
    linktype = LINKTYPE_RTAC_SERIAL if shape.endswith("250") else LINKTYPE_USER0
    if shape.startswith("pcap "):
        out = bytearray(struct.pack("<IHHiIII", PCAP_MAGIC[True, False], 2, 4, 0, 0, 0, linktype))
        for data, t in reads:
            body = data
            if linktype == LINKTYPE_RTAC_SERIAL:
                body = rtac_record(t - len(data) * LINE.char_time, data)
            secs, frac = divmod(round(t * 1e9), 10**9)
            out += struct.pack("<IIII", secs, frac, len(body), len(body)) + body
        path.write_bytes(bytes(out))
        return
    out = bytearray(_shb(order) + _idb(order, linktype, True))
    for data, t in reads:
        body = data
        if linktype == LINKTYPE_RTAC_SERIAL:
            body = rtac_record(t - len(data) * LINE.char_time, data)
        out += _epb(order, 0, t, body, [_opt(order, 2, b"\1\0\0\0")])
    path.write_bytes(bytes(out))


COLUMNS = [
    "offset",
    "length",
    "t",
    "t_end",
    "kind",
    "unit",
    "fc",
    "flags",
    "channel",
    "partner",
    "status",
]

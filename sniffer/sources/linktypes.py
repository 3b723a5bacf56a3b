"""Provides the pcap/pcapng numbers and serial link layouts shared by the reader and writer.

Three link types carry serial data:

- 147 (USER0): each packet is raw serial bytes as one read gave them.
- 250 (RTAC serial, Wireshark's `rtacser`): a 12-byte big-endian header, then the bytes:
  seconds (u32), microseconds (u32), event type (u8), control lines (u8), footer (u16).
- 252 (Wireshark upper PDU, `exported_pdu`): TLVs (u16 tag, u16 length, both big-endian),
  the dissector-name tag (12) carrying `mbrtu`, the end-of-options tag (0, length 0), then
  one RTU frame. modscope's default Wireshark export names `mbtcp` instead and adds
  address tags (IPv4 source 20 and destination 21, port type 24 = TCP, source port 25,
  destination port 26; values big-endian u32), then one Modbus/TCP ADU: the MBAP header
  (transaction id, protocol 0, length, unit) and the PDU. Wireshark's Modbus/TCP
  dissector tells a query from a response by port 502 and pairs them by transaction id,
  so every function code opens classified with no preferences (its RTU dissector
  cannot: see the design notes).

The modscope interface description records the line format in a pcapng IDB's
`if_description`: the word `modscope`, then in any order a baud rate, a character format
(`8E1`: data bits, parity N/E/O/M/S, stop bits), a mode (`rtu`, `ascii`, `auto`) and
optionally a role (`master` or `requests`: everything on the interface was sent by the
master; `slave` or `responses`: by the slaves). Example: `modscope 19200 8E1 rtu`. Other
words are ignored, so the form can grow.
"""

from __future__ import annotations

import math
import re
import struct
from dataclasses import dataclass

from sniffer.model import MODES, Direction, LineSettings, Stamp

LINKTYPE_USER0 = 147
LINKTYPE_RTAC_SERIAL = 250
LINKTYPE_WIRESHARK_UPPER_PDU = 252
SERIAL_LINKTYPES = (LINKTYPE_USER0, LINKTYPE_RTAC_SERIAL, LINKTYPE_WIRESHARK_UPPER_PDU)

# pcapng block types and option codes (pcapng specification, IETF draft)
BLOCK_SHB = 0x0A0D0D0A
BLOCK_IDB = 0x00000001
BLOCK_PB = 0x00000002  # obsolete Packet Block
BLOCK_SPB = 0x00000003
BLOCK_EPB = 0x00000006
BYTE_ORDER_MAGIC = 0x1A2B3C4D
OPT_ENDOFOPT = 0
OPT_COMMENT = 1
SHB_USERAPPL = 4
IF_NAME = 2
IF_DESCRIPTION = 3
IF_TSRESOL = 9
IF_TSOFFSET = 14
EPB_FLAGS = 2

# EPB flags word: bits 0-1 direction, bits 16-31 link-layer errors (bit 24: CRC error)
EPB_FLAG_INBOUND = 0x1
EPB_FLAG_OUTBOUND = 0x2
EPB_DIRECTION_MASK = 0x3
EPB_FLAG_CRC_ERROR = 1 << 24

# RTAC serial event types (Wireshark packet-rtacser.c)
RTAC_STATUS_CHANGE = 0x00
RTAC_DATA_TX_START = 0x01
RTAC_DATA_RX_START = 0x02
RTAC_DATA_TX_END = 0x03
RTAC_DATA_RX_END = 0x04
RTAC_CAPTURE_DATA_LOST = 0x05
RTAC_CAPTURE_COMPLETE = 0x06
RTAC_FRAMING_ERROR = 0x07
RTAC_PARITY_ERROR = 0x08
RTAC_SERIAL_BREAK = 0x09
RTAC_SERIAL_OVERFLOW = 0x0A
RTAC_HEADER = struct.Struct(">IIBBH")
RTAC_HEADER_LEN = RTAC_HEADER.size  # 12

# RTAC control line bits, in the order Wireshark lists them
RTAC_CONTROL_LINES = (
    (0x01, "CTS"),
    (0x02, "DCD"),
    (0x04, "DSR"),
    (0x08, "RTS"),
    (0x10, "DTR"),
    (0x20, "RING"),
    (0x40, "MBOK"),
)

# What an RTAC event becomes on a Chunk: (event text, note). Data events have no text.
RTAC_EVENTS: dict[int, tuple[str, str]] = {
    RTAC_STATUS_CHANGE: ("control lines", ""),
    RTAC_DATA_TX_START: ("", ""),
    RTAC_DATA_RX_START: ("", ""),
    RTAC_DATA_TX_END: ("", ""),
    RTAC_DATA_RX_END: ("", ""),
    RTAC_CAPTURE_DATA_LOST: ("data lost", "capture lost data"),
    RTAC_CAPTURE_COMPLETE: ("capture complete", ""),  # an end time, not a row (Pipeline)
    RTAC_FRAMING_ERROR: ("framing error", ""),
    RTAC_PARITY_ERROR: ("parity error", ""),
    RTAC_SERIAL_BREAK: ("break", "serial break"),
    RTAC_SERIAL_OVERFLOW: ("data lost", "serial overflow"),
}

# Exported PDU tags (Wireshark epan/exported_pdu.h)
EXP_PDU_TAG_END_OF_OPT = 0
EXP_PDU_TAG_DISSECTOR_NAME = 12
EXP_PDU_TAG_HEUR_DISSECTOR_NAME = 13
EXP_PDU_TAG_DISSECTOR_TABLE_NAME = 14
EXP_PDU_TAG_IPV4_SRC = 20
EXP_PDU_TAG_IPV4_DST = 21
EXP_PDU_TAG_PORT_TYPE = 24
EXP_PDU_TAG_SRC_PORT = 25
EXP_PDU_TAG_DST_PORT = 26
EXP_PDU_PORT_TYPE_TCP = 2
MBTCP_PORT = 502
MBAP_HEADER = struct.Struct(">HHHB")  # transaction id, protocol id (0), length, unit
_EXP_PDU_NAME_TAGS = (
    EXP_PDU_TAG_DISSECTOR_NAME,
    EXP_PDU_TAG_HEUR_DISSECTOR_NAME,
    EXP_PDU_TAG_DISSECTOR_TABLE_NAME,
)
_TLV = struct.Struct(">HH")


def control_lines_text(lines: int) -> str:
    """`CTS /DCD ...`: each RTAC control line, prefixed with `/` when it is off."""
    return " ".join(name if lines & bit else "/" + name for bit, name in RTAC_CONTROL_LINES)


@dataclass(frozen=True, slots=True)
class RtacRecord:
    """One link type 250 packet taken apart."""

    seconds: float
    event: int
    control_lines: int
    data: bytes


def parse_rtac(packet: bytes) -> RtacRecord | None:
    """The header fields and bytes of an RTAC serial packet; None if it is too short."""
    if len(packet) < RTAC_HEADER_LEN:
        return None
    secs, usecs, event, lines, _footer = RTAC_HEADER.unpack_from(packet)
    return RtacRecord(secs + usecs / 1e6, event, lines, bytes(packet[RTAC_HEADER_LEN:]))


def build_rtac(t: float, data: bytes, event: int, control_lines: int) -> bytes:
    """An RTAC serial packet: header stamped with `t` (Unix seconds), then `data`."""
    if t < 0:
        raise ValueError(f"RTAC time must not be negative, not {t}")
    whole = math.floor(t)
    secs, usecs = divmod(whole * 1_000_000 + round((t - whole) * 1e6), 1_000_000)
    return RTAC_HEADER.pack(secs & 0xFFFFFFFF, usecs, event & 0xFF, control_lines & 0xFF, 0) + data


@dataclass(frozen=True, slots=True)
class UpperPdu:
    """One link type 252 packet taken apart: the dissector it names and the PDU bytes."""

    dissector: str
    pdu: bytes


def parse_upper_pdu(packet: bytes) -> UpperPdu | None:
    """The dissector name and PDU of an exported-PDU packet; None if the TLVs are broken."""
    offset = 0
    name = ""
    while True:
        if offset + _TLV.size > len(packet):
            return None
        tag, length = _TLV.unpack_from(packet, offset)
        offset += _TLV.size
        if tag == EXP_PDU_TAG_END_OF_OPT:
            return UpperPdu(name, bytes(packet[offset:]))
        if offset + length > len(packet):
            return None
        if tag in _EXP_PDU_NAME_TAGS and not name:
            raw = bytes(packet[offset : offset + length]).split(b"\0", 1)[0]
            name = raw.decode("ascii", errors="replace")
        offset += length


def build_upper_pdu(frame: bytes, dissector: str) -> bytes:
    """Exported-PDU TLVs naming `dissector` (NUL-padded to 4 bytes), end tag, frame."""
    name = dissector.encode("ascii")
    padded = name + b"\0" * (-len(name) % 4)
    return (
        _TLV.pack(EXP_PDU_TAG_DISSECTOR_NAME, len(padded))
        + padded
        + _TLV.pack(EXP_PDU_TAG_END_OF_OPT, 0)
        + frame
    )


@dataclass(frozen=True, slots=True)
class TcpEnds:
    """The addresses an exported Modbus/TCP PDU claims: IPv4 source and destination (4
    bytes each) and TCP ports. The answering side has port 502."""

    src: bytes
    dst: bytes
    sport: int
    dport: int


def build_mbtcp_pdu(ends: TcpEnds, transaction: int, unit: int, pdu: bytes) -> bytes:
    """An exported-PDU packet for Wireshark's `mbtcp` dissector: dissector name, address
    and port tags, end tag, then the MBAP header and `pdu`."""
    name = b"mbtcp\0\0\0"
    u32 = struct.Struct(">I")
    return (
        _TLV.pack(EXP_PDU_TAG_DISSECTOR_NAME, len(name))
        + name
        + _TLV.pack(EXP_PDU_TAG_IPV4_SRC, 4)
        + ends.src
        + _TLV.pack(EXP_PDU_TAG_IPV4_DST, 4)
        + ends.dst
        + _TLV.pack(EXP_PDU_TAG_PORT_TYPE, 4)
        + u32.pack(EXP_PDU_PORT_TYPE_TCP)
        + _TLV.pack(EXP_PDU_TAG_SRC_PORT, 4)
        + u32.pack(ends.sport)
        + _TLV.pack(EXP_PDU_TAG_DST_PORT, 4)
        + u32.pack(ends.dport)
        + _TLV.pack(EXP_PDU_TAG_END_OF_OPT, 0)
        + MBAP_HEADER.pack(transaction & 0xFFFF, 0, len(pdu) + 1, unit & 0xFF)
        + pdu
    )


def open_mbap(adu: bytes) -> bytes | None:
    """The unit and PDU of one Modbus/TCP ADU (MBAP header, then the PDU); None unless the
    protocol id is 0 and the length field covers exactly the rest."""
    if len(adu) < MBAP_HEADER.size + 1:
        return None
    _tid, protocol, length, _unit = MBAP_HEADER.unpack_from(adu)
    if protocol != 0 or length != len(adu) - 6:
        return None
    return bytes(adu[6:])


_FORMAT = re.compile(r"^([78])([NEOMS])([12])$", re.IGNORECASE)
_STAMPS = {stamp.value: stamp for stamp in Stamp}
_ROLES = {
    "master": Direction.MASTER,
    "requests": Direction.MASTER,
    "slave": Direction.SLAVE,
    "responses": Direction.SLAVE,
}


@dataclass(frozen=True, slots=True)
class InterfaceNote:
    """What a modscope interface description says: line settings and a role; for an
    export, what the times it holds are worth (the stamps and resolution of the
    capture it was exported from)."""

    line: LineSettings | None
    role: Direction = Direction.UNKNOWN
    stamps: Stamp | None = None
    resolution: float | None = None


def describe_interface(
    line: LineSettings,
    role: Direction = Direction.UNKNOWN,
    timing: tuple[Stamp, float] | None = None,
) -> str:
    """The `if_description` modscope writes: `modscope 19200 8E1 rtu`, maybe ` master`,
    and for an export the times' worth: ` stamps=read-end resolution=0.016`."""
    text = f"modscope {line.describe()}"
    if role == Direction.MASTER:
        text += " master"
    elif role == Direction.SLAVE:
        text += " slave"
    if timing is not None:
        stamps, resolution = timing
        text += f" stamps={stamps.value} resolution={resolution!r}"
    return text


def parse_interface_description(text: str) -> InterfaceNote:
    """Read a modscope interface description; anything else gives an empty note."""
    words = text.split()
    if not words or words[0].lower() != "modscope":
        return InterfaceNote(None)
    baud: int | None = None
    char: tuple[int, str, int] | None = None
    mode = "auto"
    role = Direction.UNKNOWN
    stamps: Stamp | None = None
    resolution: float | None = None
    for word in words[1:]:
        lower = word.lower()
        key, _, value = lower.partition("=")
        if key == "stamps" and value in _STAMPS:
            stamps = _STAMPS[value]
        elif key == "resolution":
            try:
                resolution = float(value)
            except ValueError:
                continue
            if not resolution >= 0:
                resolution = None
        elif word.isascii() and word.isdigit() and len(word) <= 9 and baud is None:
            baud = int(word)
        elif (match := _FORMAT.match(word)) and char is None:
            char = (int(match[1]), match[2].upper(), int(match[3]))
        elif lower in MODES:
            mode = lower
        elif lower in _ROLES:
            role = _ROLES[lower]
    if baud is None and char is None and mode == "auto":
        return InterfaceNote(None, role, stamps, resolution)
    base = LineSettings()
    try:
        line = LineSettings(
            baud=baud if baud else base.baud,
            bytesize=char[0] if char else base.bytesize,
            parity=char[1] if char else base.parity,
            stopbits=char[2] if char else base.stopbits,
            mode=mode,
        )
    except ValueError:
        return InterfaceNote(None, role, stamps, resolution)
    return InterfaceNote(line, role, stamps, resolution)

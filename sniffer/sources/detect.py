"""Provides format recognition from a file's first bytes: magic numbers, then text shapes.

Order: pcapng (block type and byte-order magic), pcap (any of its magics with version 2),
ZIP (a sigrok session if it holds `metadata`, decided by the sigrok reader), then text:
a `socat -x -v` header line, a text2pcap-style offset line at offset 0, a Saleae CSV
export header (its first line, ended by LF or CR), then the text logs of
`logs.sniff_log` (ESPHome, pymodbus, libmodbus and mbpoll, evcc, ModbusTools, CAS Modbus
Scanner, serial monitors: by the lines each prints, never the file's name); anything
else is raw binary.
"""

from __future__ import annotations

import re
import struct

from sniffer.sources.logs import sniff_log
from sniffer.sources.saleae import sniff_saleae

HEAD_SIZE = 1 << 16

PCAPNG = "pcapng"
PCAP = "pcap"
SIGROK = "sigrok"
SOCAT = "socat"
HEXDUMP = "hexdump"
SALEAE = "saleae"
RAW = "raw"

PCAP_MAGICS = {
    # magic as read little-endian: (byte order, nanosecond timestamps, modified record header)
    0xA1B2C3D4: ("<", False, False),
    0xD4C3B2A1: (">", False, False),
    0xA1B23C4D: ("<", True, False),
    0x4D3CB2A1: (">", True, False),
    0xA1B2CD34: ("<", False, True),
    0x34CDB2A1: (">", False, True),
}

SOCAT_HEADER = re.compile(
    r"^([<>]) (\d{4})/(\d\d)/(\d\d) (\d\d):(\d\d):(\d\d)(?:\.(\d+))?\s+"
    r"length=(\d+) from=(\d+) to=(\d+)\s*$",
    re.MULTILINE,
)
_PRINTABLE = bytes(range(32, 127)) + b"\t\n\r"
OFFSET_LINE = re.compile(r"^[\s>]*([0-9A-Fa-f]{3,})[:\s]\s*[0-9A-Fa-f]{2}(?:\s|$)", re.MULTILINE)


SHB_MAGIC = b"\x0a\x0d\x0d\x0a"
BYTE_ORDER_MAGICS = (b"\x4d\x3c\x2b\x1a", b"\x1a\x2b\x3c\x4d")


def _is_pcapng(head: bytes) -> bool:
    if len(head) < 12:
        # a file cut inside its first header: the reader says so (offset and size)
        # instead of showing the bytes as noise
        return _truncated_pcapng(head)
    if head[:4] != SHB_MAGIC:
        return False
    return head[8:12] in BYTE_ORDER_MAGICS


def _truncated_pcapng(head: bytes) -> bool:
    if not head or not SHB_MAGIC.startswith(head[:4]):
        return False
    rest = head[8:]
    return any(magic.startswith(rest) for magic in BYTE_ORDER_MAGICS)


def _is_pcap(head: bytes) -> bool:
    if len(head) < 4:
        return False
    (magic,) = struct.unpack_from("<I", head)
    if magic not in PCAP_MAGICS:
        return False
    if len(head) < 24:
        return True  # cut inside the file header: the reader warns

    order = PCAP_MAGICS[magic][0]
    (major,) = struct.unpack_from(order + "H", head, 4)
    return bool(major == 2)


def _text(head: bytes) -> str | None:
    """The head as text if it looks like text (no NULs, mostly printable), else None."""
    if not head or b"\0" in head:
        return None
    unprintable = len(head.translate(None, _PRINTABLE))
    if unprintable > 0.05 * len(head):
        return None
    return head.decode("latin-1")


def sniff(head: bytes) -> str:
    """The format name for a file starting with `head`."""
    if _is_pcapng(head):
        return PCAPNG
    if _is_pcap(head):
        return PCAP
    if head[:4] in (b"PK\x03\x04", b"PK\x05\x06"):
        return SIGROK
    text = _text(head)
    if text is not None:
        if SOCAT_HEADER.search(text):
            return SOCAT
        for match in OFFSET_LINE.finditer(text):
            if int(match[1], 16) == 0:
                return HEXDUMP
    if sniff_saleae(head):
        return SALEAE
    return sniff_log(head) or RAW

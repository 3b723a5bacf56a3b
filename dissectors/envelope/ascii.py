"""Provides the Modbus ASCII envelope: `:`, the hex of unit, PDU and LRC, CR LF.

Some device families open their frames with another character: ABL's eMH1 wallboxes
answer a `:` request with `>`, then hex, LRC and CR LF as the standard has them (ABL's
"Schnittstellenbeschreibung Modbus-ASCII"; evcc reads them through grid-x/modbus, which
accepts both starts, and node-modbus-serial has an option for the answers' start).
`VENDOR_STARTS` names each such character and who sends it; everything after the first
character is read the same way whatever it is.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from dissectors.checks import ascii_frame, lrc

__all__ = [
    "START",
    "VENDOR_STARTS",
    "AsciiFrame",
    "ascii_body",
    "ascii_frame",
    "open_ascii",
]

START = 0x3A  # ':', the standard start of every frame, request or answer
# start characters device families use instead, and who uses them (docs/formats.md)
VENDOR_STARTS: Mapping[int, str] = MappingProxyType({0x3E: "ABL eMH1 wallboxes' answers"})


def ascii_body(raw: bytes) -> bytes | None:
    """The binary body (unit, PDU, LRC) of an ASCII frame, whatever its start character,
    or None if it is not hex."""
    text = raw[1:]
    if text.endswith(b"\r\n"):
        text = text[:-2]
    elif text.endswith(b"\n") or text.endswith(b"\r"):
        text = text[:-1]
    try:
        return bytes.fromhex(text.decode("ascii"))
    except ValueError:
        return None


@dataclass(frozen=True, slots=True)
class AsciiFrame:
    """One ASCII frame's characters, opened: the decoded hex (`decoded`: unit, PDU, LRC;
    None when the characters are not hex), the LRC sent and the one expected."""

    raw: bytes
    decoded: bytes | None

    transport = "ascii"

    @property
    def hex_ok(self) -> bool:
        return self.decoded is not None

    @property
    def body(self) -> bytes:
        """Unit and PDU: the decoded hex without its LRC (empty when not hex)."""
        return self.decoded[:-1] if self.decoded else b""

    @property
    def unit(self) -> int | None:
        body = self.body
        return body[0] if body else None

    @property
    def pdu(self) -> bytes:
        return self.body[1:]

    @property
    def sent(self) -> int | None:
        """The LRC the frame carries (its last hex byte)."""
        return self.decoded[-1] if self.decoded and len(self.decoded) >= 2 else None

    @property
    def expected(self) -> int | None:
        """The LRC of the unit and PDU."""
        return lrc(self.body) if self.decoded and len(self.decoded) >= 2 else None

    @property
    def vendor(self) -> str:
        """Who opens frames with this frame's start character, when it is a vendor's
        (`VENDOR_STARTS`) rather than `:`; empty otherwise."""
        return VENDOR_STARTS.get(self.raw[0], "") if self.raw else ""

    @property
    def check_ok(self) -> bool:
        """The LRC is right and there is a function code before it."""
        decoded = self.decoded
        return decoded is not None and len(decoded) >= 3 and lrc(decoded[:-1]) == decoded[-1]

    @property
    def check_text(self) -> str:
        """`LRC 0x12 wrong, expected 0x34`; empty when right."""
        decoded = self.decoded
        if decoded is None:
            return "characters other than hex digits: no LRC to check"
        if len(decoded) < 2:
            return "too short for an LRC"
        sent, want = decoded[-1], lrc(decoded[:-1])
        if sent != want:
            return f"LRC 0x{sent:02X} wrong, expected 0x{want:02X}"
        if len(decoded) < 3:
            return "too short: no function code before the LRC"
        return ""

    @property
    def spans(self) -> tuple[tuple[str, tuple[int, int]], ...]:
        """The parts by character offsets: the start (`:` or a vendor's), unit, PDU, LRC,
        CR LF (or what there is)."""
        raw = self.raw
        end = len(raw)
        tail = 2 if raw.endswith(b"\r\n") else 1 if raw.endswith((b"\n", b"\r")) else 0
        text_end = end - tail
        out: list[tuple[str, tuple[int, int]]] = [("start", (0, min(1, end)))]
        decoded = self.decoded
        if decoded is None or len(decoded) < 2:
            out.append(("text", (min(1, end), text_end)))
        else:
            pdu_end = text_end - 2
            out += [("unit", (1, 3)), ("pdu", (3, pdu_end)), ("lrc", (pdu_end, text_end))]
        if tail:
            out.append(("end", (text_end, end)))
        return tuple(out)


def open_ascii(raw: bytes | bytearray | memoryview) -> AsciiFrame:
    """The ASCII envelope of a frame's characters; never raises."""
    raw = bytes(raw)
    return AsciiFrame(raw, ascii_body(raw))

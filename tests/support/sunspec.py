"""Provides helpers shared by tests (moved from test_sunspec.py): a SunSpec device's
register image, the reads a master discovers it with, and those reads as RTU frames,
ASCII frames, or a network capture (Modbus TCP or RTU over TCP)."""

from __future__ import annotations

from dissectors.checks import lrc, with_crc
from sniffer.model import Chunk, LineSettings
from sniffer.session.session import Session
from tests.support.netbuild import Conversation, pcap

UNIT = 7


LINE = LineSettings(19200, 8, "E", 1)


def text_words(text: str, registers: int) -> list[int]:
    data = text.encode("ascii").ljust(2 * registers, b"\x00")
    return [int.from_bytes(data[k : k + 2], "big") for k in range(0, len(data), 2)]


def s16(v: int) -> int:
    return v & 0xFFFF


def device_image(base: int = 40000) -> dict[int, int]:
    """A SunSpec inverter with a meter: SunS, model 1 (L 66), 103 (L 50), 203 (L 105), end."""
    reg: dict[int, int] = {}

    def put(address: int, words: list[int]) -> None:
        for k, w in enumerate(words):
            reg[address + k] = w

    put(base, [0x5375, 0x6E53])
    m1 = base + 2
    put(m1, [1, 66])
    put(m1 + 2, text_words("Acme Solar", 16))
    put(m1 + 18, text_words("Inverter 3000", 16))
    put(m1 + 34, text_words("", 8))
    put(m1 + 42, text_words("1.2.3", 8))
    put(m1 + 50, text_words("SN-0042", 16))
    put(m1 + 66, [UNIT, 0x8000])  # DA, Pad
    m103 = m1 + 68
    put(m103, [103, 50] + [0xFFFF] * 50)  # every point "not implemented" to start
    put(m103 + 2, [1234])  # A = 12.34 A with A_SF -2
    put(m103 + 6, [s16(-2)])
    put(m103 + 10, [2301])  # PhVphA = 230.1 V with V_SF -1
    put(m103 + 13, [s16(-1)])
    put(m103 + 14, [8190, s16(-1)])  # W = 819.0 W, W_SF -1
    put(m103 + 16, [5001, s16(-2)])  # Hz = 50.01 Hz, Hz_SF -2
    put(m103 + 24, [0x0001, 0x86A0, 3])  # WH = 100000 * 10^3 Wh
    put(m103 + 38, [4])  # St = MPPT
    m203 = m103 + 52
    put(m203, [203, 105] + [0] * 105)
    put(m203 + 2, [s16(-52)])  # A = -5.2 A with A_SF -1
    put(m203 + 6, [s16(-1)])
    put(m203 + 16, [4999, s16(-2)])  # Hz = 49.99 Hz
    put(m203 + 18, [s16(-1500)])  # W = -1500 W (exporting), W_SF 0
    put(m203 + 22, [0])
    put(m203 + 38, [0x0000, 0x3039])  # TotWhExp = 12345 with TotWh_SF 1: 123450 Wh
    put(m203 + 46, [0x0000, 0x0065])  # TotWhImp = 101 -> 1010 Wh
    put(m203 + 54, [1])
    put(m203 + 107, [0xFFFF, 0])  # end of the chain
    return reg


def read(
    reg: dict[int, int], start: int, count: int, unit: int = UNIT, function: int = 3
) -> tuple[bytes, bytes]:
    """An RTU request (FC 3, or `function` 4) for `count` registers at `start`, and the
    device's answer."""
    request = with_crc(
        bytes([unit, function]) + start.to_bytes(2, "big") + count.to_bytes(2, "big")
    )
    data = b"".join(reg[start + k].to_bytes(2, "big") for k in range(count))
    return request, with_crc(bytes([unit, function, len(data)]) + data)


def discovery(reg: dict[int, int], base: int) -> list[tuple[int, int]]:
    """How a SunSpec master finds the models: marker, then each header and model body."""
    reads = [(base, 2)]
    at = base + 2
    while True:
        reads.append((at, 2))
        model_id, length = reg[at], reg[at + 1]
        if model_id == 0xFFFF:
            return reads
        reads.append((at + 2, length))
        at += 2 + length


def frames_of(
    reg: dict[int, int], reads: list[tuple[int, int]], function: int = 3
) -> list[tuple[float, bytes]]:
    """Each read 0.5 s after the last; times are the ends of the frames at 19200 8E1."""
    out: list[tuple[float, bytes]] = []
    for k, (start, count) in enumerate(reads):
        request, answer = read(reg, start, count, function=function)
        sent = k * 0.5 + len(request) * LINE.char_time
        out += [(sent, request), (sent + 0.005 + len(answer) * LINE.char_time, answer)]
    return out


def session_of(frames: list[tuple[float, bytes]], **kw: object) -> Session:
    session = Session(LINE, **kw)  # type: ignore[arg-type]
    for t, data in frames:
        session.feed(Chunk(data, 1_700_000_000 + t))
    session.finish()
    return session


# -- the same reads in other envelopes -------------------------------------------------------


def as_ascii(rtu: bytes, start: bytes = b":") -> bytes:
    """An RTU frame's unit and PDU as a Modbus ASCII frame: `:` (or `start`), hex, LRC, CR LF."""
    body = rtu[:-2]
    return start + (body + bytes([lrc(body)])).hex().upper().encode() + b"\r\n"


def as_mbap(rtu: bytes, tid: int) -> bytes:
    """An RTU frame's unit and PDU behind an MBAP header (transaction `tid`, protocol 0)."""
    body = rtu[:-2]
    return tid.to_bytes(2, "big") + b"\0\0" + len(body).to_bytes(2, "big") + body


def network_capture(
    reg: dict[int, int],
    reads: list[tuple[int, int]],
    *,
    function: int = 3,
    carrier: str = "tcp",
    server_port: int = 502,
) -> bytes:
    """A pcap (Ethernet) of one TCP connection in which a client makes `reads` of the
    device: Modbus TCP (`carrier` "tcp", an MBAP header per frame) or the RTU frames as
    they are ("rtu-over-tcp"), 0.5 s apart, each answered after 150 ms (as through a
    gateway to a serial line)."""
    conv = Conversation(server_port=server_port)
    t0 = 1_700_000_000.0
    packets = [(t0 + k * 0.001, p) for k, p in enumerate(conv.handshake())]
    for k, (start, count) in enumerate(reads):
        request, answer = read(reg, start, count, function=function)
        if carrier == "tcp":
            request, answer = as_mbap(request, k + 1), as_mbap(answer, k + 1)
        sent = t0 + 0.1 + k * 0.5
        packets += [(sent, conv.client(request)), (sent + 0.15, conv.server(answer))]
    return pcap(1, packets)

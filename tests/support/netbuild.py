"""Builds Ethernet-family packets and pcap/pcapng files byte by byte, for the tests.

Our own small builder (no scapy): Ethernet with optional VLAN tags, Linux cooked SLL and
SLL2, BSD loopback, IPv4 (with its header checksum) and IPv6 (with extension headers),
TCP and UDP (checksums left 0: captures of the sending host have them so too).
`Conversation` keeps a TCP connection's sequence numbers so a test can write
`conv.client(b"...")` and get the packet.
"""

from __future__ import annotations

import ipaddress
import struct
from dataclasses import dataclass, field

from sniffer.sources.net.packets import TCP_ACK, TCP_FIN, TCP_RST, TCP_SYN

__all__ = ["TCP_ACK", "TCP_FIN", "TCP_RST", "TCP_SYN"]

CLIENT_MAC = bytes.fromhex("020000000001")
SERVER_MAC = bytes.fromhex("020000000002")


def ip_checksum(header: bytes) -> int:
    total = 0
    for i in range(0, len(header), 2):
        total += header[i] << 8 | (header[i + 1] if i + 1 < len(header) else 0)
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return ~total & 0xFFFF


def ipv4(src: str, dst: str, proto: int, payload: bytes, *, frag: int = 0) -> bytes:
    header = struct.pack(
        "!BBHHHBBH4s4s",
        0x45,
        0,
        20 + len(payload),
        0x1234,
        frag,
        64,
        proto,
        0,
        ipaddress.IPv4Address(src).packed,
        ipaddress.IPv4Address(dst).packed,
    )
    checksum = ip_checksum(header)
    return header[:10] + struct.pack("!H", checksum) + header[12:] + payload


def ipv6(
    src: str, dst: str, proto: int, payload: bytes, *, ext: bytes = b"", first: int = -1
) -> bytes:
    """`ext` is a chain of extension headers placed before `payload`; `first` the next
    header value of the fixed header (the first extension's type) when `ext` is given."""
    body = ext + payload
    nh = first if ext else proto
    return (
        struct.pack("!IHBB", 6 << 28, len(body), nh, 64)
        + ipaddress.IPv6Address(src).packed
        + ipaddress.IPv6Address(dst).packed
        + body
    )


def tcp(sport: int, dport: int, seq: int, ack: int, flags: int, payload: bytes = b"") -> bytes:
    return struct.pack("!HHIIBBHHH", sport, dport, seq, ack, 5 << 4, flags, 65535, 0, 0) + payload


def udp(sport: int, dport: int, payload: bytes) -> bytes:
    return struct.pack("!HHHH", sport, dport, 8 + len(payload), 0) + payload


def ethernet(
    ip_packet: bytes, *, v6: bool = False, vlans: tuple[int, ...] = (), pad: bool = True
) -> bytes:
    frame = SERVER_MAC + CLIENT_MAC
    for vid in vlans:
        frame += struct.pack("!HH", 0x8100, vid)
    frame += struct.pack("!H", 0x86DD if v6 else 0x0800) + ip_packet
    if pad and len(frame) < 60:
        frame += b"\0" * (60 - len(frame))  # Ethernet minimum size: trailer the IP length excludes
    return frame


def sll(ip_packet: bytes, *, v6: bool = False) -> bytes:
    return (
        struct.pack("!HHH8sH", 0, 1, 6, CLIENT_MAC + b"\0\0", 0x86DD if v6 else 0x0800) + ip_packet
    )


def sll2(ip_packet: bytes, *, v6: bool = False) -> bytes:
    return (
        struct.pack("!HHIHBB8s", 0x86DD if v6 else 0x0800, 0, 1, 1, 0, 6, CLIENT_MAC + b"\0\0")
        + ip_packet
    )


def null_loopback(ip_packet: bytes, *, v6: bool = False, big_endian: bool = False) -> bytes:
    return struct.pack(">I" if big_endian else "<I", 30 if v6 else 2) + ip_packet


def pcap(linktype: int, packets: list[tuple[float, bytes]], *, snaplen: int = 65535) -> bytes:
    # (the records joined once: adding each to a growing bytes copied the file each
    # time, and 100k packets took minutes)
    out = [struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, snaplen, linktype)]
    for t, data in packets:
        secs = int(t)
        usec = round((t - secs) * 1_000_000)
        kept = data[:snaplen]
        out.append(struct.pack("<IIII", secs, usec, len(kept), len(data)) + kept)
    return b"".join(out)


@dataclass
class Conversation:
    """One TCP connection between a client and a server, over IPv4 or IPv6."""

    client_ip: str = "192.168.1.10"
    server_ip: str = "192.168.1.20"
    client_port: int = 50211
    server_port: int = 502
    client_seq: int = 1000
    server_seq: int = 5000
    v6: bool = False
    link: str = "ethernet"
    vlans: tuple[int, ...] = ()
    log: list[bytes] = field(default_factory=list)

    def _wrap(self, segment: bytes, from_client: bool) -> bytes:
        src, dst = (
            (self.client_ip, self.server_ip) if from_client else (self.server_ip, self.client_ip)
        )
        ip = ipv6(src, dst, 6, segment) if self.v6 else ipv4(src, dst, 6, segment)
        if self.link == "sll":
            return sll(ip, v6=self.v6)
        if self.link == "sll2":
            return sll2(ip, v6=self.v6)
        if self.link == "null":
            return null_loopback(ip, v6=self.v6)
        if self.link == "raw":
            return ip
        return ethernet(ip, v6=self.v6, vlans=self.vlans)

    def segment(
        self, from_client: bool, payload: bytes, *, flags: int = TCP_ACK, seq: int | None = None
    ) -> bytes:
        """A segment with `payload` at `seq` (default: the next byte) without moving on."""
        if from_client:
            s = self.client_seq if seq is None else seq
            seg = tcp(self.client_port, self.server_port, s, self.server_seq, flags, payload)
        else:
            s = self.server_seq if seq is None else seq
            seg = tcp(self.server_port, self.client_port, s, self.client_seq, flags, payload)
        return self._wrap(seg, from_client)

    def send(self, from_client: bool, payload: bytes, *, flags: int = TCP_ACK) -> bytes:
        """The next segment of one side, and move its sequence number on."""
        packet = self.segment(from_client, payload, flags=flags)
        step = len(payload) + (1 if flags & (TCP_SYN | TCP_FIN) else 0)
        if from_client:
            self.client_seq = (self.client_seq + step) % (1 << 32)
        else:
            self.server_seq = (self.server_seq + step) % (1 << 32)
        return packet

    def client(self, payload: bytes, flags: int = TCP_ACK) -> bytes:
        return self.send(True, payload, flags=flags)

    def server(self, payload: bytes, flags: int = TCP_ACK) -> bytes:
        return self.send(False, payload, flags=flags)

    def handshake(self) -> list[bytes]:
        return [
            self.client(b"", TCP_SYN),
            self.server(b"", TCP_SYN | TCP_ACK),
            self.client(b"", TCP_ACK),
        ]

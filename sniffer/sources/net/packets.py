"""Provides the packet decoder for Ethernet-family captures: link layer, IP, TCP and UDP.

`decode(linktype, data)` takes one captured packet and returns a `Segment` (addresses,
ports, TCP sequence number and flags, payload) or a `Skip` saying why the packet carries
no TCP or UDP payload we can use. Nothing here raises on packet bytes.

Link types: Ethernet (1, with 802.1Q/802.1ad VLAN tags, stacked), Linux cooked SLL (113)
and SLL2 (276), raw IP (101; 228 IPv4; 229 IPv6), BSD loopback/null (0, the address
family in the capturing host's byte order) and OpenBSD loopback (108, network order).
IPv4 options are skipped by the header length; IPv6 extension headers (hop-by-hop,
routing, destination options, mobility, HIP, shim6, AH) are walked; IP fragments are not
reassembled (Modbus messages fit one packet): they are skipped with a reason, so a TCP
stream that needed one shows a gap. Checksums are not checked: the capturing host's own
packets are captured before the NIC fills them in.
"""

from __future__ import annotations

import ipaddress
import struct
from dataclasses import dataclass

LINKTYPE_NULL = 0
LINKTYPE_ETHERNET = 1
LINKTYPE_RAW = 101
LINKTYPE_LOOP = 108
LINKTYPE_LINUX_SLL = 113
LINKTYPE_IPV4 = 228
LINKTYPE_IPV6 = 229
LINKTYPE_LINUX_SLL2 = 276

NET_LINKTYPES: dict[int, str] = {
    LINKTYPE_NULL: "BSD loopback",
    LINKTYPE_ETHERNET: "Ethernet",
    LINKTYPE_RAW: "raw IP",
    LINKTYPE_LOOP: "OpenBSD loopback",
    LINKTYPE_LINUX_SLL: "Linux cooked",
    LINKTYPE_IPV4: "raw IPv4",
    LINKTYPE_IPV6: "raw IPv6",
    LINKTYPE_LINUX_SLL2: "Linux cooked v2",
}

ETHERTYPE_IPV4 = 0x0800
ETHERTYPE_IPV6 = 0x86DD
VLAN_ETHERTYPES = frozenset({0x8100, 0x88A8, 0x9100})
AF_INET = 2
AF_INET6 = frozenset({10, 24, 28, 30})  # Linux, NetBSD/OpenBSD, FreeBSD, macOS

PROTO_TCP = 6
PROTO_UDP = 17
IPV6_SKIPPABLE = frozenset({0, 43, 60, 135, 139, 140})  # (length + 1) * 8 bytes
IPV6_FRAGMENT = 44
IPV6_AH = 51  # (length + 2) * 4 bytes

TCP_FIN = 0x01
TCP_SYN = 0x02
TCP_RST = 0x04
TCP_ACK = 0x10


@dataclass(frozen=True, slots=True)
class Segment:
    """One TCP segment or UDP datagram: who sent it to whom, and its payload.

    `src` and `dst` are `ip:port` strings (`[v6]:port` for IPv6). `seq` and `flags` are
    the TCP header's (0 for UDP); `ack` is the acknowledgement number when ACK is set.
    """

    transport: str  # "tcp" or "udp"
    src: str
    dst: str
    sport: int
    dport: int
    seq: int
    ack: int | None
    flags: int
    payload: bytes
    missing: int = 0  # payload bytes the capture's snap length cut off


@dataclass(frozen=True, slots=True)
class Skip:
    """A packet with nothing for us, and why (`reason` is a short category, `text` the
    detail; the reader counts reasons rather than warning per packet)."""

    reason: str
    text: str


def _endpoint(address: bytes, port: int) -> str:
    if len(address) == 4:
        return f"{ipaddress.IPv4Address(address)}:{port}"
    return f"[{ipaddress.IPv6Address(address)}]:{port}"


def decode(linktype: int, data: bytes) -> Segment | Skip:
    """The TCP or UDP segment one packet of `linktype` carries, or why there is none."""
    if linktype == LINKTYPE_ETHERNET:
        if len(data) < 14:
            return Skip("truncated", f"Ethernet header needs 14 bytes, packet has {len(data)}")
        return _ethertype(data, 12)
    if linktype == LINKTYPE_LINUX_SLL:
        if len(data) < 16:
            return Skip("truncated", f"Linux cooked header needs 16 bytes, packet has {len(data)}")
        return _ethertype(data, 14)
    if linktype == LINKTYPE_LINUX_SLL2:
        if len(data) < 20:
            return Skip("truncated", f"SLL2 header needs 20 bytes, packet has {len(data)}")
        (ethertype,) = struct.unpack_from("!H", data, 0)
        return _network(ethertype, data, 20)
    if linktype in (LINKTYPE_RAW, LINKTYPE_IPV4, LINKTYPE_IPV6):
        return _ip(data, 0)
    if linktype in (LINKTYPE_NULL, LINKTYPE_LOOP):
        if len(data) < 4:
            return Skip("truncated", f"loopback header needs 4 bytes, packet has {len(data)}")
        family = struct.unpack_from("!I" if linktype == LINKTYPE_LOOP else "<I", data)[0]
        if linktype == LINKTYPE_NULL and family > 0xFFFF:
            family = struct.unpack_from("!I", data)[0]  # written by a big-endian host
        if family == AF_INET or family in AF_INET6:
            return _ip(data, 4)
        return Skip("not IP", f"loopback address family {family}")
    return Skip("link type", f"link type {linktype} is not an Ethernet-family link type")


def _ethertype(data: bytes, pos: int) -> Segment | Skip:
    """Walk VLAN tags from the ethertype at `pos`, then hand over to the network layer."""
    (ethertype,) = struct.unpack_from("!H", data, pos)
    pos += 2
    while ethertype in VLAN_ETHERTYPES:
        if len(data) < pos + 4:
            return Skip("truncated", "VLAN tag cut short")
        (ethertype,) = struct.unpack_from("!H", data, pos + 2)
        pos += 4
    return _network(ethertype, data, pos)


def _network(ethertype: int, data: bytes, pos: int) -> Segment | Skip:
    if ethertype in (ETHERTYPE_IPV4, ETHERTYPE_IPV6):
        return _ip(data, pos)
    if ethertype < 0x0600:
        return Skip("not IP", "IEEE 802.3 frame (LLC), not IP")
    return Skip("not IP", f"ethertype 0x{ethertype:04X}")


def _ip(data: bytes, pos: int) -> Segment | Skip:
    if len(data) <= pos:
        return Skip("truncated", "no IP header")
    version = data[pos] >> 4
    if version == 4:
        return _ipv4(data, pos)
    if version == 6:
        return _ipv6(data, pos)
    return Skip("not IP", f"IP version {version}")


def _ipv4(data: bytes, pos: int) -> Segment | Skip:
    if len(data) < pos + 20:
        return Skip("truncated", "IPv4 header cut short")
    ihl = (data[pos] & 0x0F) * 4
    total, frag, proto = struct.unpack_from("!H2xH1xB", data, pos + 2)
    if ihl < 20 or len(data) < pos + ihl:
        return Skip("truncated", f"IPv4 header length {ihl}")
    if frag & 0x3FFF:  # more fragments, or a fragment offset
        return Skip("fragment", "IPv4 fragment (fragments are not reassembled)")
    end = pos + total if total >= ihl else len(data)  # total 0: TCP segmentation offload
    missing = max(0, end - len(data))  # cut by the capture's snap length
    src = data[pos + 12 : pos + 16]
    dst = data[pos + 16 : pos + 20]
    return _transport(proto, src, dst, data[pos + ihl : end], missing)


def _ipv6(data: bytes, pos: int) -> Segment | Skip:
    if len(data) < pos + 40:
        return Skip("truncated", "IPv6 header cut short")
    (length,) = struct.unpack_from("!H", data, pos + 4)
    proto = data[pos + 6]
    src = data[pos + 8 : pos + 24]
    dst = data[pos + 24 : pos + 40]
    end = pos + 40 + length if length else len(data)  # 0: jumbogram
    missing = max(0, end - len(data))
    end -= missing
    at = pos + 40
    while proto in IPV6_SKIPPABLE or proto in (IPV6_FRAGMENT, IPV6_AH):
        if end < at + 8:
            return Skip("truncated", "IPv6 extension header cut short")
        if proto == IPV6_FRAGMENT:
            (offset_flags,) = struct.unpack_from("!H", data, at + 2)
            if offset_flags & 0xFFF9:  # an offset or more fragments
                return Skip("fragment", "IPv6 fragment (fragments are not reassembled)")
            size = 8
        elif proto == IPV6_AH:
            size = (data[at + 1] + 2) * 4
        else:
            size = (data[at + 1] + 1) * 8
        proto = data[at]
        at += size
    if at > end:
        return Skip("truncated", "IPv6 extension headers run past the packet")
    return _transport(proto, src, dst, data[at:end], missing)


def _transport(proto: int, src: bytes, dst: bytes, data: bytes, missing: int = 0) -> Segment | Skip:
    if proto == PROTO_TCP:
        if len(data) < 20:
            return Skip("truncated", "TCP header cut short")
        sport, dport, seq, ack, offset, flags = struct.unpack_from("!HHIIBB", data)
        header = (offset >> 4) * 4
        if header < 20 or header > len(data):
            return Skip("truncated", f"TCP header length {header}")
        return Segment(
            "tcp",
            _endpoint(src, sport),
            _endpoint(dst, dport),
            sport,
            dport,
            seq,
            ack if flags & TCP_ACK else None,
            flags,
            data[header:],
            missing,
        )
    if proto == PROTO_UDP:
        if len(data) < 8:
            return Skip("truncated", "UDP header cut short")
        sport, dport, length = struct.unpack_from("!HHH", data)
        end = length if 8 <= length <= len(data) else len(data)
        return Segment(
            "udp",
            _endpoint(src, sport),
            _endpoint(dst, dport),
            sport,
            dport,
            0,
            None,
            0,
            data[8:end],
            max(missing, length - len(data)) if length >= 8 else missing,
        )
    return Skip("not TCP or UDP", f"IP protocol {proto}")

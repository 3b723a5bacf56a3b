"""Provides carrier detection (what a connection carries) and the channel labels.

A carrier is how Modbus rides on a connection: `modbus-tcp` (MBAP frames; Modbus/UDP
is the same envelope in datagrams, `modbus-udp`), `rtu-over-tcp` and `rtu-over-udp` (RTU
frames with their CRC as the payload, as serial servers send them), or `other` (not
Modbus: its bytes are left out and counted in a warning).

Detection looks at the first payloads of a connection, both directions: a payload that
reads as MBAP frames back to back (protocol 0, lengths that fit) votes for MBAP; one
that is an RTU frame with a valid CRC (or two back to back) votes for RTU. The first
carrier with `DECISIVE` votes and none against wins; after `MAX_VOTES` payloads the
larger count wins, and a tie (or no vote) goes by port: 502 and 503 mean Modbus TCP.

A channel's label says who sends on it, to whom, and what it carries:
`tcp 192.168.1.10:50211 > 192.168.1.20:502 modbus-tcp`. `parse_label` reads it back,
so consumers of `SourceInfo.channels` can find the peer and the carrier.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass

from dissectors import mbap
from dissectors.checks import crc16
from sniffer.model import Direction

MODBUS_TCP = "modbus-tcp"
MODBUS_UDP = "modbus-udp"
RTU_OVER_TCP = "rtu-over-tcp"
RTU_OVER_UDP = "rtu-over-udp"
OTHER = "other"
CARRIERS = (MODBUS_TCP, MODBUS_UDP, RTU_OVER_TCP, RTU_OVER_UDP, OTHER)
OPTION_CARRIERS = ("tcp", "rtu-over-tcp", "rtu-over-udp")  # what --carrier accepts
MBAP_CARRIERS = frozenset({MODBUS_TCP, MODBUS_UDP})

MODBUS_PORTS = frozenset({502, 503})
DECISIVE = 2
MAX_VOTES = 6
MIN_RTU = 4
MAX_RTU = 256


def rtu_frames(payload: bytes) -> bool:
    """Whether `payload` is one RTU frame with a valid CRC, or two back to back."""
    n = len(payload)
    if n < MIN_RTU:
        return False
    if n <= MAX_RTU and _crc_ok(payload):
        return True
    for first in range(MIN_RTU, min(n - MIN_RTU, MAX_RTU) + 1):
        if _crc_ok(payload[:first]) and n - first <= MAX_RTU and _crc_ok(payload[first:]):
            return True
    return False


def _crc_ok(frame: bytes) -> bool:
    return crc16(frame[:-2]) == frame[-2] | frame[-1] << 8


@dataclass
class Votes:
    """Evidence gathered from a connection's first payloads."""

    mbap: int = 0
    rtu: int = 0
    seen: int = 0

    def add(self, payload: bytes) -> None:
        self.seen += 1
        is_mbap = mbap.consistent(payload)
        is_rtu = rtu_frames(payload)
        if is_mbap and not is_rtu:
            self.mbap += 1
        elif is_rtu and not is_mbap:
            self.rtu += 1  # both: `01 03 00 00 00 02 C4 0B` reads either way; no vote

    def verdict(self, transport: str, server_port: int, final: bool) -> str | None:
        """The carrier, or None while the evidence is not enough (and not `final`)."""
        stream = transport == "tcp"
        if self.mbap >= DECISIVE and not self.rtu:
            return MODBUS_TCP if stream else MODBUS_UDP
        if self.rtu >= DECISIVE and not self.mbap:
            return RTU_OVER_TCP if stream else RTU_OVER_UDP
        if not final and self.seen < MAX_VOTES:
            return None
        if self.mbap > self.rtu or (
            self.mbap and self.mbap == self.rtu and server_port in MODBUS_PORTS
        ):
            return MODBUS_TCP if stream else MODBUS_UDP
        if self.rtu:
            return RTU_OVER_TCP if stream else RTU_OVER_UDP
        if server_port in MODBUS_PORTS:
            return MODBUS_TCP if stream else MODBUS_UDP
        return OTHER


def forced(option: str | None, transport: str) -> str | None:
    """The carrier `--carrier` imposes on a connection of `transport`, if any."""
    if option is None:
        return None
    if option == "tcp":
        return MODBUS_TCP if transport == "tcp" else MODBUS_UDP
    if option == "rtu-over-tcp" and transport == "tcp":
        return RTU_OVER_TCP
    if option == "rtu-over-udp" and transport == "udp":
        return RTU_OVER_UDP
    return None


@dataclass(frozen=True, slots=True)
class ChannelLabel:
    """What a channel of a network capture carries: read back from its label."""

    transport: str
    sender: str  # ip:port of the side that sends on this channel (the row's peer)
    receiver: str
    carrier: str
    role: Direction  # MASTER: client to server; SLAVE: server to client

    @property
    def text(self) -> str:
        return f"{self.transport} {self.sender} > {self.receiver} {self.carrier}" + (
            " (server)" if self.role == Direction.SLAVE else ""
        )


_LABEL = re.compile(
    r"^(tcp|udp) (\S+) > (\S+) (" + "|".join(map(re.escape, CARRIERS)) + r")( \(server\))?$"
)


def parse_label(label: str) -> ChannelLabel | None:
    """The parts of a network channel's label; None for any other label."""
    match = _LABEL.match(label)
    if match is None:
        return None
    role = Direction.SLAVE if match[5] else Direction.MASTER
    return ChannelLabel(match[1], match[2], match[3], match[4], role)


SHOWN_SERVERS = 4  # servers a summary names; the others are counted


def summary(channels: Mapping[int, str]) -> str:
    """What a network capture holds, from its channel labels, for a header in place of
    serial line settings: `network: 2 TCP connections, modbus-tcp, servers
    192.168.1.20:502, 192.168.1.30:503`."""
    connections: dict[str, set[tuple[str, str]]] = {}  # transport -> (client, server)
    carriers: list[str] = []
    servers: list[str] = []
    for _, text in sorted(channels.items()):  # connections in the order first seen
        label = parse_label(text)
        if label is None or label.role != Direction.MASTER:
            continue
        connections.setdefault(label.transport, set()).add((label.sender, label.receiver))
        if label.carrier not in carriers:
            carriers.append(label.carrier)
        if label.receiver not in servers:
            servers.append(label.receiver)
    if not connections:
        return "network: no Modbus connection"
    parts = []
    for transport, word in (("tcp", "TCP connection"), ("udp", "UDP flow")):
        n = len(connections.get(transport, ()))
        if n:
            parts.append(f"{n} {word}{'s' if n != 1 else ''}")
    named = ", ".join(servers[:SHOWN_SERVERS])
    if len(servers) > SHOWN_SERVERS:
        named += f" and {len(servers) - SHOWN_SERVERS} more"
    noun = "server" if len(servers) == 1 else "servers"
    return f"network: {' and '.join(parts)}, {' and '.join(carriers)}, {noun} {named}"

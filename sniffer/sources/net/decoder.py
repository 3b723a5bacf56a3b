"""Provides the network decoder: captured packets in, chunks per connection direction out.

Each TCP connection (and each UDP flow between two endpoints) gets two channels, in a
pair: `2k` for what the client sends (requests, `Direction.MASTER`) and `2k + 1` for what
the server sends (answers, `Direction.SLAVE`). The channel label (see `carrier`) names
the sender, the receiver and the carrier, and is written into the capture's channel
table before the channel's first chunk leaves.

The server is the side on `--port` when one is given, else the side on port 502 or 503,
else the side a SYN was sent to, else the side that did not speak first.

TCP bytes come out reassembled (see `tcp`); a UDP datagram is one chunk. Chunk times are
packet capture times. A connection's chunks are held back until its carrier is known
(a few payloads, see `carrier`); connections that carry neither Modbus TCP nor RTU are
left out with one warning that names them.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import sniffer.sources.net.carrier as carriers
from sniffer.model import Chunk, Direction
from sniffer.sources.net.packets import TCP_ACK, TCP_FIN, TCP_RST, TCP_SYN, Segment, Skip, decode
from sniffer.sources.net.tcp import Piece, TcpHalf

MAX_CHANNEL = 255  # the frame store keeps channel numbers in one byte
MAX_HELD = 64  # chunks a connection may hold while its carrier is being detected


@dataclass(eq=False)
class _Connection:
    transport: str
    client: str
    server: str
    server_port: int
    channels: tuple[int, int]  # client to server, server to client
    carrier: str | None = None
    votes: carriers.Votes = field(default_factory=carriers.Votes)
    halves: tuple[TcpHalf, TcpHalf] = field(default_factory=lambda: (TcpHalf(), TcpHalf()))
    held: list[Chunk] = field(default_factory=list)
    bytes: int = 0


class NetDecoder:
    """Turns the packets of Ethernet-family interfaces into chunks (see the module doc).

    `channels` is the capture's channel table (labels are added to it); `warnings`
    collects what the reader should tell. `carrier` and `port` are the `--carrier` and
    `--port` options."""

    def __init__(
        self,
        channels: dict[int, str],
        warnings: list[str],
        *,
        carrier: str | None = None,
        port: int | None = None,
        reserved: frozenset[int] = frozenset(),
    ) -> None:
        self.channels = channels
        self.warnings = warnings
        self.carrier = carrier
        self.port = port
        self.reserved = reserved  # channel numbers other interfaces of the file use
        self.connections: dict[tuple[str, str, str], _Connection] = {}
        self.waiting: set[tuple[_Connection, int]] = set()  # halves with a hole
        self.skipped: Counter[str] = Counter()
        self.next_pair = 0
        self.refused: set[tuple[str, str, str]] = set()
        self.last_t = 0.0

    # -- input ---------------------------------------------------------------------------

    def packet(self, linktype: int, t: float, data: bytes) -> list[Chunk]:
        self.last_t = max(self.last_t, t)
        found = decode(linktype, data)
        out: list[Chunk] = []
        self._check_holes(t, out)
        if isinstance(found, Skip):
            self.skipped[found.reason] += 1
            return out
        conn = self._connection(found)
        if conn is None:
            return out
        sending = 0 if found.src == conn.client else 1
        if found.transport == "udp":
            if found.payload:
                self._emit(conn, sending, [Piece(t, data=found.payload)], out)
            if found.missing:
                note = f"{found.missing} bytes cut off by the capture's snap length"
                self._emit(conn, sending, [Piece(t, event="gap", note=note)], out)
            return out
        half = conn.halves[sending]
        pieces = half.segment(found, t)
        if found.ack is not None:
            other = conn.halves[1 - sending]
            pieces_other = other.acknowledged(found.ack, t)
            self._emit(conn, 1 - sending, pieces_other, out)
        self._emit(conn, sending, pieces, out)
        for side in (0, 1):
            key = (conn, side)
            if conn.halves[side].waiting:
                self.waiting.add(key)
            else:
                self.waiting.discard(key)
        return out

    def finish(self) -> list[Chunk]:
        """The capture ended: holes become gaps, held chunks leave, warnings are written."""
        out: list[Chunk] = []
        t = self.last_t
        for conn in self.connections.values():
            for side in (0, 1):
                self._emit(conn, side, conn.halves[side].flush(t), out)
            if conn.carrier is None:
                self._decide(conn, final=True, out=out)
        self.waiting.clear()
        self._summarise()
        return out

    # -- internals -----------------------------------------------------------------------

    def _check_holes(self, t: float, out: list[Chunk]) -> None:
        if not self.waiting:
            return
        for conn, side in list(self.waiting):
            pieces = conn.halves[side].check(t)
            if pieces:
                self._emit(conn, side, pieces, out)
            if not conn.halves[side].waiting:
                self.waiting.discard((conn, side))

    def _connection(self, seg: Segment) -> _Connection | None:
        a, b = sorted((seg.src, seg.dst))
        key = (seg.transport, a, b)
        conn = self.connections.get(key)
        if conn is not None:
            return conn
        if key in self.refused:
            return None
        if self.port is not None and self.port not in (seg.sport, seg.dport):
            self.refused.add(key)
            self.skipped[f"not on port {self.port}"] += 1
            return None
        syn_only = seg.flags & (TCP_SYN | TCP_ACK) == TCP_SYN
        syn_ack = seg.flags & (TCP_SYN | TCP_ACK) == TCP_SYN | TCP_ACK
        if not (seg.payload or seg.missing or seg.flags & (TCP_SYN | TCP_FIN | TCP_RST)):
            return None  # a bare ACK says too little to tell client from server
        server_ports = {self.port} if self.port is not None else carriers.MODBUS_PORTS
        if seg.dport in server_ports and seg.sport not in server_ports:
            to_server = True
        elif seg.sport in server_ports and seg.dport not in server_ports:
            to_server = False
        elif syn_only or syn_ack:
            to_server = bool(syn_only)
        else:
            to_server = True  # the first to speak is the client
        client, server = (seg.src, seg.dst) if to_server else (seg.dst, seg.src)
        server_port = seg.dport if to_server else seg.sport
        pair = self._allocate()
        if pair is None:
            self.refused.add(key)
            self.warnings.append(
                f"more connections than {MAX_CHANNEL + 1} channels can hold: "
                f"{seg.transport} {client} > {server} and later ones are left out"
            )
            return None
        conn = _Connection(seg.transport, client, server, server_port, pair)
        conn.carrier = carriers.forced(self.carrier, seg.transport)
        if conn.carrier is not None:
            self._label(conn)
        self.connections[key] = conn
        return conn

    def _allocate(self) -> tuple[int, int] | None:
        while True:
            first = 2 * self.next_pair
            if first + 1 > MAX_CHANNEL:
                return None
            self.next_pair += 1
            if first not in self.reserved and first + 1 not in self.reserved:
                return (first, first + 1)

    def _label(self, conn: _Connection) -> None:
        assert conn.carrier is not None
        for side, channel in enumerate(conn.channels):
            sender, receiver = (
                (conn.client, conn.server) if side == 0 else (conn.server, conn.client)
            )
            role = Direction.MASTER if side == 0 else Direction.SLAVE
            label = carriers.ChannelLabel(conn.transport, sender, receiver, conn.carrier, role)
            self.channels[channel] = label.text

    def _emit(self, conn: _Connection, side: int, pieces: list[Piece], out: list[Chunk]) -> None:
        if not pieces:
            return
        channel = conn.channels[side]
        direction = Direction.MASTER if side == 0 else Direction.SLAVE
        for piece in pieces:
            chunk = Chunk(
                data=piece.data,
                t_end=piece.t,
                channel=channel,
                direction=direction,
                event=piece.event,
                note=piece.note,
            )
            if piece.data:
                conn.bytes += len(piece.data)
            if conn.carrier is None:
                conn.held.append(chunk)
                if piece.data:
                    conn.votes.add(piece.data)
            elif conn.carrier != carriers.OTHER:
                out.append(chunk)
        if conn.carrier is None:
            final = len(conn.held) >= MAX_HELD
            self._decide(conn, final=final, out=out)

    def _decide(self, conn: _Connection, *, final: bool, out: list[Chunk]) -> None:
        verdict = conn.votes.verdict(conn.transport, conn.server_port, final)
        if verdict is None:
            return
        conn.carrier = verdict
        if verdict != carriers.OTHER:
            self._label(conn)
            out.extend(conn.held)
        conn.held = []

    def _summarise(self) -> None:
        others = [c for c in self.connections.values() if c.carrier == carriers.OTHER]
        if others:
            names = ", ".join(f"{c.transport} {c.client} > {c.server}" for c in others[:5])
            more = f" and {len(others) - 5} more" if len(others) > 5 else ""
            self.warnings.append(
                f"{len(others)} connection(s) carry neither Modbus TCP nor RTU and are left "
                f"out: {names}{more}; give --carrier and --port to read one anyway"
            )
        gaps = [
            (c, h)
            for c in self.connections.values()
            for h in c.halves
            if h.gaps and c.carrier != carriers.OTHER
        ]
        if gaps:
            total = sum(h.gap_bytes for _, h in gaps)
            self.warnings.append(
                f"{sum(h.gaps for _, h in gaps)} gap(s) in TCP streams, {total} bytes the "
                "capture does not hold; the frames around each gap are marked"
            )
        if self.skipped:
            parts = ", ".join(f"{n} {reason}" for reason, n in sorted(self.skipped.items()))
            self.warnings.append(f"packets without Modbus left out: {parts}")

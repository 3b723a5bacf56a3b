"""Provides the network decoder: captured packets in, chunks per connection direction out.

Each TCP connection (and each UDP flow between two endpoints) gets two channels, in a
pair: `2k` for what the client sends (requests, `Direction.MASTER`) and `2k + 1` for what
the server sends (answers, `Direction.SLAVE`). The channel label (see `carrier`) names
the sender, the receiver and the carrier, and is written into the capture's channel
table before the channel's first chunk leaves.

The server is the side on `--port` when one is given, else the side on port 502 or 503,
else the side a SYN was sent to, else the side that did not speak first.

TCP bytes come out reassembled (see `tcp`); a UDP datagram is one chunk. Chunk times are
packet capture times, and a chunk's bytes all have its packet's time (`t_start` is
`t_end`): the sender had the whole payload when it sent the packet, so no line speed
applies and no byte is dated before the packet that carried it.

A connection's chunks are held back until its carrier is known (a few payloads, see
`carrier`); connections that carry neither Modbus TCP nor RTU are left out with one
warning that names them. Chunks leave in time order over all connections: those of
connections already known wait behind the chunks a connection still holds. So that
nothing waits long, a connection's carrier is decided when it closes (FIN or RST), when
its oldest held chunk is `HOLD_SPAN` seconds of capture time old, or when `MAX_READY`
chunks wait behind it, on the evidence it has by then. A connection that has sent no
payload by then (opened, then silent) gives its events out under a provisional label
(the port's guess: Modbus TCP on 502 and 503, else `other`) and is decided by its
first payloads when they come.

Channels are numbered in one byte, so at most 128 connections get a pair of their own.
Past that, a connection takes the pair of a closed one (FIN both ways, or a reset)
between the same client host and the same server `ip:port`: a poller that connects
anew for each poll goes on in the channels of its first connections. The pair's labels
then name the client by its host only (`192.168.1.10:*`, the port varies: each
connection's own port is in its opening event, `REUSED`), it carries what the closed
connection carried (the same client and server: taken to be the same polling, not
detected again), and the bytes and open requests of the closed connection end there
(`sniffer.framing.tcp.NetPipeline`). A connection that finds no such pair is left out;
one warning at the end says how many were, and names the first.
"""

from __future__ import annotations

import heapq
from collections import Counter, deque
from dataclasses import dataclass, field

import sniffer.sources.net.carrier as carriers
from sniffer.model import Chunk, Direction
from sniffer.sources.net.packets import TCP_ACK, TCP_FIN, TCP_RST, TCP_SYN, Segment, Skip, decode
from sniffer.sources.net.tcp import CONNECTION, Piece, TcpHalf

MAX_CHANNEL = 255  # the frame store keeps channel numbers in one byte
MAX_HELD = 64  # chunks a connection may hold while its carrier is being detected
HOLD_SPAN = 10.0  # seconds of capture time a connection may hold chunks back
MAX_READY = 1 << 16  # chunks that may wait behind a connection holding its own back
# the note of the event that starts a connection in the channels of a closed one
REUSED = "a new connection in the channels of a closed one, from "


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
    provisional: bool = False  # labelled by its port's guess while its payload is awaited
    reset: bool = False  # a reset ended it (both directions)
    shown_client: str = ""  # the client as its channels' labels name it (else `client`)

    @property
    def closed(self) -> bool:
        return self.reset or all(h.closed for h in self.halves)


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
        # closed connections whose channels a new one may take: (transport, client host,
        # server) -> connections, oldest first
        self.closed: dict[tuple[str, str, str], deque[_Connection]] = {}
        self.retired: set[tuple[str, str, str]] = set()  # whose channels went to another
        self.left_out = 0  # connections that found no channels
        self.first_left_out = ""
        self.last_t = 0.0
        # chunks of connections whose carrier is known, in time order, waiting until no
        # connection holds an older one
        self.ready: deque[Chunk] = deque()
        # connections holding chunks, in the order they began to (oldest held first)
        self.holding: dict[_Connection, None] = {}

    # -- input ---------------------------------------------------------------------------

    def packet(self, linktype: int, t: float, data: bytes) -> list[Chunk]:
        self.last_t = max(self.last_t, t)
        found = decode(linktype, data)
        self._check_holes(t)
        if isinstance(found, Skip):
            self.skipped[found.reason] += 1
            return self._flow(t)
        conn = self._connection(found)
        if conn is None:
            return self._flow(t)
        sending = 0 if found.src == conn.client else 1
        if found.transport == "udp":
            if found.payload:
                self._emit(conn, sending, [Piece(t, data=found.payload)])
            if found.missing:
                note = f"{found.missing} bytes cut off by the capture's snap length"
                self._emit(conn, sending, [Piece(t, event="gap", note=note)])
            return self._flow(t)
        half = conn.halves[sending]
        pieces = half.segment(found, t)
        if found.flags & TCP_RST:
            conn.reset = True
        if found.ack is not None:
            other = conn.halves[1 - sending]
            pieces_other = other.acknowledged(found.ack, t)
            self._emit(conn, 1 - sending, pieces_other)
        self._emit(conn, sending, pieces)
        for side in (0, 1):
            key = (conn, side)
            if conn.halves[side].waiting:
                self.waiting.add(key)
            else:
                self.waiting.discard(key)
        return self._flow(t)

    def finish(self) -> list[Chunk]:
        """The capture ended: holes become gaps, held chunks leave, warnings are written."""
        t = self.last_t
        for conn in self.connections.values():
            for side in (0, 1):
                self._emit(conn, side, conn.halves[side].flush(t))
        for conn in list(self.holding):
            self._decide(conn, final=True)
        self.waiting.clear()
        self._summarise()
        out = list(self.ready)
        self.ready.clear()
        return out

    # -- internals -----------------------------------------------------------------------

    def _flow(self, now: float) -> list[Chunk]:
        """The chunks that may leave at capture time `now`: those no older than every
        chunk a connection still holds (see the module doc)."""
        out: list[Chunk] = []
        self._release(out)
        holding = self.holding
        while holding:
            first = next(iter(holding))
            if now - first.held[0].t_end <= HOLD_SPAN and len(self.ready) <= MAX_READY:
                break
            self._decide(first, final=True, waited=True)
            self._release(out)
        return out

    def _release(self, out: list[Chunk]) -> None:
        """Move the ready chunks that no held chunk precedes to `out`."""
        ready = self.ready
        if not ready:
            return
        if not self.holding:
            out.extend(ready)
            ready.clear()
            return
        # the first holder began to hold first: no other holds an older chunk
        until = next(iter(self.holding)).held[0].t_end
        while ready and ready[0].t_end <= until:
            out.append(ready.popleft())

    def _check_holes(self, t: float) -> None:
        if not self.waiting:
            return
        for conn, side in list(self.waiting):
            pieces = conn.halves[side].check(t)
            if pieces:
                self._emit(conn, side, pieces)
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
        if key in self.retired:
            if not seg.flags & TCP_SYN:
                return None  # the rest of a connection whose channels went to another
            self.retired.discard(key)  # the same ports open a new connection
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
        old = None if pair is not None else self._closed_like(seg.transport, client, server)
        if pair is None and old is None:
            self.refused.add(key)
            if not self.left_out:
                self.first_left_out = f"{seg.transport} {client} > {server}"
            self.left_out += 1
            return None
        if old is not None:
            pair = old.channels
            self._retire(old)
        assert pair is not None
        conn = _Connection(seg.transport, client, server, server_port, pair)
        conn.carrier = carriers.forced(self.carrier, seg.transport)
        if old is not None:
            conn.carrier = old.carrier
            conn.shown_client = f"{_host(client)}:*"  # the label: the client's host only
        if conn.carrier is not None:
            self._label(conn)
        self.connections[key] = conn
        if old is not None:
            t = self.last_t
            self._emit(conn, 0, [Piece(t, event=CONNECTION, note=REUSED + client)])
        return conn

    def _closed_like(self, transport: str, client: str, server: str) -> _Connection | None:
        """A closed connection of the same client host to the same server whose channels
        a new one may take (see the module doc)."""
        waiting = self.closed.get((transport, _host(client), server))
        while waiting:
            conn = waiting.popleft()
            if conn.closed and not conn.held and conn.carrier not in (None, carriers.OTHER):
                return conn
        return None

    def _retire(self, conn: _Connection) -> None:
        """`conn` gives its channels to a new connection: what it still sends is ignored."""
        for key, known in list(self.connections.items()):
            if known is conn:
                del self.connections[key]
                self.retired.add(key)
                break
        for side in (0, 1):
            self.waiting.discard((conn, side))

    def _closing(self, conn: _Connection) -> None:
        """`conn` has closed: a later connection may take its channels (module doc)."""
        if conn.transport != "tcp" or not conn.closed:
            return
        key = (conn.transport, _host(conn.client), conn.server)
        waiting = self.closed.setdefault(key, deque())
        if conn not in waiting:
            waiting.append(conn)

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
        client = conn.shown_client or conn.client
        for side, channel in enumerate(conn.channels):
            sender, receiver = (client, conn.server) if side == 0 else (conn.server, client)
            role = Direction.MASTER if side == 0 else Direction.SLAVE
            label = carriers.ChannelLabel(conn.transport, sender, receiver, conn.carrier, role)
            self.channels[channel] = label.text

    def _emit(self, conn: _Connection, side: int, pieces: list[Piece]) -> None:
        if not pieces:
            return
        channel = conn.channels[side]
        direction = Direction.MASTER if side == 0 else Direction.SLAVE
        closes = False
        for piece in pieces:
            chunk = Chunk(
                data=piece.data,
                t_end=piece.t,
                t_start=piece.t if piece.data else None,  # a packet's bytes: all at its time
                channel=channel,
                direction=direction,
                event=piece.event,
                note=piece.note,
            )
            closes = closes or piece.closes
            if piece.closes:
                self._closing(conn)
            if piece.data:
                conn.bytes += len(piece.data)
            if conn.carrier is None and (piece.data or conn.held or not conn.provisional):
                if not conn.held:
                    self.holding[conn] = None
                conn.held.append(chunk)
                if piece.data:
                    conn.votes.add(piece.data)
            elif conn.carrier != carriers.OTHER:
                self.ready.append(chunk)
        if conn.carrier is None and conn.held:
            self._decide(conn, final=closes or len(conn.held) >= MAX_HELD)

    def _decide(self, conn: _Connection, *, final: bool, waited: bool = False) -> None:
        """Decide the carrier of `conn` from its votes (`final`: on what it has); the
        chunks it held join those ready, in time order. `waited`: it held them too long
        (see the module doc)."""
        if waited and not conn.votes.seen:
            # opened, then silent: its events go out under the port's guess, and its
            # first payloads decide
            conn.carrier = (
                (carriers.MODBUS_TCP if conn.transport == "tcp" else carriers.MODBUS_UDP)
                if conn.server_port in carriers.MODBUS_PORTS
                else carriers.OTHER
            )
            self._label(conn)
            conn.carrier = None
            conn.provisional = True
            self._release_held(conn)
            return
        verdict = conn.votes.verdict(conn.transport, conn.server_port, final)
        if verdict is None:
            return
        conn.carrier = verdict
        conn.provisional = False
        if verdict != carriers.OTHER:
            self._label(conn)
            self._release_held(conn)
        else:
            self.holding.pop(conn, None)
            conn.held = []

    def _release_held(self, conn: _Connection) -> None:
        self.holding.pop(conn, None)
        held, conn.held = conn.held, []
        if not held:
            return
        if not self.ready or self.ready[-1].t_end <= held[0].t_end:
            self.ready.extend(held)
        else:  # older than chunks already waiting: merged in by time
            self.ready = deque(heapq.merge(self.ready, held, key=_time))

    def _summarise(self) -> None:
        if self.left_out:
            self.warnings.append(
                f"{self.left_out:,} connection(s) left out, from {self.first_left_out} on: "
                f"modscope reads {(MAX_CHANNEL + 1) // 2} connections at once, and a new one "
                "goes on only in the channels of a closed one of the same client host and "
                "server; give --port, or split the capture (editcap)"
            )
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
        conflicts = sum(h.conflicts for c in self.connections.values() for h in c.halves)
        if conflicts:
            self.warnings.append(
                f"{conflicts} TCP retransmission(s) carry bytes different from those first "
                "sent (a reassembly error); the first bytes were kept, each place is marked"
            )
        if self.skipped:
            parts = ", ".join(f"{n} {reason}" for reason, n in sorted(self.skipped.items()))
            self.warnings.append(f"packets without Modbus left out: {parts}")


def _host(endpoint: str) -> str:
    """The address of an `ip:port` endpoint (`[v6]:port` too)."""
    return endpoint.rsplit(":", 1)[0]


def _time(chunk: Chunk) -> float:
    return chunk.t_end

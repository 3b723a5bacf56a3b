"""Provides TCP reassembly: one direction's segments in, its byte stream in order out.

`TcpHalf.segment()` takes the segments of one direction of one connection as captured
and returns `Piece`s: runs of bytes in stream order, and events (connection opened,
closed, reset, and gaps). The rules:

- retransmitted bytes (sequence numbers already delivered) are dropped; a segment that
  overlaps what was delivered gives only its new bytes. Where its old bytes differ from
  those delivered (within the last `RECENT` bytes), a `REASSEMBLY` event says so and the
  first bytes are kept (Wireshark reports the same case as a reassembly error, and keeps
  the first too);
- a segment ahead of the next expected byte waits until the hole before it is filled
  (out-of-order capture); its bytes come out with the time of the packet that filled
  the hole, when the receiver could first read them;
- a hole is never guessed over: it becomes a `gap` event with the number of missing
  bytes when it cannot be filled any more, that is when the receiver acknowledges bytes
  past it (the capture missed what the receiver got), when the waiting segments pass
  `PENDING_LIMIT` bytes or wait more than `REORDER_WAIT` seconds of capture time, when
  the connection closes or resets, or at the end of the capture (`flush`);
- bytes the capture's snap length cut off are a gap as well.

Sequence numbers wrap at 2**32; comparisons are made modulo that. Segments waiting
behind a hole are kept by their position in the stream (not wrapped) in a heap, so that
thousands of tiny or out-of-order segments cost a logarithm each, not a scan of all the
others.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass, field

from sniffer.sources.net.packets import TCP_ACK, TCP_FIN, TCP_RST, TCP_SYN, Segment

SEQ_MOD = 1 << 32
REORDER_WAIT = 2.0  # seconds of capture time a hole may wait for its segment
PENDING_LIMIT = 1 << 18  # bytes waiting behind a hole before the hole is declared a gap

GAP = "gap"
CONNECTION = "connection"
REASSEMBLY = "reassembly error"
RECENT = 1 << 16  # delivered bytes kept to compare with retransmissions


def seq_diff(a: int, b: int) -> int:
    """`a - b` in sequence space: negative when `a` lies before `b` (modulo 2**32)."""
    return (a - b + (1 << 31)) % SEQ_MOD - (1 << 31)


@dataclass(frozen=True, slots=True)
class Piece:
    """Bytes in stream order (`data`), or an event (`event` with its `note`), at time `t`;
    `closes`: the event is the sender's FIN or a reset."""

    t: float
    data: bytes = b""
    event: str = ""
    note: str = ""
    closes: bool = False


@dataclass(slots=True)
class _Waiting:
    data: bytes
    missing: int
    fin: bool
    t: float


@dataclass
class TcpHalf:
    """One direction of a TCP connection (see the module doc)."""

    next: int | None = None  # sequence number of the next byte expected
    isn: int | None = None
    acked: int | None = None  # highest acknowledgement the other side sent
    waiting: dict[int, _Waiting] = field(default_factory=dict)  # by stream position
    heap: list[int] = field(default_factory=list)  # the positions in `waiting`
    position: int = 0  # the stream position of `next` (not wrapped)
    waiting_bytes: int = 0
    hole_since: float | None = None
    closed: bool = False
    delivered: int = 0
    retransmitted: int = 0  # bytes dropped as already delivered
    conflicts: int = 0  # retransmissions whose bytes differed from those delivered
    recent: bytearray = field(default_factory=bytearray)  # the last bytes delivered
    # the stream position just past `recent`'s last byte: a FIN takes a sequence number
    # and no byte, so `position` may be past it (#30, found by tests/fuzz)
    recent_end: int = 0
    gaps: int = 0
    gap_bytes: int = 0

    def segment(self, seg: Segment, t: float) -> list[Piece]:
        out: list[Piece] = []
        seq = seg.seq
        if seg.flags & TCP_SYN:
            if self.isn == seq and self.next is not None:
                return out  # a retransmitted SYN
            if self.next is not None:
                out.extend(self.flush(t, "a new connection started on the same ports"))
            self.isn = seq
            self.closed = False
            seq = (seq + 1) % SEQ_MOD
            self.next = seq
            self.position = 0
            self.recent.clear()
            self.recent_end = 0
            note = "accepted (SYN ACK)" if seg.flags & TCP_ACK else "opened (SYN)"
            out.append(Piece(t, event=CONNECTION, note=note))
        if seg.flags & TCP_RST:
            if self.next is None:
                # the first this side sent (a refused SYN is answered RST ACK): its bytes,
                # if any, start the stream
                self.next = seq
            out.extend(self._arrive(seq, seg.payload, seg.missing, False, t))
            out.extend(self.flush(t, "the connection was reset"))
            out.append(Piece(t, event=CONNECTION, note="reset (RST)", closes=True))
            self.closed = True
            return out
        fin = bool(seg.flags & TCP_FIN)
        if not seg.payload and not seg.missing and not fin:
            return out
        if self.next is None:
            self.next = seq  # the capture started inside the connection
        out.extend(self._arrive(seq, seg.payload, seg.missing, fin, t))
        return out

    def acknowledged(self, ack: int, t: float) -> list[Piece]:
        """The other side acknowledged bytes up to `ack`: a hole before it will not be
        filled by a retransmission, so it is a gap in the capture."""
        if self.acked is None or seq_diff(ack, self.acked) > 0:
            self.acked = ack
        if self.waiting and self.next is not None and seq_diff(ack, self.next) > 0:
            return self._gap(t, "the receiver acknowledged bytes the capture does not hold")
        return []

    def check(self, t: float) -> list[Piece]:
        """Declare the hole a gap once it has waited too long (call as time passes)."""
        if self.hole_since is not None and t - self.hole_since > REORDER_WAIT:
            return self._gap(t, f"no segment filled it within {REORDER_WAIT:g} s")
        return []

    def flush(self, t: float, why: str = "the capture ended") -> list[Piece]:
        """Deliver what waits behind holes, each hole reported as a gap."""
        out: list[Piece] = []
        while self.waiting:
            out.extend(self._gap(t, why))
        self.heap.clear()
        return out

    def _advance(self, count: int) -> None:
        assert self.next is not None
        self.next = (self.next + count) % SEQ_MOD
        self.position += count

    # -- internals -----------------------------------------------------------------------

    def _arrive(self, seq: int, data: bytes, missing: int, fin: bool, t: float) -> list[Piece]:
        assert self.next is not None
        out: list[Piece] = []
        ahead = seq_diff(seq, self.next)
        if ahead > 0:
            at = self.position + ahead
            known = self.waiting.get(at)
            if known is None or len(data) + missing > len(known.data) + known.missing:
                if known is not None:
                    self.waiting_bytes -= len(known.data)
                else:
                    heapq.heappush(self.heap, at)
                self.waiting[at] = _Waiting(data, missing, fin, t)
                self.waiting_bytes += len(data)
            if self.hole_since is None:
                self.hole_since = t
            if self.acked is not None and seq_diff(self.acked, self.next) > 0:
                out.extend(
                    self._gap(t, "the receiver acknowledged bytes the capture does not hold")
                )
            elif self.waiting_bytes > PENDING_LIMIT:
                out.extend(self._gap(t, f"more than {PENDING_LIMIT} bytes wait behind it"))
            return out
        out.extend(self._deliver(ahead, data, missing, fin, t))
        out.extend(self._drain(t))
        return out

    def _deliver(self, ahead: int, data: bytes, missing: int, fin: bool, t: float) -> list[Piece]:
        """Deliver a segment starting `ahead` (<= 0) bytes from the next expected byte."""
        assert self.next is not None
        out: list[Piece] = []
        old = -ahead  # bytes at the segment's start that were delivered already
        if old:
            seen = min(old, len(data))
            self.retransmitted += seen
            out.extend(self._compare(old, data[:seen], t))
            data = data[seen:]
            missing = max(0, missing - (old - seen))
        if data:
            out.append(Piece(t, data=data))
            self.delivered += len(data)
            self._advance(len(data))
            recent = self.recent
            recent += data
            if len(recent) > 2 * RECENT:
                del recent[:-RECENT]
            self.recent_end = self.position
        if missing:
            out.append(
                Piece(t, event=GAP, note=f"{missing} bytes cut off by the capture's snap length")
            )
            self.gaps += 1
            self.gap_bytes += missing
            self._advance(missing)
            self.recent.clear()  # bytes before a gap are not compared with those after it
        if fin and not self.closed:
            self.closed = True
            self._advance(1)
            out.append(Piece(t, event=CONNECTION, note="closed by the sender (FIN)", closes=True))
        return out

    def _compare(self, old: int, again: bytes, t: float) -> list[Piece]:
        """A retransmission of bytes that began `old` bytes before the next expected:
        a `REASSEMBLY` event when they differ from those delivered (module doc)."""
        recent = self.recent
        # where `again` begins in `recent`: `old` bytes before the next expected byte,
        # which may be past the last byte delivered (a FIN)
        start = len(recent) - (self.recent_end - (self.position - old))
        if start < 0 or start >= len(recent) or not again:
            return []  # older than the bytes kept: not compared
        first = bytes(recent[start : start + len(again)])
        if first == again[: len(first)]:
            return []
        self.conflicts += 1
        differ = sum(a != b for a, b in zip(first, again, strict=False))
        note = (
            f"a retransmission carries {differ} byte(s) different from those delivered "
            f"{old} byte(s) back; the first were kept"
        )
        return [Piece(t, event=REASSEMBLY, note=note)]

    def _drain(self, t: float) -> list[Piece]:
        """Deliver waiting segments that now follow on, in stream order."""
        out: list[Piece] = []
        heap, waiting = self.heap, self.waiting
        while heap and heap[0] <= self.position and self.next is not None:
            at = heapq.heappop(heap)
            w = waiting.pop(at, None)
            if w is None:
                continue
            self.waiting_bytes -= len(w.data)
            ahead = at - self.position
            if ahead + len(w.data) + w.missing <= 0 and not w.fin:
                self.retransmitted += len(w.data)
                continue
            out.extend(self._deliver(ahead, w.data, w.missing, w.fin, t))
        self.hole_since = t if waiting else None
        return out

    def _gap(self, t: float, why: str) -> list[Piece]:
        """The hole before the first waiting segment will not be filled: report it, then
        go on from that segment."""
        if not self.waiting or self.next is None:
            return []
        while self.heap[0] not in self.waiting:
            heapq.heappop(self.heap)
        size = self.heap[0] - self.position
        self.gaps += 1
        self.gap_bytes += size
        out = [Piece(t, event=GAP, note=f"{size} bytes missing from the capture; {why}")]
        self._advance(size)
        self.recent.clear()  # bytes before a gap are not compared with those after it
        self.hole_since = None
        out.extend(self._drain(t))
        return out

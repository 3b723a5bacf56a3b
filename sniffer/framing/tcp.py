"""Provides Modbus TCP framing and pairing, and the pipeline for network captures.

`TcpFramer` has the RTU and ASCII framers' interface (feed, flush, idle, finish,
line_error, `out`, `pair_inline`) and cuts one direction of a connection into MBAP
frames by their length field. A row's raw bytes are the whole frame, header and PDU;
the body `dissect()` takes is `dissectors.mbap.body(raw)` (the unit byte on). The row's
unit and function columns are set from the unit byte and the PDU, not from the header,
and the row carries the `MBAP` flag so that every later stage can tell.

Bytes that cannot start a frame (protocol id not 0, a length out of range) are noise
until a position where a plausible header starts; a frame cut short by a gap in the
captured stream, or by the end of the capture, keeps its bytes and the `CUT_SHORT`
flag. `NetPairer` pairs by connection and transaction id with any number of requests in
flight; a request reusing an id still in flight gets `TID_REUSED`; an answer to an id
nobody asked for is an orphan. A request that timed out still takes a late answer with
its id for `LATE_WAITS` timeouts after it was sent, no longer (see `NetPairer`). RTU
frames over TCP/UDP are paired one transaction at a time per connection, as on a serial
line.

`PacketRtuFramer` is the RTU framer for RTU over TCP/UDP. No serial line speed applies
to a payload: the sender (a serial server that read the frame off its line, or a device
that speaks RTU framing over TCP) had the whole payload when it sent the packet, so
every byte has its packet's time, never a time back-dated by a baud rate. Each packet
starts at a boundary, as silence does on a line: bytes no frame claims are split into
noise at packet starts, and a whole packet of frame size (4 to 256 bytes) from a unit
the connection knows, or of the length its function code gives, is a frame with a bad
check (a CRC garbled on the serial side, swapped by a buggy gateway), not noise. One
request is in flight per connection: when one side sends, the bytes the other side
left undecided are decided (its turn is over).

`NetPipeline` is the pipeline with these plugged in: a channel whose label (see
`sniffer.sources.net.carrier`) says `modbus-tcp` or `modbus-udp` is framed by a
`TcpFramer`; the other network channels by a `PacketRtuFramer`. The decoder gives
chunks in time order over all connections (`sniffer.sources.net.decoder`), so rows are
merged as soon as no channel can still give an older one: rows are stored in time
order, a request before its answer when both have the same time.

A connection that takes the channels of a closed one (past 128 connections, see
`sniffer.sources.net.decoder`) starts with a `REUSED` event: what the closed one left
unframed is closed as it is (as at a gap), its requests still open time out (no answer
can come on another connection), and the channels' peers are read again from their
labels.
"""

from __future__ import annotations

from bisect import bisect_right
from collections import deque
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, cast

from dissectors import mbap
from dissectors.functions import FUNCTIONS, FunctionSpec
from sniffer.framing.lengths import MAX_RTU, MIN_RTU
from sniffer.framing.pipeline import Pipeline, _Channel
from sniffer.framing.serial import MAX_NOISE, RtuFramer
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.model import Chunk, Direction, LineSettings
from sniffer.sources.net.carrier import MBAP_CARRIERS, parse_label
from sniffer.sources.net.decoder import REUSED
from sniffer.sources.net.tcp import CONNECTION, GAP
from sniffer.vocab import Flag, Kind, Status

if TYPE_CHECKING:
    from sniffer.framing.serial import Framer
    from sniffer.sources.reads import Reads

# Flag bits of network rows, named in the one table of meanings (sniffer.vocab)
MBAP = int(Flag.MBAP)  # the row is a Modbus TCP frame: raw = MBAP header + PDU (a fact)
ENVELOPE_BAD = int(Flag.ENVELOPE_BAD)  # MBAP protocol id not 0, or a length wrong
TID_REUSED = int(Flag.TID_REUSED)  # a request reusing a transaction id still waiting
CUT_SHORT = int(Flag.CUT_SHORT)  # the frame was cut by a gap in the captured stream

STAGING_ROWS = 4096  # rows a channel's staging store may hold merged before it is replaced
TCP_TIMEOUT = 3.0  # seconds: Modbus TCP clients (pymodbus, libmodbus) wait about this long
# How long a Modbus TCP request that timed out still takes a late answer with its
# transaction id, in timeouts from its sending (9 s at the default timeout). The
# protocol leaves it open: an id means nothing once the client gave up (pymodbus and
# libmodbus drop an answer that comes after their timeout), and Wireshark pairs by id
# whenever the answer comes. An answer later than this is an orphan. Without a bound, a
# capture with one timeout would never be settled again (`settled`) and could not be
# read a window of rows at a time.
LATE_WAITS = 3


def body(raw: bytes, flags: int) -> bytes:
    """Unit byte and PDU of a network row (`MBAP` rows), else the RTU body."""
    if flags & MBAP:
        return mbap.body(raw)
    return raw[:-2]


class TcpFramer:
    """Frames one direction of a Modbus TCP connection into `out` (module doc)."""

    def __init__(
        self,
        line: LineSettings,
        out: FrameStore,
        *,
        channel: int = 0,
        direction: Direction = Direction.UNKNOWN,
        exact_timing: bool = False,
        functions: Mapping[int, FunctionSpec] = FUNCTIONS,
    ) -> None:
        self.line = line
        self.out = out
        self.stream = out.stream(channel)
        self.channel = channel
        self.direction = direction
        self.pos = len(self.stream)
        self.pair_inline = False  # pairing is NetPairer's, over the merged store
        self.starts: list[int] = []  # stream offset where each chunk starts
        self.times: list[float] = []  # its time

    # -- the framer interface --------------------------------------------------------

    def feed(self, chunk: Chunk) -> None:
        if not chunk.data:
            return
        self.starts.append(len(self.stream))
        self.times.append(chunk.t_end)
        self.stream += chunk.data
        self._scan(final=False)

    def flush(self) -> None:
        """Rows are complete as they are written."""

    def idle(self) -> None:
        """A TCP stream keeps its bytes over any pause."""

    def line_error(self) -> None:
        """Network captures report no line errors."""

    def finish(self) -> None:
        self._scan(final=True)

    def gap(self) -> None:
        """Bytes are missing from the stream here: what is open is closed as it is."""
        self._scan(final=True)

    def start_pending(self) -> float | None:
        """The time of the first byte not yet in a row; None when every byte is."""
        return self._time(self.pos) if self.pos < len(self.stream) else None

    def decided(self) -> int:
        """The offset of the first byte not yet decided (see `_Framer.decided`): noise is
        written as soon as it is found, so none is ever under way."""
        return self.pos

    def undecided(self) -> bool:
        return self.decided() < len(self.stream)

    def settled(self) -> bool:
        """Every byte given is in a row: the next row owes nothing to the bytes before
        (see `rebase`)."""
        return not self.undecided()

    def rebase(self) -> None:
        """A settled framer's stream offsets from 0 again, its stream about to be emptied
        (`sniffer.session.session.Session.new_segment`)."""
        self.pos = 0
        self.starts.clear()
        self.times.clear()

    # -- internals -------------------------------------------------------------------

    def _scan(self, final: bool) -> None:
        buf = self.stream
        end = len(buf)
        pos = self.pos
        while pos < end:
            size = mbap.announced(buf, pos)
            if size is None or (end - pos < mbap.HEADER_SIZE + 1 and not final):
                if final:
                    self._frame(pos, end, CUT_SHORT)
                    pos = end
                break
            if not mbap.plausible(buf, pos):
                nxt = self._resync(pos + 1, end, final)
                if nxt is None:
                    break
                self._noise(pos, nxt)
                pos = nxt
                continue
            if end - pos < size:
                if final:
                    self._frame(pos, end, CUT_SHORT)
                    pos = end
                break
            self._frame(pos, pos + size, 0)
            pos += size
        self.pos = pos
        self._forget(pos)

    def _resync(self, start: int, end: int, final: bool) -> int | None:
        """The next offset where a frame plausibly starts and is confirmed (by the header
        after it, or by ending exactly at the stream's end); None to wait for more."""
        buf = self.stream
        for p in range(start, end):
            if not mbap.plausible(buf, p):
                continue
            size = mbap.announced(buf, p)
            assert size is not None
            after = p + size
            if after == end or (after < end and mbap.plausible(buf, after)):
                return p
            if after > end and not final:
                return None  # wait: the candidate is not complete yet
        if final:
            return end
        # keep at most one frame's worth undecided; older bytes are noise
        return max(start, end - mbap.MAX_FRAME) if end - start > mbap.MAX_FRAME else None

    def _time(self, pos: int) -> float:
        k = bisect_right(self.starts, pos) - 1
        return self.times[k if k >= 0 else 0]

    def _forget(self, pos: int) -> None:
        k = bisect_right(self.starts, pos) - 1
        if k > 0:
            del self.starts[:k]
            del self.times[:k]

    def _noise(self, start: int, end: int) -> None:
        for piece in range(start, end, MAX_NOISE):
            stop = min(end, piece + MAX_NOISE)
            self.out.add_row(
                self.channel,
                piece,
                stop - piece,
                self._time(piece),
                self._time(stop - 1),
                int(Kind.NOISE),
                MBAP,
            )

    def _frame(self, start: int, end: int, flags: int) -> None:
        raw = bytes(self.stream[start:end])
        header = mbap.parse(raw)
        flags |= MBAP
        if header.problems and not flags & CUT_SHORT:
            flags |= ENVELOPE_BAD
        fc = raw[7] if len(raw) > 7 else 0
        if self.direction == Direction.MASTER:
            kind = Kind.REQUEST
        elif self.direction == Direction.SLAVE:
            kind = Kind.EXCEPTION if fc & 0x80 else Kind.RESPONSE
        else:
            kind = Kind.UNKNOWN
        out = self.out
        out.add_row(
            self.channel,
            start,
            end - start,
            self._time(start),
            self._time(end - 1),
            int(kind),
            flags,
        )
        out.unit[-1] = header.unit
        out.fc[-1] = fc


class PacketRtuFramer(RtuFramer):
    """Frames one direction of an RTU over TCP/UDP connection (module doc)."""

    def feed(self, chunk: Chunk) -> None:
        if not chunk.data:
            return
        tl = self.timeline
        start = len(self.stream)
        tl.add_read(len(chunk.data), chunk.t_end, chunk.t_end)  # every byte at packet time
        if not tl.boundaries or tl.boundaries[-1] != start:
            tl.boundaries.append(start)  # a packet starts here, whatever the gap before
        self.stream += chunk.data
        self._scan(final=False)

    def feed_reads(self, reads: Reads) -> None:
        for chunk in reads.split():
            self.feed(chunk)

    def start_pending(self) -> float | None:
        """The time of the first byte not yet in a row; None when every byte is."""
        first = self.decided()
        if first >= len(self.stream):
            return None
        return self.timeline.start_time(first)

    def _emit_noise(self, start: int, end: int) -> None:
        tl = self.timeline
        while start < end:
            nxt = tl.next_boundary(start)
            stop = end if nxt is None or nxt >= end else nxt
            super()._emit_noise(start, stop)
            start = stop

    def _plausible_frame(self, start: int, length: int) -> bool:
        tl = self.timeline
        stop = start + length
        buf = self.stream
        if (
            MIN_RTU <= length <= MAX_RTU
            and tl.is_boundary(start)
            and (stop == len(buf) or tl.is_boundary(stop))
            and (
                buf[start] in self.units_seen
                or any(
                    rule.length(buf, start, stop) == length
                    for rule, _ in self.rules[buf[start + 1]]
                )
            )
        ):
            return True  # one whole packet: what the sender sent as one frame
        return super()._plausible_frame(start, length)


class NetPairer:
    """Pairs the rows of network channels (module doc). Channels `2k` and `2k + 1` are
    the two directions of one connection (see `sniffer.sources.net.decoder`)."""

    def __init__(self, store: FrameStore, timeout: float) -> None:
        self.store = store
        self.timeout = timeout  # what the client waits
        self.end_time = float("-inf")
        self.next = 0
        # Modbus TCP: (connection, transaction id) -> requests waiting, oldest first
        self.open: dict[tuple[int, int], deque[int]] = {}
        self.late: dict[tuple[int, int], int] = {}  # timed out, an answer may still come
        # (until when, key, request) of each entry of `late`, in time order: LATE_WAITS
        self.late_until: deque[tuple[float, tuple[int, int], int]] = deque()
        self.waiting: deque[int] = deque()  # requests in time order, for timeouts
        self.serial_open: dict[int, int] = {}  # RTU over TCP/UDP: connection -> request

    def update(self) -> None:
        s = self.store
        s.sync()
        n = len(s)
        for i in range(self.next, n):
            kind = s.kind[i]
            if kind == Kind.NOISE or kind == Kind.EVENT:
                continue
            self._expire(s.t[i])
            if s.flags[i] & MBAP:
                self._mbap(i)
            else:
                self._serial(i)
        self.next = n

    def tick(self, now: float) -> None:
        self.update()
        self._expire(now)

    def finish(self) -> None:
        self.update()
        s = self.store
        if len(s):
            end = max(s.t_end[len(s) - 1], self.end_time)
            self._expire(end)

    def settled(self) -> bool:
        """No request waits for its answer, nor a late one (`LATE_WAITS`): no row to come
        pairs with a row so far."""
        return not self.open and not self.late and not self.serial_open

    def rebase(self, store: FrameStore) -> None:
        """A settled pairer goes on in `store`, empty, numbering rows from 0 again
        (`sniffer.session.session.Session.new_segment`): the requests waiting for their
        timeout are all answered or timed out, and are forgotten."""
        self.store = store
        self.next = 0
        self.waiting.clear()
        self.late_until.clear()

    # -- internals -------------------------------------------------------------------

    def _tid(self, i: int) -> tuple[int, int]:
        raw = self.store.raw(i)
        return (self.store.channel[i] >> 1, int.from_bytes(raw[0:2], "big"))

    def _mbap(self, i: int) -> None:
        s = self.store
        if s.flags[i] & CUT_SHORT and s.length[i] < 2:
            return
        key = self._tid(i)
        if s.kind[i] == Kind.REQUEST:
            asked = self.open.setdefault(key, deque())
            if asked:
                s.flags[i] |= TID_REUSED
            asked.append(i)
            s.status[i] = Status.OPEN
            self.waiting.append(i)
            return
        queue = self.open.get(key)
        req = -1
        if queue:
            req = queue.popleft()
            if not queue:
                del self.open[key]
        elif key in self.late:
            req = self.late.pop(key)
            s.flags[i] |= Flag.LATE
        if req < 0 or s.fc[req] != s.fc[i] & 0x7F:
            if req >= 0:  # an answer to another question: leave the request waiting
                self.open.setdefault(key, deque()).appendleft(req)
            s.status[i] = Status.ORPHAN
            return
        self._pair(req, i)

    def _serial(self, i: int) -> None:
        s = self.store
        conn = s.channel[i] >> 1
        if s.kind[i] == Kind.REQUEST:
            old = self.serial_open.pop(conn, -1)
            if old >= 0:
                self._time_out(old)
            if s.unit[i] == 0:
                s.status[i] = Status.BROADCAST
            else:
                s.status[i] = Status.OPEN
                self.serial_open[conn] = i
                self.waiting.append(i)
            return
        req = self.serial_open.get(conn, -1)
        if req >= 0 and s.unit[req] == s.unit[i] and s.fc[req] == s.fc[i] & 0x7F:
            del self.serial_open[conn]
            self._pair(req, i)
        elif s.kind[i] != Kind.UNKNOWN:
            s.status[i] = Status.ORPHAN

    def _pair(self, req: int, resp: int) -> None:
        s = self.store
        s.partner[req] = resp
        s.partner[resp] = req
        if s.flags[resp] & (Flag.CHECK_BAD | CUT_SHORT):
            status = Status.BAD_ANSWER
        elif s.fc[resp] & 0x80:
            status = Status.EXCEPTION
        else:
            status = Status.OK
        s.status[req] = s.status[resp] = status
        if s.t[resp] - s.t_end[req] > self.judged:
            s.flags[resp] |= Flag.LATE

    @property
    def judged(self) -> float:
        """The wait past which the row times show an answer overdue (`Pairer.judged`):
        the timeout plus the stamps' resolution."""
        return self.timeout + self.store.resolution

    def _expire(self, now: float) -> None:
        s = self.store
        waiting = self.waiting
        judged = self.judged
        while waiting and now - s.t_end[waiting[0]] > judged:
            req = waiting.popleft()
            if s.status[req] == Status.OPEN and s.partner[req] == NO_PARTNER:
                self._time_out(req)
        late, until = self.late, self.late_until
        while until and now > until[0][0]:
            _, key, req = until.popleft()
            if late.get(key) == req:
                del late[key]  # too late now: an answer with its id is an orphan

    def end_connection(self, conn: int) -> None:
        """Connection `conn` ended and another takes its channels: its open requests time
        out and no late answer is awaited for them."""
        self.update()
        s = self.store
        for key in [k for k in self.open if k[0] == conn]:
            for req in self.open.pop(key):
                if s.partner[req] == NO_PARTNER:
                    s.status[req] = Status.TIMEOUT
        for key in [k for k in self.late if k[0] == conn]:
            del self.late[key]
        req = self.serial_open.pop(conn, -1)
        if req >= 0 and s.partner[req] == NO_PARTNER:
            s.status[req] = Status.TIMEOUT

    def _time_out(self, req: int) -> None:
        s = self.store
        if s.partner[req] != NO_PARTNER:
            return
        s.status[req] = Status.TIMEOUT
        if s.flags[req] & MBAP:
            key = self._tid(req)
            queue = self.open.get(key)
            if queue and req in queue:
                queue.remove(req)
                if not queue:
                    del self.open[key]
            self.late[key] = req
            self.late_until.append((s.t_end[req] + LATE_WAITS * self.timeout, key, req))
        else:
            conn = s.channel[req] >> 1
            if self.serial_open.get(conn) == req:
                del self.serial_open[conn]


class NetPipeline(Pipeline):
    """The pipeline for network captures: `channels` is the capture's channel table,
    whose labels say each channel's carrier (see the module doc)."""

    def __init__(
        self,
        line: LineSettings,
        store: FrameStore | None = None,
        *,
        channels: Mapping[int, str],
        timeout: float | None = None,
        **options: Any,
    ) -> None:
        super().__init__(line, store, timeout=timeout, **options)
        self.channel_labels = channels
        wait = timeout if timeout is not None else TCP_TIMEOUT
        # (judged one resolution later, `NetPairer.judged`: a coarse clock shows no shorter
        # wait; the timeout itself stays what the client waits, which the timing line names)
        self.pairer = NetPairer(self.store, wait)  # type: ignore[assignment]
        self.mode = "rtu"  # RTU over TCP/UDP; Modbus TCP channels get their own framer
        self.units: dict[int, set[int]] = {}  # units seen on each RTU connection
        self.now = float("-inf")  # the newest chunk's time

    def feed(self, chunk: Chunk) -> None:
        if chunk.event == GAP:
            ch = self.channels.get(chunk.channel)
            if ch is not None and isinstance(ch.framer, TcpFramer):
                ch.framer.gap()
        if chunk.event == CONNECTION and chunk.note.startswith(REUSED):
            self._reused(chunk.channel & ~1)
        if chunk.data:
            # one request in flight: when one side sends, the other's turn is over
            other = self.channels.get(chunk.channel ^ 1)
            if (
                other is not None
                and isinstance(other.framer, PacketRtuFramer)
                and other.framer.undecided()
            ):
                other.framer.idle()
        self.now = max(self.now, chunk.t_end)
        super().feed(chunk)

    def _reused(self, first: int) -> None:
        """A new connection in the channels `first`, `first + 1` (module doc)."""
        for number in (first, first + 1):
            ch = self.channels.get(number)
            if ch is not None and isinstance(ch.framer, TcpFramer):
                ch.framer.gap()
            elif ch is not None and isinstance(ch.framer, PacketRtuFramer):
                ch.framer.idle()
            label = parse_label(self.channel_labels.get(number, ""))
            if label is not None and number in self.store.peers:
                self.store.peers[number] = label.sender
        if isinstance(self.pairer, NetPairer):
            self.pairer.end_connection(first >> 1)

    def too_fast(self) -> tuple[int, float | None]:
        """Packets carry bytes as fast as the network does: no line speed applies."""
        return 0, None

    def _add_channel(self, number: int, direction: Direction) -> _Channel:
        ch = super()._add_channel(number, direction)
        label = parse_label(self.channel_labels.get(number, ""))
        if label is not None:
            # named from its first row on, events too (a connection's opening comes
            # before its bytes, which start its framer; and a window of rows may be
            # listed before any come)
            self.store.peers[number] = label.sender
            server = label.sender if label.role == Direction.SLAVE else label.receiver
            self.store.servers[number] = server
        return ch

    def _start_framer(self, ch: _Channel) -> None:
        label = parse_label(self.channel_labels.get(ch.number, ""))
        if label is None:  # a serial interface of the same file
            super()._start_framer(ch)
            return
        out = ch.staging if ch.staging is not None else self.store
        if label.carrier in MBAP_CARRIERS:
            framer = TcpFramer(self.line, out, channel=ch.number, direction=ch.direction)
            ch.framer = cast("Framer", framer)  # the same interface; see docs/ethernet.md
        else:
            rtu = PacketRtuFramer(
                self.line, out, channel=ch.number, direction=ch.direction, functions=self.registry
            )
            rtu.pair_inline = False  # NetPairer pairs, per connection
            rtu.timeout = self.pairer.judged  # (its wait for an echo, as a serial framer's)
            # a unit one side names is known to the other (a garbled answer to it is a frame)
            rtu.units_seen = self.units.setdefault(ch.number >> 1, rtu.units_seen)
            ch.framer = rtu
        held, ch.held = ch.held or [], None
        for old in held:
            if old.event and not old.data:
                self._event(ch, old)  # held in its place (Pipeline.feed)
                continue
            ch.framer.feed(old)
            ch.last_t = old.t_end

    def _release(self, final: bool, now: float | None = None) -> None:
        """Merge the rows no channel can still precede: chunks come in time order, so a
        network channel's next row is no older than its first undecided byte, or than
        the newest chunk when it has none (a serial interface of the same file keeps the
        merge slack)."""
        for ch in self.channels.values():
            if ch.framer is not None:
                ch.framer.flush()
            if ch.events:
                self._settle_events(ch)
        if not self.multi:
            return
        if final:
            self._merge(float("inf"))
            return
        watermark = self.now
        for ch in self.channels.values():
            framer = ch.framer
            if isinstance(framer, PacketRtuFramer | TcpFramer):
                pending = framer.start_pending()
                if pending is not None:
                    watermark = min(watermark, pending)
            elif framer is not None or parse_label(self.channel_labels.get(ch.number, "")) is None:
                watermark = min(watermark, ch.last_t - self.merge_slack)
        if now is not None:
            watermark = max(watermark, now - self.merge_slack)
        self._merge(watermark)

    def _merge(self, watermark: float) -> None:
        """Copy staged rows up to `watermark` into the store in time order; of rows with
        the same time, the lower channel's first (a connection's request before its
        answer)."""
        store = self.store
        staged = [c for c in self.channels.values() if c.staging is not None]
        while True:
            best: _Channel | None = None
            best_key = (watermark, 1 << 16)
            for c in staged:
                st = c.staging
                assert st is not None
                if c.read < len(st):
                    key = (st.t[c.read], c.number)
                    if key[0] <= watermark and key < best_key:
                        best, best_key = c, key
            if best is None:
                break
            assert best.staging is not None
            store.copy_row(best.staging, best.read)
            best.read += 1
        for c in staged:
            st = c.staging
            assert st is not None
            # rows merge as they come: a fresh staging store now and then, not every time
            if c.read >= STAGING_ROWS and c.read == len(st):
                c.staging = FrameStore(store.streams)
                if c.framer is not None:
                    c.framer.out = c.staging
                c.read = 0

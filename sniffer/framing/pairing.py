"""Provides request/response pairing over a frame store: transactions, timeouts, retries.

A sniffer does not know who sent what; the framer already told requests from answers by
their layouts and by order. Pairing then walks the frames in time order with one open
request per bus (Modbus RTU has one transaction in flight at a time) and decides what
became of each: answered, exception, timeout, orphan answer, broadcast, retry.
"""

from __future__ import annotations

from dataclasses import dataclass

from sniffer import core
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.model import LineSettings, Stamp
from sniffer.vocab import BAD_CHECK, Flag, Kind, Status


def default_timeout(line: LineSettings) -> float:
    """Response timeout when none is given: 200 ms plus the time of a longest frame."""
    return 0.2 + 256 * line.char_time


class Pairer:
    """Pairs the frames of a store incrementally: call `update()` after frames arrive,
    `tick(now)` while live so that silent slaves time out, `finish()` at the end."""

    def __init__(
        self, store: FrameStore, timeout: float, answered_broadcasts: frozenset[int] = frozenset()
    ) -> None:
        self.store = store
        self.timeout = timeout
        # vendor function codes whose broadcasts do get an answer (VED903B 0x41)
        self.answered_broadcasts = answered_broadcasts
        self.end_time = float("-inf")  # when the capture ended, if the source said so
        self.next = 0
        self.open = -1  # index of the request waiting for its answer
        self.last_timed_out = b""  # raw bytes of the last request that got no answer
        # the same as 256 bytes, for the compiled loop (made again if the set is replaced)
        self._answered_of = answered_broadcasts
        self._answered = bytes(fc in answered_broadcasts for fc in range(256))

    def update(self) -> None:
        s = self.store
        s.sync()
        n = len(s)
        fast = core.FAST
        if fast is not None and self.next < n:
            if self._answered_of is not self.answered_broadcasts:
                self._answered_of = self.answered_broadcasts
                self._answered = bytes(fc in self._answered_of for fc in range(256))
            # the compiled copy of the loop below (sniffer/_core.c: pair_update): the loop
            # does little for each row, so in Python its cost is mostly the interpreter's
            self.open, last = fast.pair_update(
                s, self.next, self.open, self.timeout, self._answered, self.last_timed_out
            )
            if last != -2:
                self.last_timed_out = b"" if last == -1 else s.raw(last)
            self.next = n
            return
        kind, unit, fc, partner = s.kind, s.unit, s.fc, s.partner
        t, t_end, timeout = s.t, s.t_end, self.timeout
        for i in range(self.next, n):
            k = kind[i]
            if k == 0 or k == 5:  # noise, events
                continue
            op = self.open
            if op >= 0 and t[i] - t_end[op] > timeout:
                self._time_out(op)
                op = -1
            j = partner[i]
            if j >= 0:
                # paired as it was framed (the answer its request predicted)
                if j < i:  # the answer
                    if op == j:
                        self.open = -1
                    if t[i] - t_end[j] > timeout:
                        s.flags[i] |= Flag.LATE
                else:  # the request
                    if op >= 0:
                        self._time_out(op)
                    if self.last_timed_out:
                        self._check_retry(i)
                continue
            if k == 1:  # Kind.REQUEST
                self._request(i)
                continue
            u = unit[i]
            if op >= 0 and unit[op] in (u, 0) and fc[op] == fc[i] & 0x7F:
                self._pair(op, i)
            elif k != Kind.UNKNOWN:
                s.status[i] = Status.ORPHAN
                if u == 0:
                    s.flags[i] |= Flag.ANSWERED_BROADCAST
        self.next = n

    def _check_retry(self, i: int) -> None:
        if self.store.raw(i) == self.last_timed_out:
            self.store.flags[i] |= Flag.RETRY
        self.last_timed_out = b""

    def _request(self, i: int) -> None:
        s = self.store
        if self.open >= 0:
            self._time_out(self.open)
        if s.unit[i] == 0 and s.fc[i] not in self.answered_broadcasts:
            s.status[i] = Status.BROADCAST
            self.open = -1
        else:
            s.status[i] = Status.OPEN
            self.open = i
        if self.last_timed_out:
            self._check_retry(i)

    def _pair(self, req: int, resp: int) -> None:
        s = self.store
        s.partner[req] = resp
        s.partner[resp] = req
        if s.flags[resp] & BAD_CHECK:
            status = Status.BAD_ANSWER
        elif s.fc[resp] & 0x80:
            status = Status.EXCEPTION
        else:
            status = Status.OK
        s.status[req] = status
        s.status[resp] = status
        if s.t[resp] - s.t_end[req] > self.timeout:
            s.flags[resp] |= Flag.LATE
        self.open = -1

    def _time_out(self, req: int) -> None:
        s = self.store
        self.open = -1
        if s.partner[req] != NO_PARTNER:
            return  # answered after all (paired as it was framed)
        s.status[req] = Status.TIMEOUT
        self.last_timed_out = s.raw(req)
        self.open = -1

    def tick(self, now: float) -> None:
        """Time out the open request if its answer is overdue at time `now`."""
        self.update()
        if self.open >= 0 and now - self.store.t_end[self.open] > self.timeout:
            self._time_out(self.open)

    def finish(self) -> None:
        """At the end of a capture an open request stays open: the capture, not the
        slave, may have stopped first (unless the capture went on past the timeout)."""
        self.update()
        s = self.store
        if self.open >= 0:
            end = max(s.t_end[len(s) - 1], self.end_time)
            if end - s.t_end[self.open] > self.timeout:
                self._time_out(self.open)


def latency(store: FrameStore, i: int) -> float | None:
    """Seconds from the end of a request to the start of its answer (either side's index),
    as the row times say; `measure` says what of it the timing can vouch for."""
    j = store.partner[i]
    if j == NO_PARTNER:
        return None
    req, resp = (i, j) if store.kind[i] == Kind.REQUEST else (j, i)
    return store.t[resp] - store.t_end[req]


_REQUEST = int(Kind.REQUEST)

# Below this, an answer's start and its request's end are the same instant to the row
# times: the framer placed both inside one read (or one print stamp) by the line speed.
UNRESOLVED = 1e-6


@dataclass(frozen=True, slots=True)
class Latency:
    """A latency the timing can vouch for: `seconds` exactly (within the source's
    resolution), or, when `bound`, at most `seconds`."""

    seconds: float
    bound: bool = False


def measure(store: FrameStore, i: int) -> Latency | None:
    """The latency of row `i`'s transaction as far as the store's timing can measure it;
    None when it cannot (no timestamps, or stamps that put the answer's bytes on the wire
    before the line speed allows).

    - exact stamps (logic analysers, RTAC records): the difference of the row times;
    - host reads: a difference of zero means both ends fell in one read: the latency is
      below the read's resolution (`<16ms`) if that is known, else unknown;
    - frame or print stamps: a difference of zero means the framer had to squeeze the
      answer's bytes in after the request because its stamp came sooner than the line
      speed allows: unknown.
    Larger differences are shown, good to about the resolution.
    """
    j = store.partner[i]
    stamps = store.stamps
    if j == NO_PARTNER or stamps is Stamp.NONE:
        return None
    # `latency(store, i)`, inline: this runs for every answer a listing shows
    raw = store.t[i] - store.t_end[j] if store.kind[i] != _REQUEST else store.t[j] - store.t_end[i]
    if stamps is Stamp.EXACT:
        return Latency(raw) if raw >= 0 else None
    if raw < UNRESOLVED:
        if stamps is Stamp.READ_END and store.resolution > 0:
            return Latency(store.resolution, bound=True)
        return None
    return Latency(raw)

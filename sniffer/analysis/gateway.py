"""Provides the linking of both sides of a gateway: Modbus TCP transactions to the RTU
transactions that carried them, with a verdict on where each one failed.

Two stores, one per side (a network capture framed by `NetPipeline`, a serial capture
framed by the ordinary pipeline). `offset` is what to add to serial times to put them on
the network capture's clock; `estimate_offset` finds it from transactions whose request
appears once on each side, assuming the gateway takes about as long in as out:
offset = median of ((tcp request end + tcp answer start) - (rtu request start + rtu
answer end)) / 2.

A TCP request is linked to the first serial request after it (within `timeout`, less
`slack` before it for clock error) with the same unit and the same PDU, not linked yet.
Verdicts (`Verdict`): ok, not sent on the serial side, device timed out, answer lost by
the gateway, gateway exception explained by the serial side (0x0A/0x0B), the device's
answer garbled on the serial line (a bad check, or a framing or parity error: the
gateway rightly refused it, with 0x0B or with silence), gateway exception although the
device answered intact, answers that differ.
"""

from __future__ import annotations

import enum
import statistics
from bisect import bisect_left, bisect_right
from dataclasses import dataclass

from dissectors import mbap
from dissectors.envelope import ascii_body
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.framing.tcp import MBAP
from sniffer.vocab import BAD_CHECK, Flag, Kind

GATEWAY_PATH_UNAVAILABLE = 0x0A
GATEWAY_TARGET_FAILED = 0x0B
# an answer that reached the tap damaged: a gateway on the same line got it damaged too
GARBLED = BAD_CHECK | int(Flag.LINE_ERROR)


class Verdict(enum.Enum):
    OK = "ok"
    NOT_SENT = "not-sent"  # the gateway never put the request on the serial line
    DEVICE_TIMEOUT = "device-timeout"  # sent, the device did not answer
    ANSWER_LOST = "answer-lost"  # the device answered, the TCP client got nothing
    GATEWAY_EXCEPTION = "gateway-exception"  # 0x0A/0x0B, and the serial side agrees
    LINE_ERROR = "line-error"  # the device's answer was garbled on the serial line
    GATEWAY_FAULT = "gateway-fault"  # 0x0A/0x0B although the device answered intact
    MISMATCH = "mismatch"  # both answered, with different PDUs


@dataclass(frozen=True, slots=True)
class Side:
    """One transaction on one side: rows, times, bodies (unit + PDU)."""

    request: int
    answer: int  # NO_PARTNER when unanswered
    t_request: float  # start of the request
    t_request_end: float
    t_answer: float | None  # start of the answer
    t_answer_end: float | None
    body: bytes
    answer_body: bytes | None
    answer_intact: bool = True  # the answer passed its check, with no line error


@dataclass(frozen=True, slots=True)
class Link:
    """A TCP transaction and what became of it on the serial side."""

    tcp: Side
    serial: Side | None
    verdict: Verdict
    delay_in: float | None  # serial request start - TCP request end (s)
    delay_out: float | None  # TCP answer start - serial answer end (s)
    text: str


def _body(store: FrameStore, i: int) -> bytes:
    raw = store.raw(i)
    flags = store.flags[i]
    if flags & MBAP:
        return mbap.body(raw)
    if flags & Flag.ASCII:
        decoded = ascii_body(raw)
        return decoded[:-1] if decoded else b""
    return raw[:-2]


def transactions(store: FrameStore) -> list[Side]:
    """Every request of a store with its answer (if paired), in store order."""
    store.sync()
    out = []
    for i in range(len(store)):
        if store.kind[i] != Kind.REQUEST:
            continue
        j = store.partner[i]
        answered = j != NO_PARTNER
        out.append(
            Side(
                i,
                j,
                store.t[i],
                store.t_end[i],
                store.t[j] if answered else None,
                store.t_end[j] if answered else None,
                _body(store, i),
                _body(store, j) if answered else None,
                not answered or not store.flags[j] & GARBLED,
            )
        )
    return out


PAIRS_PER_KEY = 20_000  # votes one transaction key may cast (long runs of one poll)


def _key(side: Side) -> bytes:
    """What makes a transaction recognisable on both sides: its request, and its answer
    when it has one (values change where requests repeat)."""
    return side.body + b"|" + (side.answer_body or b"")


def coarse_offset(tcp: list[Side], serial: list[Side], step: float = 0.05) -> float | None:
    """A first guess of the seconds to add to serial times, for clocks that may be any
    distance apart. Transactions are matched by request and answer (request alone where
    no answer matches anything): every (TCP request end - serial request start) of a
    matching pair votes, and the `step`-wide bin with the most votes, with its two
    neighbours, wins. A poll repeated with the same answer votes for the multiples of its
    period too, but the true offset gets the most votes: every transaction gives one.
    None when nothing matches."""
    for key in (_key, lambda x: x.body):
        by_key: dict[bytes, list[float]] = {}
        for s in serial:
            by_key.setdefault(key(s), []).append(s.t_request)
        tcp_by_key: dict[bytes, list[float]] = {}
        for t in tcp:
            if key(t) in by_key:
                tcp_by_key.setdefault(key(t), []).append(t.t_request_end)
        votes: dict[int, int] = {}
        for k, ends in tcp_by_key.items():
            starts = by_key[k]
            # for long runs, every so many TCP transactions (each with all its matches,
            # so that the true pair is always among them)
            every = max(1, len(ends) * len(starts) // PAIRS_PER_KEY)
            for end in ends[::every]:
                for start in starts:
                    b = round((end - start) / step)
                    votes[b] = votes.get(b, 0) + 1
        if votes:
            best = max(
                votes,
                key=lambda b: (votes.get(b - 1, 0) + votes[b] + votes.get(b + 1, 0), -abs(b)),
            )
            return best * step
    return None


def estimate_offset(
    tcp: list[Side], serial: list[Side], window: float = 5.0, guess: float = 0.0
) -> tuple[float, float, int] | None:
    """(offset, spread, samples): seconds to add to serial times, the median absolute
    deviation of the samples, and how many answered transactions were unique enough on
    both sides to use (within `window` of each other once `guess` is added to the serial
    times). None without any."""
    by_body: dict[bytes, list[Side]] = {}
    for s in serial:
        if s.t_answer_end is not None:
            by_body.setdefault(s.body, []).append(s)
    starts: dict[bytes, list[float]] = {}
    for body, sides in by_body.items():
        sides.sort(key=lambda x: x.t_request)
        starts[body] = [x.t_request + guess for x in sides]
    samples = []
    for t in tcp:
        if t.t_answer is None or t.body not in starts:
            continue
        times = starts[t.body]
        lo = bisect_left(times, t.t_request_end - window)
        hi = bisect_right(times, t.t_request_end + window)
        if hi - lo != 1:
            continue
        s = by_body[t.body][lo]
        assert s.t_answer_end is not None
        samples.append(((t.t_request_end + t.t_answer) - (s.t_request + s.t_answer_end)) / 2)
    if not samples:
        return None
    offset = statistics.median(samples)
    spread = statistics.median(abs(x - offset) for x in samples)
    return offset, spread, len(samples)


def link(
    tcp_store: FrameStore,
    serial_store: FrameStore,
    *,
    offset: float = 0.0,
    timeout: float = 1.0,
    slack: float = 0.05,
) -> list[Link]:
    """Link every TCP transaction to its serial one (module doc)."""
    return link_sides(
        transactions(tcp_store),
        transactions(serial_store),
        offset=offset,
        timeout=timeout,
        slack=slack,
    )


def link_sides(
    tcp: list[Side],
    serial: list[Side],
    *,
    offset: float = 0.0,
    timeout: float = 1.0,
    slack: float = 0.05,
) -> list[Link]:
    """`link` over transactions already taken from their stores.

    Polls repeat: the same request may be on the serial line every few tens of
    milliseconds, so "the first one after" can belong to the next TCP request. Links are
    made in two passes: first every TCP transaction whose answer is the device's answer,
    to the first such serial transaction after it; then the others, to the candidate
    whose gateway delay is nearest the delay the first pass measured (median), the
    nearest pairs first."""
    serial = sorted(serial, key=lambda x: x.t_request)
    starts = [x.t_request + offset for x in serial]

    def candidates(t: Side) -> range:
        lo = bisect_left(starts, t.t_request_end - slack)
        hi = bisect_right(starts, t.t_request_end + timeout)
        return range(lo, hi)

    found: dict[int, int] = {}  # TCP transaction -> serial transaction (list positions)
    used: set[int] = set()
    for n, t in enumerate(tcp):
        if t.answer_body is None:
            continue
        for k in candidates(t):
            s = serial[k]
            if k not in used and s.body == t.body and s.answer_body == t.answer_body:
                found[n] = k
                used.add(k)
                break
    delays = [starts[k] - tcp[n].t_request_end for n, k in found.items()]
    typical = statistics.median(delays) if delays else 0.0
    pairs = [
        (abs(starts[k] - t.t_request_end - typical), n, k)
        for n, t in enumerate(tcp)
        if n not in found
        for k in candidates(t)
        if k not in used and serial[k].body == t.body
    ]
    pairs.sort()
    for _, n, k in pairs:
        if n not in found and k not in used:
            found[n] = k
            used.add(k)
    return [
        _verdict(t, serial[found[n]] if n in found else None, offset) for n, t in enumerate(tcp)
    ]


def _verdict(t: Side, s: Side | None, offset: float) -> Link:
    delay_in = None if s is None else s.t_request + offset - t.t_request_end
    delay_out = None
    if s is not None and s.t_answer_end is not None and t.t_answer is not None:
        delay_out = t.t_answer - (s.t_answer_end + offset)
    code = None
    if t.answer_body is not None and len(t.answer_body) >= 3 and t.answer_body[1] & 0x80:
        code = t.answer_body[2]
    device_answered = s is not None and s.answer_body is not None
    garbled = device_answered and s is not None and not s.answer_intact
    if code in (GATEWAY_PATH_UNAVAILABLE, GATEWAY_TARGET_FAILED):
        name = "0x0A path unavailable" if code == GATEWAY_PATH_UNAVAILABLE else "0x0B target failed"
        if garbled:
            return Link(
                t,
                s,
                Verdict.LINE_ERROR,
                delay_in,
                delay_out,
                f"gateway answered {name}: the device's answer was garbled on the serial "
                "line (its check failed), so the gateway rightly refused it",
            )
        if device_answered:
            return Link(
                t,
                s,
                Verdict.GATEWAY_FAULT,
                delay_in,
                delay_out,
                f"gateway answered {name}, but the device answered on the serial line",
            )
        why = "nothing was sent on the serial line" if s is None else "the device did not answer"
        return Link(
            t, s, Verdict.GATEWAY_EXCEPTION, delay_in, delay_out, f"gateway answered {name}: {why}"
        )
    if s is None:
        return Link(
            t,
            s,
            Verdict.NOT_SENT,
            None,
            None,
            "never sent on the serial line: the gateway dropped or queued it",
        )
    if not device_answered:
        return Link(
            t,
            s,
            Verdict.DEVICE_TIMEOUT,
            delay_in,
            None,
            "sent on the serial line; the device did not answer",
        )
    if t.answer_body is None and garbled:
        return Link(
            t,
            s,
            Verdict.LINE_ERROR,
            delay_in,
            None,
            "the device's answer was garbled on the serial line (its check failed); the "
            "gateway passed nothing on",
        )
    if t.answer_body is None:
        return Link(
            t,
            s,
            Verdict.ANSWER_LOST,
            delay_in,
            None,
            "the device answered; the gateway did not pass the answer on",
        )
    if t.answer_body != s.answer_body:
        return Link(
            t,
            s,
            Verdict.MISMATCH,
            delay_in,
            delay_out,
            "the TCP answer differs from the device's answer",
        )
    return Link(t, s, Verdict.OK, delay_in, delay_out, "")

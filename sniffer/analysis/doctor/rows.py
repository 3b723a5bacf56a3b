"""Provides the rows as the doctor's checks look at them (`Look`: every request with what
became of it, per unit), the thresholds the checks share and the evidence helpers."""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Sequence
from dataclasses import dataclass

from sniffer.analysis.polls import frame_body, poll_identity
from sniffer.framing.pairing import measure
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.model import LineSettings, Stamp
from sniffer.vocab import BAD_CHECK, Flag, Kind, Status

MIN_POLLS = 3  # requests to a unit before its silence is a finding
MIN_MISSES = 3  # timeouts before a unit is intermittent
MIN_SHARE = 0.02  # ... and the share of its polls they must be
SLOW_FACTOR = 3.0  # an answer this many times the unit's median latency is slow ...
SLOW_MARGIN = 0.020  # ... and at least this much (s) above it
SLOW_SHARE = 0.05  # slow answers from this share on are a warning (fewer: info)
MIN_LATENCIES = 10  # latency values a unit needs before its usual latency is known
BIMODAL_SHARE = 0.2  # each of two latency groups of one poll holds at least this share
BIMODAL_RATIO = 3.0  # ... and the slower is this many times the faster
BIMODAL_GAP = 0.005  # ... and this much (s) slower
MIN_EXCEPTIONS = 3  # exceptions a poll earned, with no good answer, before it is a finding
MIN_ERRORS = 3  # check errors and noise rows before they are said to follow a station
STATION_SHARE = 0.6  # ... and the share of them after that one station
MIN_INTERLEAVED = 3  # requests sent while another's answer was still to come
LOAD_OCCUPANCY = 0.9  # the share of time in transactions from which the line is overloaded
LOAD_UTILISATION = 0.8  # ... or the share of time bytes are on the wire
MIN_SPAN = 1.0  # seconds of traffic before the load is judged
MIN_TRANSACTIONS = 20
MIN_BYTES = 64  # bytes read before their settings are judged
CLEAN_SHARE = 0.2  # wrong settings: fewer of the bytes than this in check-valid frames
MIN_TIMING = 3  # timing violations before a warning (fewer: info)
EXCERPT = 4  # frames quoted per finding
ROWS = 10  # rows listed per finding
HEX_BYTES = 24  # bytes of a frame quoted

NOISE, EVENT, REQUEST = int(Kind.NOISE), int(Kind.EVENT), int(Kind.REQUEST)
ANSWERS = (int(Kind.RESPONSE), int(Kind.EXCEPTION))
ANSWERED = (int(Status.OK), int(Status.EXCEPTION), int(Status.BAD_ANSWER))
WRITE_REGISTERS = (6, 16)
READ_REGISTERS = {3: "holding", 4: "input"}


@dataclass(slots=True)
class Tx:
    """One request and what became of it."""

    row: int
    unit: int
    fc: int
    status: int
    answer: int
    key: object
    what: str
    latency: float | None  # a value the stamps vouch for, else None


@dataclass(slots=True)
class Look:
    """The rows, as the checks look at them."""

    store: FrameStore
    line: LineSettings
    timeout: float
    origin: float
    n: int  # the rows looked at
    txs: list[Tx]
    by_unit: dict[int, list[Tx]]
    answers_of: Counter[int]  # check-valid answers seen per unit (paired or not)
    frames: list[int]  # rows that are frames (not noise, not events)
    network: bool

    def when(self, i: int) -> float:
        return self.store.t[i] - self.origin


def timing_notes(store: FrameStore) -> tuple[str, ...]:
    if store.stamps is Stamp.NONE:
        return ("no timestamps: latencies, line load and timing were not judged",)
    if store.stamps is Stamp.PRINT or not store.resolution < 0.1:
        return ("coarse times: latencies are bounds, so answer times were not judged",)
    if store.stamps is not Stamp.EXACT:
        return ("times are not exact per character: silences (t1.5, t3.5) were not judged",)
    return ()


def look_at(store: FrameStore, line: LineSettings, timeout: float, n: int) -> Look:
    kind, status, partner, flags = store.kind, store.status, store.partner, store.flags
    txs: list[Tx] = []
    by_unit: dict[int, list[Tx]] = defaultdict(list)
    answers_of: Counter[int] = Counter()
    frames: list[int] = []
    network = False
    keys: dict[bytes, tuple[object, str]] = {}
    for i in range(n):
        k = kind[i]
        if k in (NOISE, EVENT):
            continue
        frames.append(i)
        f = flags[i]
        network = network or bool(f & Flag.MBAP)
        if f & BAD_CHECK:
            continue
        if k in ANSWERS:
            answers_of[store.unit[i]] += 1
            continue
        if k != REQUEST or status[i] == Status.BROADCAST:
            continue
        body = frame_body(store.raw(i), f)
        ident = keys.get(body)
        if ident is None:
            ident = keys[body] = poll_identity(body)
        j = partner[i]
        lat = measure(store, i) if j != NO_PARTNER else None
        value = None if lat is None or lat.bound else lat.seconds
        tx = Tx(i, store.unit[i], store.fc[i], status[i], j, ident[0], ident[1], value)
        txs.append(tx)
        by_unit[tx.unit].append(tx)
    # the earliest row's time (a source's event may be stamped after the bytes before it)
    origin = min(store.t[:n]) if n else 0.0
    return Look(store, line, timeout, origin, n, txs, by_unit, answers_of, frames, network)


# -- helpers for evidence -------------------------------------------------------------


def hex_text(raw: bytes) -> str:
    text = raw[:HEX_BYTES].hex(" ")
    return text + (" …" if len(raw) > HEX_BYTES else "")


def excerpt(look: Look, rows: Sequence[int]) -> tuple[str, ...]:
    s = look.store
    out = []
    for i in rows[:EXCERPT]:
        what = ("noise", "request", "response", "exception", "unknown", "event")[s.kind[i]]
        if s.kind[i] != NOISE and s.flags[i] & BAD_CHECK:
            what += " (check error)"
        out.append(f"row {i} at {look.when(i):.3f} s: {what}: {hex_text(s.raw(i))}")
    return tuple(out)


def first_rows(rows: Sequence[int]) -> tuple[int, ...]:
    return tuple(rows[:ROWS])


def ms(seconds: float) -> float:
    return round(seconds * 1000, 3)


def share(part: int, whole: int) -> str:
    return f"{100 * part / whole:.0f} %" if whole else "0 %"

"""Provides the bus doctor: a capture's rows turned into ranked findings (what is wrong with
this bus, for whom, the evidence and what to check next).

Each finding has a stable `kind` (part of the interface: JSON, MQTT, the TUI pane), a
severity (`error`, `warning`, `info`), the units it concerns, a one-line summary, what it
means on site, its evidence (counts, times, rows and a short excerpt of the frames) and
advice. `diagnose` reads only the store's columns and bytes; it never imports `meaning`.
What a dictionary documents (a response time) comes in as plain numbers.

Every time a finding states is backed by the row times as far as they vouch for it:
latencies only where `pairing.measure` gives a value (bounds are never taken for
values), timing violations only where the stamps are exact, line load only where the
stamps are times at all. docs/doctor.md says how each finding is detected and its limits.
"""

from __future__ import annotations

import itertools
from bisect import bisect_left
from collections import Counter, defaultdict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from statistics import median

from dissectors.dictionary.model import Timing
from dissectors.pdu.exceptions import exception_name
from sniffer.analysis.linescore import Sample, score
from sniffer.analysis.polls import frame_body, poll_identity
from sniffer.framing.pairing import measure
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.model import Chunk, LineSettings, Stamp
from sniffer.text import json_line, plain
from sniffer.vocab import BAD_CHECK, ERROR, INFO, WARNING, Flag, Kind, Status

# the kinds, in the order a finding of one severity is fixed first: a cause that makes
# other findings meaningless (settings, a second master, a shared address) before its
# symptoms
KINDS = (
    "wrong-line-settings",
    "two-masters",
    "address-conflict",
    "line-overload",
    "errors-follow-station",
    "silent-unit",
    "timing-violation",
    "intermittent-unit",
    "slow-answers",
    "exception-poll",
    "write-effect",
)
_RANK = {severity: n for n, severity in enumerate((ERROR, WARNING, INFO))}

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

_NOISE, _EVENT, _REQUEST = int(Kind.NOISE), int(Kind.EVENT), int(Kind.REQUEST)
_ANSWERS = (int(Kind.RESPONSE), int(Kind.EXCEPTION))
_ANSWERED = (int(Status.OK), int(Status.EXCEPTION), int(Status.BAD_ANSWER))
_WRITE_REGISTERS = (6, 16)
_READ_REGISTERS = {3: "holding", 4: "input"}


@dataclass(frozen=True, slots=True)
class Finding:
    """One diagnosis: what, for whom, how bad, the evidence and what to check next."""

    kind: str
    severity: str
    units: tuple[int, ...]
    summary: str
    meaning: str
    advice: str
    evidence: dict[str, object] = field(default_factory=dict)
    rows: tuple[int, ...] = ()
    excerpt: tuple[str, ...] = ()

    def record(self) -> dict[str, object]:
        """The finding as `--format json` and MQTT give it."""
        out: dict[str, object] = {"kind": self.kind, "severity": self.severity}
        if len(self.units) == 1:
            out["unit"] = self.units[0]
        elif self.units:
            out["units"] = list(self.units)
        evidence = dict(self.evidence)
        evidence["rows"] = list(self.rows)
        evidence["excerpt"] = list(self.excerpt)
        out.update(summary=self.summary, meaning=self.meaning, evidence=evidence)
        out["advice"] = self.advice
        return out


@dataclass(frozen=True, slots=True)
class Diagnosis:
    """What `diagnose` found, ranked, and what the timing allowed it to look at."""

    findings: tuple[Finding, ...]
    notes: tuple[str, ...] = ()

    @property
    def status(self) -> int:
        """The exit status: 1 when any finding is a warning or an error, else 0."""
        return 1 if any(f.severity != INFO for f in self.findings) else 0

    def counts(self) -> Counter[str]:
        return Counter(f.severity for f in self.findings)


@dataclass(slots=True)
class _Tx:
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
class _Look:
    """The rows, as the checks look at them."""

    store: FrameStore
    line: LineSettings
    timeout: float
    origin: float
    n: int  # the rows looked at
    txs: list[_Tx]
    by_unit: dict[int, list[_Tx]]
    answers_of: Counter[int]  # check-valid answers seen per unit (paired or not)
    frames: list[int]  # rows that are frames (not noise, not events)
    network: bool

    def when(self, i: int) -> float:
        return self.store.t[i] - self.origin


def diagnose(
    store: FrameStore,
    line: LineSettings,
    timeout: float,
    response_bounds: Mapping[int, float] | None = None,
    rows: int | None = None,
) -> Diagnosis:
    """The findings on a paired store, ranked: what to fix first comes first.
    `response_bounds`: unit -> the response time (s) its dictionary documents.
    `rows`: look at the first `rows` rows only, and leave the store as it is (a store
    another thread fills: the TUI's health pane); by default every row."""
    if rows is None:
        store.sync()
        rows = len(store)
    # (a store being filled: only the rows every column already holds)
    n = min(rows, len(store.t), len(store.flags), len(store.status), len(store.partner))
    look = _look(store, line, timeout, n)
    notes = _notes(store)
    settings = wrong_settings(look)
    if settings is not None:  # every other finding would be read from misframed bytes
        return Diagnosis((settings,), notes)
    found: list[Finding] = []
    masters = two_masters(look)
    cut = set(masters[1]) if masters else set()  # the first master's requests cut short
    if masters:
        found.append(masters[0])
    conflicts = address_conflicts(look)
    found += conflicts
    conflicted = {u for f in conflicts for u in f.units}
    silent = silent_units(look)
    found += silent
    quiet = {u for f in silent for u in f.units}
    found += intermittent_units(look, quiet | conflicted, cut)
    found += errors_follow_station(look, conflicted)
    found += slow_answers(look, response_bounds or {}, conflicted)
    found += exception_polls(look)
    found += line_overload(look)
    found += timing_violations(look, set(masters[2]) if masters else set())
    found += write_effects(look)
    ranked = sorted(found, key=lambda f: (_RANK[f.severity], KINDS.index(f.kind), f.units))
    return Diagnosis(tuple(ranked), notes)


def response_bounds(timings: Mapping[int, Timing | None]) -> dict[int, float]:
    """unit -> the response time (s) its dictionary documents, where it documents one."""
    return {
        unit: t.response_ms / 1000
        for unit, t in timings.items()
        if t is not None and t.response_ms is not None
    }


def _notes(store: FrameStore) -> tuple[str, ...]:
    if store.stamps is Stamp.NONE:
        return ("no timestamps: latencies, line load and timing were not judged",)
    if store.stamps is Stamp.PRINT or not store.resolution < 0.1:
        return ("coarse times: latencies are bounds, so answer times were not judged",)
    if store.stamps is not Stamp.EXACT:
        return ("times are not exact per character: silences (t1.5, t3.5) were not judged",)
    return ()


def _look(store: FrameStore, line: LineSettings, timeout: float, n: int) -> _Look:
    kind, status, partner, flags = store.kind, store.status, store.partner, store.flags
    txs: list[_Tx] = []
    by_unit: dict[int, list[_Tx]] = defaultdict(list)
    answers_of: Counter[int] = Counter()
    frames: list[int] = []
    network = False
    keys: dict[bytes, tuple[object, str]] = {}
    for i in range(n):
        k = kind[i]
        if k in (_NOISE, _EVENT):
            continue
        frames.append(i)
        f = flags[i]
        network = network or bool(f & Flag.MBAP)
        if f & BAD_CHECK:
            continue
        if k in _ANSWERS:
            answers_of[store.unit[i]] += 1
            continue
        if k != _REQUEST or status[i] == Status.BROADCAST:
            continue
        body = frame_body(store.raw(i), f)
        ident = keys.get(body)
        if ident is None:
            ident = keys[body] = poll_identity(body)
        j = partner[i]
        lat = measure(store, i) if j != NO_PARTNER else None
        value = None if lat is None or lat.bound else lat.seconds
        tx = _Tx(i, store.unit[i], store.fc[i], status[i], j, ident[0], ident[1], value)
        txs.append(tx)
        by_unit[tx.unit].append(tx)
    origin = store.t[0] if n else 0.0
    return _Look(store, line, timeout, origin, n, txs, by_unit, answers_of, frames, network)


# -- helpers for evidence -------------------------------------------------------------


def _hex(raw: bytes) -> str:
    text = raw[:HEX_BYTES].hex(" ")
    return text + (" …" if len(raw) > HEX_BYTES else "")


def _excerpt(look: _Look, rows: Sequence[int]) -> tuple[str, ...]:
    s = look.store
    out = []
    for i in rows[:EXCERPT]:
        what = ("noise", "request", "response", "exception", "unknown", "event")[s.kind[i]]
        if s.kind[i] != _NOISE and s.flags[i] & BAD_CHECK:
            what += " (check error)"
        out.append(f"row {i} at {look.when(i):.3f} s: {what}: {_hex(s.raw(i))}")
    return tuple(out)


def _rows(rows: Sequence[int]) -> tuple[int, ...]:
    return tuple(rows[:ROWS])


def _ms(seconds: float) -> float:
    return round(seconds * 1000, 3)


def _share(part: int, whole: int) -> str:
    return f"{100 * part / whole:.0f} %" if whole else "0 %"


# -- the checks -----------------------------------------------------------------------


def wrong_settings(look: _Look) -> Finding | None:
    """Many bytes and almost no check-valid frame: the line settings do not fit."""
    s = look.store
    total = valid = noise = 0
    noise_rows: list[int] = []
    for i in range(look.n):
        k = s.kind[i]
        if k == _EVENT:
            continue
        total += s.length[i]
        if k == _NOISE:
            noise += s.length[i]
            noise_rows.append(i)
        elif not s.flags[i] & BAD_CHECK:
            valid += s.length[i]
    if total < MIN_BYTES or valid >= CLEAN_SHARE * total or look.network:
        return None
    guess, why = _settings_guess(look)
    advice = (
        f"read the capture again with {guess}; on the line itself, `modscope scan PORT` "
        "listens at each setting and scores it"
        if guess
        else "the bytes cannot say which setting fits (bytes read at the wrong baud rate "
        "or parity are already wrong): on the line, `modscope scan PORT` finds it; "
        "otherwise compare --baud/--parity/--stopbits with the master's configuration"
    )
    return Finding(
        "wrong-line-settings",
        ERROR,
        (),
        f"{total:,} bytes and only {_share(valid, total)} of them in check-valid frames "
        f"at {look.line.describe()}, mode {look.line.mode}",
        "the analyser is not reading this line with the settings it runs at: every "
        "frame shown is noise, so nothing else about the bus can be judged",
        advice,
        {
            "bytes": total,
            "valid_frame_bytes": valid,
            "noise_bytes": noise,
            "settings": f"{look.line.describe()} {look.line.mode}",
            "guess": guess or None,
            "guess_basis": why or None,
        },
        _rows(noise_rows),
        _excerpt(look, noise_rows),
    )


def _settings_guess(look: _Look) -> tuple[str, str]:
    """A setting the bytes themselves fit, where re-framing them can tell: the framing
    mode, and 7-bit characters read as 8 (the parity bit left in bit 7). A wrong baud
    rate or parity garbles bytes in the UART, so no re-framing can name those."""
    s = look.store
    line = look.line
    chunks: list[Chunk] = []
    for channel, data in s.streams.items():
        if data:
            chunks.append(Chunk(bytes(data[:8192]), 0.0, 1.0, channel=channel))
    if not chunks:
        return "", ""
    sample = Sample(tuple(chunks), 1.0)
    here = score(line, sample)
    tries: list[tuple[str, LineSettings, Sample]] = []
    other = "ascii" if line.mode != "ascii" else "rtu"
    tries.append((f"--mode {other}", _with(line, mode=other), sample))
    masked = Sample(
        tuple(Chunk(bytes(b & 0x7F for b in c.data), 0.0, 1.0, channel=c.channel) for c in chunks),
        1.0,
    )
    raw = b"".join(c.data for c in chunks)
    even = sum(1 for b in raw if (b >> 7) == (b & 0x7F).bit_count() & 1)
    # the parity bit, if that is what bit 7 holds, says which parity the line runs
    for parity in ("E",) if even * 2 >= len(raw) else ("O",):
        tries.append(
            (
                f"--bytesize 7 --parity {parity} --mode ascii",
                _with(line, bytesize=7, parity=parity, mode="ascii"),
                masked,
            )
        )
    best: tuple[str, int] = ("", here.frames)
    for words, setting, sam in tries:
        try:
            trial = score(setting, sam)
        except ValueError:
            continue
        if trial.valid and trial.frames > best[1] and trial.clean >= 0.5:
            best = (words, trial.frames)
    if not best[0]:
        return "", ""
    return best[0], (
        f"framed again with {best[0]}, the first {min(8192, s.bytes_total):,} bytes give "
        f"{best[1]} check-valid frames (here {here.frames})"
    )


def _with(line: LineSettings, **changes: object) -> LineSettings:
    values: dict[str, object] = {
        "baud": line.baud,
        "bytesize": line.bytesize,
        "parity": line.parity,
        "stopbits": line.stopbits,
        "mode": line.mode,
    }
    values.update(changes)
    return LineSettings(**values)  # type: ignore[arg-type]


def silent_units(look: _Look) -> list[Finding]:
    """A polled unit that never answered (not one check-valid answer from it)."""
    out = []
    for unit, txs in sorted(look.by_unit.items()):
        timeouts = [t.row for t in txs if t.status == Status.TIMEOUT]
        if len(txs) < MIN_POLLS or look.answers_of[unit] or not timeouts:
            continue
        polls = sorted({t.what for t in txs})
        out.append(
            Finding(
                "silent-unit",
                ERROR,
                (unit,),
                f"unit {unit} never answered: {len(txs)} requests, {len(timeouts)} timed out",
                "the master polls an address where no device answers: the device is off, "
                "unwired, set to another address or other line settings, or not there",
                f"check that a device is set to address {unit}, powered and wired to this "
                "line (A/B not swapped), and that its baud rate and parity match the "
                "master's; if it was removed, take it out of the master's poll list",
                {
                    "requests": len(txs),
                    "timeouts": len(timeouts),
                    "first_s": round(look.when(txs[0].row), 3),
                    "last_s": round(look.when(txs[-1].row), 3),
                    "polls": polls[:5],
                },
                _rows(timeouts),
                _excerpt(look, timeouts),
            )
        )
    return out


def intermittent_units(look: _Look, skip: set[int], cut: set[int]) -> list[Finding]:
    """A unit that answers most polls and misses a share of them; says when the misses
    cluster. Timeouts another master's request explains (`cut`) are not misses."""
    out = []
    for unit, txs in sorted(look.by_unit.items()):
        if unit in skip:
            continue
        counted = [t for t in txs if t.row not in cut and t.status != Status.OPEN]
        missed = [n for n, t in enumerate(counted) if t.status == Status.TIMEOUT]
        if len(missed) < MIN_MISSES or len(missed) < MIN_SHARE * len(counted):
            continue
        rows = [counted[n].row for n in missed]
        run, start = _longest_run(missed)
        when = _clustering(look, counted, missed, run, start)
        out.append(
            Finding(
                "intermittent-unit",
                WARNING,
                (unit,),
                f"unit {unit} missed {len(missed)} of {len(counted)} polls "
                f"({_share(len(missed), len(counted))}); {when}",
                "the device is there but does not always answer: a marginal signal "
                "(termination, bias, cable length), a device too busy to answer in time, "
                "or a master timeout shorter than the device needs",
                "look at the signal at this device (termination at both ends only, bias, "
                "shield and ground); compare the master's response timeout with the "
                "device's documented response time; if misses cluster, look for what "
                "happens on site at those times (drives starting, welding, load changes)",
                {
                    "polls": len(counted),
                    "missed": len(missed),
                    "share": round(len(missed) / len(counted), 4),
                    "longest_run": run,
                    "longest_run_from_s": round(look.when(counted[start].row), 3),
                    "misses_s": [round(look.when(r), 3) for r in rows[:ROWS]],
                },
                _rows(rows),
                _excerpt(look, rows),
            )
        )
    return out


def _longest_run(missed: Sequence[int]) -> tuple[int, int]:
    """The longest run of consecutive misses among a unit's polls: (length, first poll)."""
    best, best_start, run, start, last = 0, 0, 0, 0, -2
    for n in missed:
        if n == last + 1:
            run += 1
        else:
            run, start = 1, n
        if run > best:
            best, best_start = run, start
        last = n
    return best, best_start


def _clustering(look: _Look, txs: Sequence[_Tx], missed: Sequence[int], run: int, at: int) -> str:
    if run >= 3:
        return (
            f"they cluster: {run} in a row from {look.when(txs[at].row):.3f} s "
            f"to {look.when(txs[at + run - 1].row):.3f} s"
        )
    half = len(txs) // 2
    early = sum(1 for n in missed if n < half)
    late = len(missed) - early
    if min(early, late) * 4 < max(early, late):
        which = "first" if early > late else "second"
        return f"most ({max(early, late)}) fall in the {which} half of the capture"
    return "spread over the whole capture, never more than two in a row"


def _second_answers(look: _Look) -> dict[int, list[int]]:
    """Per unit: check-valid orphan answers from it that come after its paired answer
    and before the next request (a second answer to one request), in one pass."""
    out: dict[int, list[int]] = defaultdict(list)
    s = look.store
    answered = -1  # the unit whose paired answer came last, until the next request
    for i in look.frames:
        k = s.kind[i]
        if k == _REQUEST:
            answered = -1
        elif k in _ANSWERS and not s.flags[i] & BAD_CHECK:
            if s.partner[i] != NO_PARTNER:
                answered = s.unit[i]
            elif s.status[i] == Status.ORPHAN and s.unit[i] == answered:
                out[answered].append(i)
    return out


def two_masters(look: _Look) -> tuple[Finding, list[int], list[int]] | None:
    """Requests sent while another request's answer was still to come: the answer to
    the earlier request arrives after the later request (an orphan that fits it). One
    master waits for each answer or its timeout; a second master does not know about
    the first one's transaction. Returns the finding, the requests so cut and the
    requests that cut them."""
    if look.network:
        return None
    s = look.store
    frames = look.frames
    cut: list[int] = []
    seconds: list[int] = []
    for n, i in enumerate(frames):
        if s.kind[i] != _REQUEST or s.status[i] != Status.TIMEOUT:
            continue
        # the next frames: another request, then (before any other request) an orphan
        # answer from the first request's unit and function
        j = frames[n + 1] if n + 1 < len(frames) else -1
        if j < 0 or s.kind[j] != _REQUEST or s.t[j] - s.t_end[i] > look.timeout:
            continue
        for m in frames[n + 2 : n + 5]:
            if s.kind[m] == _REQUEST:
                break
            if (
                s.kind[m] in _ANSWERS
                and s.status[m] == Status.ORPHAN
                and s.unit[m] == s.unit[i]
                and s.fc[m] & 0x7F == s.fc[i]
            ):
                cut.append(i)
                seconds.append(j)
                break
    if len(cut) < MIN_INTERLEAVED or len(cut) < MIN_SHARE * max(len(look.txs), 1):
        return None
    units = tuple(sorted({s.unit[i] for i in cut} | {s.unit[j] for j in seconds}))
    rows = sorted(set(cut) | set(seconds))
    first = cut[0]
    return (
        Finding(
            "two-masters",
            ERROR,
            units,
            f"{len(cut)} requests were followed by another request before their answer "
            f"came (first at {look.when(first):.3f} s): two masters take turns unaware "
            "of each other",
            "two masters poll this line (a SCADA and a service laptop, an HMI, a second "
            "gateway): their transactions overlap, so answers collide or reach the wrong "
            "master and both see timeouts and garbage",
            "find the second master (a laptop left connected, an HMI or gateway "
            "configured as master) and make it a slave or remove it; one RS-485 line "
            "has one master",
            {
                "interleaved": len(cut),
                "requests": len(look.txs),
                "units": list(units),
                "first_s": round(look.when(first), 3),
            },
            _rows(rows),
            _excerpt(look, rows[:EXCERPT]),
        ),
        cut,
        seconds,
    )


def _latency_groups(values: Sequence[float], resolution: float) -> tuple[float, float, int] | None:
    """Two clusters of latencies (fast median, slow median, slow count), or None."""
    if len(values) < MIN_LATENCIES:
        return None
    ordered = sorted(values)
    n = len(ordered)
    lo = max(1, int(BIMODAL_SHARE * n))
    best: tuple[float, int] | None = None
    for k in range(lo, n - lo + 1):
        a, b = ordered[k - 1], ordered[k]
        ratio = b / a if a > 0 else float("inf")
        apart = ratio >= BIMODAL_RATIO and b - a >= max(BIMODAL_GAP, 4 * resolution)
        if apart and (best is None or ratio > best[0]):
            best = (ratio, k)
    if best is None:
        return None
    k = best[1]
    return median(ordered[:k]), median(ordered[k:]), n - k


def address_conflicts(look: _Look) -> list[Finding]:
    """Two devices on one address: two answers to one request, or one poll's answer
    times falling into two groups; collisions in its answer slots are given as evidence."""
    if look.network:
        return []
    s = look.store
    seconds = _second_answers(look)
    slots = _answer_slot_errors(look)
    out = []
    for unit, txs in sorted(look.by_unit.items()):
        doubles = seconds.get(unit, [])
        groups: list[tuple[str, float, float, int, int]] = []
        by_key: dict[object, list[_Tx]] = defaultdict(list)
        for tx in txs:
            if tx.latency is not None and tx.status == Status.OK:
                by_key[tx.key].append(tx)
        for timed in by_key.values():
            values = [t.latency for t in timed if t.latency is not None]
            g = _latency_groups(values, s.resolution)
            # a device that is slow now and then gives the same data either way; two
            # devices give their own data, one per group
            if g is not None and _data_splits(look, timed, (g[0] + g[1]) / 2):
                groups.append((timed[0].what, g[0], g[1], g[2], len(values)))
        if len(doubles) < 2 and not groups:
            continue
        said = []
        if doubles:
            said.append(f"{len(doubles)} requests got two answers")
        if groups:
            name, fast, slow, k, m = groups[0]
            said.append(
                f"the answers to {name} come either after about {_ms(fast):g} ms or after "
                f"about {_ms(slow):g} ms ({k} of {m})"
            )
        collided = slots.get(unit, [])
        if collided:
            said.append(f"{len(collided)} answer slots held check errors or noise")
        rows = sorted(set(doubles) | set(collided))
        out.append(
            Finding(
                "address-conflict",
                ERROR,
                (unit,),
                f"two devices seem to answer address {unit}: " + "; ".join(said),
                "two devices are set to one address: both answer, their answers collide "
                "(check errors) or the master takes one device's values for the other's",
                f"list the devices on this line and their addresses; disconnect them one "
                f"at a time and watch which answer to unit {unit} goes away; give one of "
                "them a free address",
                {
                    "requests": len(txs),
                    "double_answers": len(doubles),
                    "collisions": len(collided),
                    "latency_groups": [
                        {
                            "poll": g[0],
                            "fast_ms": _ms(g[1]),
                            "slow_ms": _ms(g[2]),
                            "slow": g[3],
                            "of": g[4],
                        }
                        for g in groups[:3]
                    ],
                },
                _rows(rows),
                _excerpt(look, rows),
            )
        )
    return out


def _data_splits(look: _Look, txs: Sequence[_Tx], cut: float) -> bool:
    """Whether the answers faster than `cut` and those slower carry no data in common."""
    s = look.store
    fast: set[bytes] = set()
    slow: set[bytes] = set()
    for tx in txs:
        data = frame_body(s.raw(tx.answer), s.flags[tx.answer])[2:]
        (fast if (tx.latency or 0.0) < cut else slow).add(data)
    return bool(fast) and bool(slow) and not fast & slow


def _error_rows(look: _Look) -> list[int]:
    s = look.store
    out = []
    for i in range(look.n):
        k = s.kind[i]
        if k == _EVENT:
            continue
        if k == _NOISE or s.flags[i] & BAD_CHECK:
            out.append(i)
    return out


def _answer_slot_errors(look: _Look) -> dict[int, list[int]]:
    """Per unit: check errors and noise between a request to it and the next request."""
    return _errors_after(look)[0]


def _errors_after(look: _Look) -> tuple[dict[int, list[int]], dict[int, list[int]], int]:
    """Check-error and noise rows by what came before them: (after a request to a unit
    and before its answer; after a unit's good answer; all of them)."""
    s = look.store
    in_slot: dict[int, list[int]] = defaultdict(list)
    after_answer: dict[int, list[int]] = defaultdict(list)
    errors = _error_rows(look)
    good = [i for i in look.frames if not s.flags[i] & BAD_CHECK]
    for e in errors:
        k = bisect_left(good, e) - 1
        if k < 0:
            continue
        p = good[k]
        if s.t[e] - s.t_end[p] > look.timeout:
            continue
        if s.kind[p] == _REQUEST:
            in_slot[s.unit[p]].append(e)
        elif s.kind[p] in _ANSWERS:
            after_answer[s.unit[p]].append(e)
    return in_slot, after_answer, len(errors)


def errors_follow_station(look: _Look, skip: set[int]) -> list[Finding]:
    """Check errors and noise concentrated after one station: in the answer slot of its
    requests (its own answers garbled) or right after its answers (its driver holding
    or ringing on the line)."""
    in_slot, after_answer, total = _errors_after(look)
    if total < MIN_ERRORS:
        return []
    out = []
    for unit in sorted(set(in_slot) | set(after_answer)):
        if unit in skip:
            continue
        mine = sorted(in_slot.get(unit, []) + after_answer.get(unit, []))
        if len(mine) < MIN_ERRORS or len(mine) < STATION_SHARE * total:
            continue
        share = _share(len(mine), total)
        out.append(
            Finding(
                "errors-follow-station",
                WARNING,
                (unit,),
                f"{len(mine)} of the {total} check errors and noise spans ({share}) come "
                f"right after unit {unit}'s requests or answers",
                f"the errors follow one station: unit {unit}'s transmitter, its end of "
                "the cable, its termination or its ground is the likely fault, not the "
                "whole line",
                f"at unit {unit}: check the A/B wiring and the shield, whether a "
                "terminator is fitted where it should not be (or missing at the line's "
                "end), the ground reference, and the driver's turn-off (a converter "
                "that holds the line after sending)",
                {
                    "errors": total,
                    "after_station": len(mine),
                    "in_answer_slot": len(in_slot.get(unit, [])),
                    "after_answer": len(after_answer.get(unit, [])),
                },
                _rows(mine),
                _excerpt(look, mine),
            )
        )
    return out


def slow_answers(look: _Look, bounds: Mapping[int, float], skip: set[int]) -> list[Finding]:
    """Answers far slower than the unit's own usual latency, or than its dictionary's
    documented response time. Only latency values count; bounds say nothing here."""
    s = look.store
    out = []
    for unit, txs in sorted(look.by_unit.items()):
        if unit in skip:
            continue
        timed = [t for t in txs if t.latency is not None and t.status in _ANSWERED]
        if len(timed) < MIN_LATENCIES:
            continue
        values = [t.latency for t in timed if t.latency is not None]
        usual = median(values)
        limit = max(SLOW_FACTOR * usual, usual + SLOW_MARGIN, 4 * s.resolution + usual)
        slow = [t for t in timed if t.latency is not None and t.latency > limit]
        bound = bounds.get(unit)
        over = [t for t in timed if bound is not None and (t.latency or 0.0) > bound]
        picked = over if len(over) > len(slow) else slow
        if not picked:
            continue
        share = len(picked) / len(timed)
        severity = WARNING if share >= SLOW_SHARE or len(over) >= MIN_POLLS else INFO
        worst = max(t.latency or 0.0 for t in picked)
        said = (
            f"{len(over)} answers slower than the {_ms(bound):g} ms its dictionary documents"
            if picked is over and bound is not None
            else f"{len(slow)} answers over {_ms(limit):g} ms"
        )
        rows = [r for t in picked for r in (t.row, t.answer)]
        out.append(
            Finding(
                "slow-answers",
                severity,
                (unit,),
                f"unit {unit}: {said} (usual {_ms(usual):g} ms, slowest {_ms(worst):g} ms, "
                f"{_share(len(picked), len(timed))} of {len(timed)} timed answers)",
                "the device takes much longer than usual to answer now and then: it is "
                "busy (a write to EEPROM, a measurement, a gateway behind it), or its "
                "answer is delayed by a retry; near the master's timeout these become "
                "misses",
                "compare the slowest answer with the master's response timeout; look at "
                "what the slow polls have in common (function, size, a write just "
                "before); give the device more time or poll it less often",
                {
                    "timed_answers": len(timed),
                    "slow": len(picked),
                    "usual_ms": _ms(usual),
                    "slowest_ms": _ms(worst),
                    "threshold_ms": _ms(limit),
                    "documented_ms": None if bound is None else _ms(bound),
                },
                _rows([t.row for t in picked]),
                _excerpt(look, rows),
            )
        )
    return out


def exception_polls(look: _Look) -> list[Finding]:
    """A poll that earns an exception every time it is answered."""
    s = look.store
    out = []
    for unit, txs in sorted(look.by_unit.items()):
        by_key: dict[object, list[_Tx]] = defaultdict(list)
        for tx in txs:
            by_key[tx.key].append(tx)
        for _key, group in by_key.items():
            exc = [t for t in group if t.status == Status.EXCEPTION]
            good = [t for t in group if t.status == Status.OK]
            if len(exc) < MIN_EXCEPTIONS or good:
                continue
            codes = Counter(_exception_code(look, t.answer) for t in exc)
            code, _ = codes.most_common(1)[0]
            name = exception_name(code)
            what = group[0].what
            request = _hex(s.raw(group[0].row))
            rows = [r for t in exc[:EXCERPT] for r in (t.row, t.answer)]
            out.append(
                Finding(
                    "exception-poll",
                    WARNING,
                    (unit,),
                    f"unit {unit} answers every {what} with exception {code:02X} "
                    f"({name}): {len(exc)} times",
                    _exception_meaning(code),
                    f"fix the master's poll list: the request {request} ({what}) never "
                    "succeeds; check the register map of the device model actually "
                    "fitted (manuals count from 0 or 1, 30001/40001 offsets)",
                    {
                        "requests": len(group),
                        "exceptions": len(exc),
                        "code": code,
                        "name": name,
                        "poll": what,
                        "request": request,
                        "first_s": round(look.when(exc[0].row), 3),
                    },
                    _rows([t.row for t in exc]),
                    _excerpt(look, rows),
                )
            )
    return out


def _exception_code(look: _Look, i: int) -> int:
    body = frame_body(look.store.raw(i), look.store.flags[i])
    return body[2] if len(body) > 2 else 0


def _exception_meaning(code: int) -> str:
    if code == 2:
        return (
            "the master reads or writes an address the device does not have: a register "
            "map from another model or firmware, or an off-by-one in the addresses"
        )
    if code == 1:
        return "the device does not support this function code"
    if code == 3:
        return "the device refuses the value or quantity the master sends"
    if code in (10, 11):
        return "a gateway cannot reach the device behind it"
    return "the device refuses this request every time"


def line_overload(look: _Look) -> list[Finding]:
    """The line busy most of the time, or the transactions of one poll cycle not fitting
    its period. Needs real times (not synthetic, not print times)."""
    s = look.store
    if look.network or s.stamps in (Stamp.NONE, Stamp.PRINT) or not s.resolution < 0.1:
        return []
    if len(look.txs) < MIN_TRANSACTIONS or not look.frames:
        return []
    first, last = look.frames[0], look.frames[-1]
    span = s.t_end[last] - s.t[first]
    if span < MIN_SPAN:
        return []
    char = look.line.char_time
    wire = sum(s.length[i] for i in look.frames) * char
    utilisation = wire / span
    t35 = look.line.t35
    busy = 0.0
    txs = look.txs
    for n, tx in enumerate(txs):
        start = s.t[tx.row]
        if tx.answer != NO_PARTNER:
            end = s.t_end[tx.answer]
        elif tx.status == Status.TIMEOUT:
            end = s.t_end[tx.row] + look.timeout
        else:
            end = s.t_end[tx.row]
        # a transaction holds the line until its answer (or the timeout) and t3.5 after
        # it, but no longer than the next request (a master that gave up sooner)
        end += t35
        if n + 1 < len(txs):
            end = min(end, s.t[txs[n + 1].row])
        busy += max(0.0, end - start)
    occupancy = busy / span
    periods = _poll_periods(look)
    period = min(periods) if periods else None
    if utilisation < LOAD_UTILISATION and occupancy < LOAD_OCCUPANCY:
        return []
    shortest = None if period is None else period * occupancy
    said = f"the line carries bytes {_share(round(1000 * utilisation), 1000)} of the time"
    said += f" and is in a transaction {_share(round(1000 * min(occupancy, 1.0)), 1000)}"
    return [
        Finding(
            "line-overload",
            WARNING,
            (),
            f"{said} at {look.line.baud} baud: the polls barely fit",
            "the master asks for more than the line can carry at this baud rate: every "
            "poll waits for the ones before it, so values arrive late and a slow answer "
            "pushes the whole cycle",
            "poll less (longer periods for slow values, fewer registers per read), "
            "combine adjacent reads into one, raise the baud rate if every device "
            "supports it, or split the devices over two lines",
            {
                "utilisation": round(utilisation, 3),
                "occupancy": round(occupancy, 3),
                "span_s": round(span, 3),
                "baud": look.line.baud,
                "transactions": len(look.txs),
                "fastest_poll_period_s": None if period is None else round(period, 3),
                "shortest_period_allowed_s": None if shortest is None else round(shortest, 3),
            },
        )
    ]


def _poll_periods(look: _Look) -> list[float]:
    times: dict[object, list[float]] = defaultdict(list)
    s = look.store
    for tx in look.txs:
        times[(tx.unit, tx.key)].append(s.t[tx.row])
    out = []
    for ts in times.values():
        if len(ts) >= 3:
            out.append(median(b - a for a, b in itertools.pairwise(ts)))
    return out


def timing_violations(look: _Look, explained: set[int]) -> list[Finding]:
    """Silences shorter than t3.5 before a frame and longer than t1.5 inside one, where
    the stamps are exact; an answer that starts before t3.5 has passed since its
    request answered before the turnaround the protocol allows. `explained`: requests
    whose short silence a second master explains (said there, not here)."""
    s = look.store
    if s.stamps is not Stamp.EXACT or look.network:
        return []
    by_sender: dict[int, dict[str, list[int]]] = defaultdict(lambda: defaultdict(list))
    shortest: dict[int, float] = {}
    prev = -1
    for i in look.frames:
        f = s.flags[i]
        sender = -1 if s.kind[i] == _REQUEST else s.unit[i]  # -1: the master
        if s.flags[i] & BAD_CHECK:
            prev = i
            continue
        if f & Flag.SHORT_SILENCE and prev >= 0 and i not in explained:
            what = "early answer" if s.kind[i] in _ANSWERS else "short silence"
            by_sender[sender][what].append(i)
            gap = s.t[i] - s.t_end[prev]
            shortest[sender] = min(shortest.get(sender, gap), gap)
        if f & Flag.GAP_INSIDE:
            by_sender[sender]["gap inside"].append(i)
        prev = i
    out = []
    for sender, found in sorted(by_sender.items()):
        rows = sorted(r for rs in found.values() for r in rs)
        who = "the master" if sender < 0 else f"unit {sender}"
        counts = {k: len(v) for k, v in sorted(found.items())}
        said = ", ".join(f"{n} {k}{'s' if n > 1 else ''}" for k, n in counts.items())
        # early answers alone are info: many real slaves answer inside t3.5 and masters
        # take them; silences broken by the master, or gaps inside frames, are warnings
        strict = len(rows) - len(found.get("early answer", []))
        severity = WARNING if strict >= MIN_TIMING else INFO
        least = shortest.get(sender)
        out.append(
            Finding(
                "timing-violation",
                severity,
                () if sender < 0 else (sender,),
                f"{who} breaks the RTU silences: {said} (t3.5 {_ms(look.line.t35):g} ms, "
                f"t1.5 {_ms(look.line.t15):g} ms)",
                f"{who} sends with less silence than RTU requires between frames (or "
                "pauses inside one): strict devices drop such frames, and a master may "
                "glue two frames into one",
                f"check {who}'s inter-frame delay and turnaround settings; a USB or "
                "Ethernet converter that sends in chunks pauses inside frames: use one "
                "with RTU timing, or a lower latency timer",
                {
                    "sender": "master" if sender < 0 else sender,
                    **counts,
                    "shortest_silence_ms": None if least is None else _ms(least),
                    "t35_ms": _ms(look.line.t35),
                    "t15_ms": _ms(look.line.t15),
                },
                _rows(rows),
                _excerpt(look, rows),
            )
        )
    return out


def write_effects(look: _Look) -> list[Finding]:
    """What changed in the polled registers of a unit after each write to it (raw
    register words: the reads before the write against the first read after it)."""
    s = look.store
    out = []
    for unit, txs in sorted(look.by_unit.items()):
        writes = [t for t in txs if t.fc in _WRITE_REGISTERS and t.status == Status.OK]
        if not writes or not any(t.fc in _READ_REGISTERS for t in txs):
            continue
        changes = _changes_after_writes(look, txs)
        said: list[str] = []
        effects: list[dict[str, object]] = []
        for w in writes[:ROWS]:
            changed = changes.get(w.row, [])
            body = frame_body(s.raw(w.row), s.flags[w.row])
            line = f"{w.what} at {look.when(w.row):.3f} s: " + (
                ", ".join(changed[:6]) if changed else "no polled register changed"
            )
            said.append(line)
            effects.append({"write": w.what, "at_s": round(look.when(w.row), 3),
                            "request": _hex(body), "changed": changed[:20]})  # fmt: skip
        rows = [w.row for w in writes]
        out.append(
            Finding(
                "write-effect",
                INFO,
                (unit,),
                f"unit {unit}: {len(writes)} write{'s' if len(writes) > 1 else ''}; "
                + "; ".join(said[:3]),
                "what the device's polled registers did after each write (raw words): "
                "a write that changes nothing may have been refused silently or need a "
                "commit or restart",
                "check that each write had the effect the master intends; if nothing "
                "changed, the register may be read-only in this mode or need a save "
                "command",
                {"writes": effects},
                _rows(rows),
                _excerpt(look, rows),
            )
        )
    return out


def _changes_after_writes(look: _Look, txs: Sequence[_Tx]) -> dict[int, list[str]]:
    """Per write row: `holding 13: 300 -> 700` for each register word that held one
    value over the last two reads of its poll before the write and reads differently in
    the first read after it. One pass over the unit's transactions."""
    last: dict[object, list[_Tx]] = {}  # poll -> its last two good reads
    waiting: dict[object, list[tuple[_Tx, list[_Tx]]]] = defaultdict(list)
    out: dict[int, list[str]] = defaultdict(list)
    for tx in txs:
        if tx.status != Status.OK:
            continue
        if tx.fc in _WRITE_REGISTERS:
            for key, olds in last.items():
                waiting[key].append((tx, olds))
            continue
        if tx.fc not in _READ_REGISTERS:
            continue
        for write, olds in waiting.pop(tx.key, ()):
            out[write.row] += _changed(look, tx, olds)
        last[tx.key] = [*last.get(tx.key, [])[-1:], tx]
    return out


def _changed(look: _Look, new: _Tx, olds: Sequence[_Tx]) -> list[str]:
    key = new.key
    if not isinstance(key, tuple) or len(key) < 2 or not isinstance(key[1], int):
        return []
    start = key[1]
    # a register counts only where it held still over the last two reads before the
    # write: a measurement that drifts anyway says nothing about the write
    held = [_words(look, r.answer) for r in olds]
    table = _READ_REGISTERS[new.fc]
    out = []
    for n, y in enumerate(_words(look, new.answer)):
        seen = {w[n] for w in held if n < len(w)}
        if len(seen) == 1 and y not in seen:
            out.append(f"{table} {start + n}: {seen.pop()} -> {y}")
    return out


def _words(look: _Look, i: int) -> list[int]:
    body = frame_body(look.store.raw(i), look.store.flags[i])
    data = body[3 : 3 + body[2]] if len(body) > 3 else b""
    return [int.from_bytes(data[k : k + 2], "big") for k in range(0, len(data) - 1, 2)]


# -- the findings as text ---------------------------------------------------------------

_TAG = {ERROR: "ERROR", WARNING: "WARNING", INFO: "info"}


def report(diagnosis: Diagnosis, title: str, labels: Mapping[int, str] | None = None) -> str:
    """The findings as text: a head line, then each finding ranked, with its meaning on
    site, its evidence and what to check next."""
    findings = diagnosis.findings
    counts = diagnosis.counts()
    title = plain(title, 400)
    if not findings:
        head = f"{title}: no findings: nothing wrong seen on this bus"
    else:
        parts = [f"{counts[s]} {s}{'s' if counts[s] > 1 else ''}" for s in _TAG if counts[s]]
        many = "s" if len(findings) > 1 else ""
        head = f"{title}: {len(findings)} finding{many} ({', '.join(parts)})"
    lines = [head]
    lines += [f"  note: {plain(n)}" for n in diagnosis.notes]
    for n, f in enumerate(findings, 1):
        lines.append("")
        lines += finding_lines(f, n, labels or {})
    return "\n".join(lines) + "\n"


def finding_lines(f: Finding, n: int, labels: Mapping[int, str]) -> list[str]:
    who = ", ".join(f"{u} ({plain(labels[u], 60)})" if u in labels else str(u) for u in f.units)
    target = f" [unit{'s' if len(f.units) > 1 else ''} {who}]" if f.units else ""
    lines = [f"{n}. {_TAG[f.severity]} {f.kind}{target}: {plain(f.summary, 400)}"]
    lines.append(f"   on site: {plain(f.meaning, 400)}")
    facts = [f"{k}={_fact(v)}" for k, v in f.evidence.items() if v is not None and v != []]
    if facts:
        lines.append(f"   evidence: {plain(', '.join(facts), 800)}")
    if f.rows:
        lines.append(f"   rows: {', '.join(str(r) for r in f.rows)}")
    lines += [f"     {plain(x, 200)}" for x in f.excerpt]
    lines.append(f"   check next: {plain(f.advice, 400)}")
    return lines


def _fact(value: object) -> str:
    if isinstance(value, (list, dict)):
        return json_line(value)
    return str(value)

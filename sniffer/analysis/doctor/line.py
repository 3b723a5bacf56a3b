"""Provides the doctor's checks of the line as a whole: wrong settings, two masters,
address conflicts, errors that follow one station, overload and RTU timing."""

from __future__ import annotations

import itertools
from bisect import bisect_left
from collections import defaultdict
from collections.abc import Sequence
from statistics import median

from sniffer.analysis.doctor.finding import Finding
from sniffer.analysis.doctor.rows import (
    ANSWERS,
    BIMODAL_GAP,
    BIMODAL_RATIO,
    BIMODAL_SHARE,
    CLEAN_SHARE,
    EVENT,
    EXCERPT,
    LOAD_OCCUPANCY,
    LOAD_UTILISATION,
    MIN_BYTES,
    MIN_ERRORS,
    MIN_INTERLEAVED,
    MIN_LATENCIES,
    MIN_SHARE,
    MIN_SPAN,
    MIN_TIMING,
    MIN_TRANSACTIONS,
    NOISE,
    REQUEST,
    STATION_SHARE,
    Look,
    Tx,
    excerpt,
    first_rows,
    ms,
    share,
)
from sniffer.analysis.linescore import Sample, score
from sniffer.analysis.polls import frame_body
from sniffer.framing.pipeline import BYTE_ERRORS
from sniffer.framing.store import NO_PARTNER
from sniffer.model import Chunk, LineSettings, Stamp
from sniffer.vocab import BAD_CHECK, ERROR, INFO, WARNING, Flag, Status


def wrong_settings(look: Look) -> Finding | None:
    """Many bytes and almost no check-valid frame: the line settings do not fit."""
    s = look.store
    total = valid = noise = line_errors = 0
    noise_rows: list[int] = []
    for i in range(look.n):
        k = s.kind[i]
        if k == EVENT:
            # framing and parity errors the source reported (a UART at the wrong speed)
            line_errors += s.notes.get(i, "").startswith(BYTE_ERRORS)
            continue
        line_errors += bool(s.flags[i] & Flag.LINE_ERROR)
        total += s.length[i]
        if k == NOISE:
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
        f"{total:,} bytes and only {share(valid, total)} of them in check-valid frames "
        f"at {look.line.describe()}"
        + (f", and {line_errors:,} framing or parity errors" if line_errors else ""),
        "the analyser is not reading this line with the settings it runs at: every "
        "frame shown is noise, so nothing else about the bus can be judged",
        advice,
        {
            "bytes": total,
            "valid_frame_bytes": valid,
            "noise_bytes": noise,
            "settings": look.line.describe(),
            "line_errors": line_errors,
            "guess": guess or None,
            "guess_basis": why or None,
        },
        first_rows(noise_rows),
        excerpt(look, noise_rows),
    )


def _settings_guess(look: Look) -> tuple[str, str]:
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


def _second_answers(look: Look) -> dict[int, list[int]]:
    """Per unit: check-valid orphan answers from it that come after its paired answer
    and before the next request (a second answer to one request), in one pass."""
    out: dict[int, list[int]] = defaultdict(list)
    s = look.store
    answered = -1  # the unit whose paired answer came last, until the next request
    for i in look.frames:
        k = s.kind[i]
        if k == REQUEST:
            answered = -1
        elif k in ANSWERS and not s.flags[i] & BAD_CHECK:
            if s.partner[i] != NO_PARTNER:
                answered = s.unit[i]
            elif s.status[i] == Status.ORPHAN and s.unit[i] == answered:
                out[answered].append(i)
    return out


def two_masters(look: Look) -> tuple[Finding, list[int], list[int]] | None:
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
        if s.kind[i] != REQUEST or s.status[i] != Status.TIMEOUT:
            continue
        # the next frames: another request, then (before any other request) an orphan
        # answer from the first request's unit and function
        j = frames[n + 1] if n + 1 < len(frames) else -1
        if j < 0 or s.kind[j] != REQUEST or s.t[j] - s.t_end[i] > look.timeout:
            continue
        for m in frames[n + 2 : n + 5]:
            if s.kind[m] == REQUEST:
                break
            if (
                s.kind[m] in ANSWERS
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
            first_rows(rows),
            excerpt(look, rows[:EXCERPT]),
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


def address_conflicts(look: Look) -> list[Finding]:
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
        by_key: dict[object, list[Tx]] = defaultdict(list)
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
                f"the answers to {name} come either after about {ms(fast):g} ms or after "
                f"about {ms(slow):g} ms ({k} of {m})"
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
                            "fast_ms": ms(g[1]),
                            "slow_ms": ms(g[2]),
                            "slow": g[3],
                            "of": g[4],
                        }
                        for g in groups[:3]
                    ],
                },
                first_rows(rows),
                excerpt(look, rows),
            )
        )
    return out


def _data_splits(look: Look, txs: Sequence[Tx], cut: float) -> bool:
    """Whether the answers faster than `cut` and those slower carry no data in common."""
    s = look.store
    fast: set[bytes] = set()
    slow: set[bytes] = set()
    for tx in txs:
        data = frame_body(s.raw(tx.answer), s.flags[tx.answer])[2:]
        (fast if (tx.latency or 0.0) < cut else slow).add(data)
    return bool(fast) and bool(slow) and not fast & slow


def _error_rows(look: Look) -> list[int]:
    s = look.store
    out = []
    for i in range(look.n):
        k = s.kind[i]
        if k == EVENT:
            continue
        if k == NOISE or s.flags[i] & BAD_CHECK:
            out.append(i)
    return out


def _answer_slot_errors(look: Look) -> dict[int, list[int]]:
    """Per unit: check errors and noise between a request to it and the next request."""
    return _errors_after(look)[0]


def _errors_after(look: Look) -> tuple[dict[int, list[int]], dict[int, list[int]], int]:
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
        if s.kind[p] == REQUEST:
            in_slot[s.unit[p]].append(e)
        elif s.kind[p] in ANSWERS:
            after_answer[s.unit[p]].append(e)
    return in_slot, after_answer, len(errors)


def errors_follow_station(look: Look, skip: set[int]) -> list[Finding]:
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
        part = share(len(mine), total)
        out.append(
            Finding(
                "errors-follow-station",
                WARNING,
                (unit,),
                f"{len(mine)} of the {total} check errors and noise spans ({part}) come "
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
                first_rows(mine),
                excerpt(look, mine),
            )
        )
    return out


def line_overload(look: Look) -> list[Finding]:
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
    said = f"the line carries bytes {share(round(1000 * utilisation), 1000)} of the time"
    said += f" and is in a transaction {share(round(1000 * min(occupancy, 1.0)), 1000)}"
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


def _poll_periods(look: Look) -> list[float]:
    times: dict[object, list[float]] = defaultdict(list)
    s = look.store
    for tx in look.txs:
        times[(tx.unit, tx.key)].append(s.t[tx.row])
    out = []
    for ts in times.values():
        if len(ts) >= 3:
            out.append(median(b - a for a, b in itertools.pairwise(ts)))
    return out


def timing_violations(look: Look, explained: set[int]) -> list[Finding]:
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
        sender = -1 if s.kind[i] == REQUEST else s.unit[i]  # -1: the master
        if s.flags[i] & BAD_CHECK:
            prev = i
            continue
        if f & Flag.SHORT_SILENCE and prev >= 0 and i not in explained:
            what = "early answer" if s.kind[i] in ANSWERS else "short silence"
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
                f"{who} breaks the RTU silences: {said} (t3.5 {ms(look.line.t35):g} ms, "
                f"t1.5 {ms(look.line.t15):g} ms)",
                f"{who} sends with less silence than RTU requires between frames (or "
                "pauses inside one): strict devices drop such frames, and a master may "
                "glue two frames into one",
                f"check {who}'s inter-frame delay and turnaround settings; a USB or "
                "Ethernet converter that sends in chunks pauses inside frames: use one "
                "with RTU timing, or a lower latency timer",
                {
                    "sender": "master" if sender < 0 else sender,
                    **counts,
                    "shortest_silence_ms": None if least is None else ms(least),
                    "t35_ms": ms(look.line.t35),
                    "t15_ms": ms(look.line.t15),
                },
                first_rows(rows),
                excerpt(look, rows),
            )
        )
    return out

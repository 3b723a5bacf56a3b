"""Provides the doctor's checks of one unit at a time: silent, intermittent, slow,
polls that always earn an exception, and what writes changed."""

from __future__ import annotations

from collections import Counter, defaultdict
from collections.abc import Mapping, Sequence
from statistics import median

from dissectors.pdu.exceptions import exception_name
from sniffer.analysis.doctor.finding import Finding
from sniffer.analysis.doctor.rows import (
    ANSWERED,
    EXCERPT,
    MIN_EXCEPTIONS,
    MIN_LATENCIES,
    MIN_MISSES,
    MIN_POLLS,
    MIN_SHARE,
    READ_REGISTERS,
    ROWS,
    SLOW_FACTOR,
    SLOW_MARGIN,
    SLOW_SHARE,
    WRITE_REGISTERS,
    Look,
    Tx,
    excerpt,
    first_rows,
    hex_text,
    ms,
    share,
)
from sniffer.analysis.polls import frame_body
from sniffer.vocab import ERROR, INFO, WARNING, Status


def silent_units(look: Look) -> list[Finding]:
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
                first_rows(timeouts),
                excerpt(look, timeouts),
            )
        )
    return out


def intermittent_units(look: Look, skip: set[int], cut: set[int]) -> list[Finding]:
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
                f"({share(len(missed), len(counted))}); {when}",
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
                first_rows(rows),
                excerpt(look, rows),
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


def _clustering(look: Look, txs: Sequence[Tx], missed: Sequence[int], run: int, at: int) -> str:
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


def slow_answers(look: Look, bounds: Mapping[int, float], skip: set[int]) -> list[Finding]:
    """Answers far slower than the unit's own usual latency, or than its dictionary's
    documented response time. Only latency values count; bounds say nothing here."""
    s = look.store
    out = []
    for unit, txs in sorted(look.by_unit.items()):
        if unit in skip:
            continue
        timed = [t for t in txs if t.latency is not None and t.status in ANSWERED]
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
        portion = len(picked) / len(timed)
        severity = WARNING if portion >= SLOW_SHARE or len(over) >= MIN_POLLS else INFO
        worst = max(t.latency or 0.0 for t in picked)
        documented = (
            f"{len(over)} slower than the {ms(bound):g} ms its dictionary documents"
            if over and bound is not None
            else ""
        )
        said = (
            f"{len(slow)} answers over {ms(limit):g} ms" + (f", {documented}" if documented else "")
            if slow
            else f"{len(over)} answers slower than the {ms(bound or 0.0):g} ms its "
            "dictionary documents"
        )
        rows = [r for t in picked for r in (t.row, t.answer)]
        out.append(
            Finding(
                "slow-answers",
                severity,
                (unit,),
                f"unit {unit}: {said} (usual {ms(usual):g} ms, slowest {ms(worst):g} ms, "
                f"{share(len(picked), len(timed))} of {len(timed)} timed answers)",
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
                    "usual_ms": ms(usual),
                    "slowest_ms": ms(worst),
                    "threshold_ms": ms(limit),
                    "documented_ms": None if bound is None else ms(bound),
                },
                first_rows([t.row for t in picked]),
                excerpt(look, rows),
            )
        )
    return out


def exception_polls(look: Look) -> list[Finding]:
    """A poll that earns an exception every time it is answered."""
    s = look.store
    out = []
    for unit, txs in sorted(look.by_unit.items()):
        by_key: dict[object, list[Tx]] = defaultdict(list)
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
            request = hex_text(s.raw(group[0].row))
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
                    first_rows([t.row for t in exc]),
                    excerpt(look, rows),
                )
            )
    return out


def _exception_code(look: Look, i: int) -> int:
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


def write_effects(look: Look) -> list[Finding]:
    """What changed in the polled registers of a unit after each write to it (raw
    register words: the reads before the write against the first read after it)."""
    s = look.store
    out = []
    for unit, txs in sorted(look.by_unit.items()):
        writes = [t for t in txs if t.fc in WRITE_REGISTERS and t.status == Status.OK]
        if not writes or not any(t.fc in READ_REGISTERS for t in txs):
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
                            "request": hex_text(body), "changed": changed[:20]})  # fmt: skip
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
                first_rows(rows),
                excerpt(look, rows),
            )
        )
    return out


def _changes_after_writes(look: Look, txs: Sequence[Tx]) -> dict[int, list[str]]:
    """Per write row: `holding 13: 300 -> 700` for each register word that held one
    value over the last two reads of its poll before the write and reads differently in
    the first read after it. One pass over the unit's transactions."""
    last: dict[object, list[Tx]] = {}  # poll -> its last two good reads
    waiting: dict[object, list[tuple[Tx, list[Tx]]]] = defaultdict(list)
    out: dict[int, list[str]] = defaultdict(list)
    for tx in txs:
        if tx.status != Status.OK:
            continue
        if tx.fc in WRITE_REGISTERS:
            for key, olds in last.items():
                waiting[key].append((tx, olds))
            continue
        if tx.fc not in READ_REGISTERS:
            continue
        for write, olds in waiting.pop(tx.key, ()):
            out[write.row] += _changed(look, tx, olds)
        last[tx.key] = [*last.get(tx.key, [])[-1:], tx]
    return out


def _changed(look: Look, new: Tx, olds: Sequence[Tx]) -> list[str]:
    key = new.key
    if not isinstance(key, tuple) or len(key) < 2 or not isinstance(key[1], int):
        return []
    start = key[1]
    # a register counts only where it held still over the last two reads before the
    # write: a measurement that drifts anyway says nothing about the write
    held = [_words(look, r.answer) for r in olds]
    table = READ_REGISTERS[new.fc]
    out = []
    for n, y in enumerate(_words(look, new.answer)):
        seen = {w[n] for w in held if n < len(w)}
        if len(seen) == 1 and y not in seen:
            out.append(f"{table} {start + n}: {seen.pop()} -> {y}")
    return out


def _words(look: Look, i: int) -> list[int]:
    body = frame_body(look.store.raw(i), look.store.flags[i])
    data = body[3 : 3 + body[2]] if len(body) > 3 else b""
    return [int.from_bytes(data[k : k + 2], "big") for k in range(0, len(data) - 1, 2)]

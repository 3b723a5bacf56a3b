"""The filter language's tree (`and`, `or`, `not`, parentheses) selects what it says.

Random query trees are written out (`query.show`), read back (`parse_query`) and matched
(`select.FilterJob`); the rows must be those a plain row-by-row reading of the tree gives,
on a capture built here from byte literals: a unit bound to a dictionary (register
names), answers, an exception, timeouts, noise and a bad CRC, over twenty seconds. `or`
selects the union of its sides, `not` the complement, terms side by side the
intersection; `not` binds tighter than `and`, `and` tighter than `or`.
"""

from __future__ import annotations

import re
import struct
from collections.abc import Sequence
from datetime import datetime
from functools import cache
from pathlib import Path
from typing import Any

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from dissectors.checks import with_crc
from dissectors.dictionary import load_model
from sniffer.framing.store import NO_PARTNER
from sniffer.meaning.annotate import Binding
from sniffer.meaning.describe import Describer, FrameDetail
from sniffer.meaning.query import (
    KIND_NAMES,
    STATUS_WORDS,
    And,
    Column,
    Node,
    Not,
    Or,
    Query,
    QueryError,
    Register,
    StatusTerm,
    Text,
    Time,
    TimePoint,
    TimeSpan,
    parse_query,
    show,
)
from sniffer.meaning.select import FilterJob, Options, row_matches, row_words
from sniffer.model import Chunk, LineSettings
from sniffer.session.session import Session
from sniffer.vocab import BAD_CHECK, PROBLEM_MASK, Kind
from sniffer.vocab import Status as Outcome

LINE = LineSettings(baud=19200, parity="E", stopbits=1, mode="rtu")
T0 = 1_700_000_000.0
FRAMES = (Kind.REQUEST, Kind.RESPONSE, Kind.EXCEPTION, Kind.UNKNOWN)


def _words(*values: int) -> bytes:
    return b"".join(v.to_bytes(2, "big") for v in values)


def _cycle(k: int) -> list[tuple[float, bytes]]:
    """One poll round of the bus, with what goes wrong in it depending on `k`."""
    out = [
        (0.00, with_crc(struct.pack(">BBHH", 3, 4, 0, 4))),  # unit 3: read input 0-3
        (0.02, with_crc(bytes([3, 4, 8]) + _words(1, 90 + k, 400 + k, 0))),
        (0.10, with_crc(struct.pack(">BBHH", 3, 3, 0x0B, 3))),  # read holding 11-13
        (0.12, with_crc(bytes([3, 3, 6]) + _words(115, 4, 300 + k))),
        (0.20, with_crc(struct.pack(">BBHH", 5, 3, 0, 1))),  # unit 5: read holding 0
    ]
    if k % 3:  # unit 5 answers two rounds in three; else its read times out
        out.append((0.22, with_crc(bytes([5, 3, 2]) + _words(7 * k))))
    if k % 4 == 1:  # unit 3: write Under Voltage Trip, echoed
        write = with_crc(struct.pack(">BBHH", 3, 6, 0x0D, 320))
        out += [(0.60, write), (0.62, write)]
    if k % 4 == 2:  # unit 3: a reserved address: exception 02
        out += [
            (0.60, with_crc(struct.pack(">BBHH", 3, 4, 8, 2))),
            (0.62, with_crc(bytes([3, 0x84, 2]))),
        ]
    if k % 5 == 3:  # unit 1: write two registers, answered
        body = struct.pack(">BBHHB", 1, 16, 100, 2, 4) + _words(1, 2)
        out += [(0.80, with_crc(body)), (0.82, with_crc(struct.pack(">BBHH", 1, 16, 100, 2)))]
    if k % 6 == 4:
        out.append((0.90, b"\xde\xad\xbe"))  # noise
    if k % 7 == 5:  # a request with a wrong CRC
        bad = bytearray(with_crc(struct.pack(">BBHH", 3, 4, 0, 4)))
        bad[-1] ^= 0xFF
        out.append((1.00, bytes(bad)))
    return out


@cache
def capture() -> Session:
    chunks = []
    for k in range(14):
        for dt, raw in _cycle(k):
            t = T0 + 1.5 * k + dt
            chunks.append(Chunk(raw, t_start=t, t_end=t + len(raw) * LINE.char_time))
    bindings = {3: Binding(3, "Pump", load_model("rvs-dn"))}
    session = Session(LINE, bindings=bindings, exact_timing=True, source="tree.pcapng")
    session.ingest(chunks)
    return session


def origin() -> float:
    return capture().store.t[0]


def clock_base() -> int:
    """Whole seconds after local midnight at the capture's start."""
    day = datetime.fromtimestamp(origin()).astimezone()
    midnight = day.replace(hour=0, minute=0, second=0, microsecond=0)
    return int(origin() - midnight.timestamp())


@cache
def describer() -> Describer:
    return Describer(capture().store, capture().annotator)


def options(transactions: bool = False) -> Options:
    return Options(transactions=transactions, bound=capture().annotator.bindings)


def selected(query: Query | Node, transactions: bool = False) -> list[int]:
    """The rows the matcher selects."""
    if not isinstance(query, Query):
        query = Query("", query)
    session = capture()
    store = session.store
    job = FilterJob(store, query, options(transactions), session.annotator, origin())
    while job.advance(len(store), budget=10, final=True):
        pass
    return list(job.rows)


# -- a reading of the tree one row at a time, from the plain columns -------------------------


def _named(i: int, names: frozenset[str]) -> bool:
    s = capture().store
    kind, status, flags = s.kind[i], s.status[i], s.flags[i]
    problem = (
        kind in (Kind.NOISE, Kind.EVENT)
        or status in (Outcome.EXCEPTION, Outcome.TIMEOUT, Outcome.ORPHAN)
        or bool(flags & PROBLEM_MASK)
    )
    hits = {
        "ok": status == Outcome.OK,
        "exception": status == Outcome.EXCEPTION,
        "timeout": status == Outcome.TIMEOUT,
        "orphan": status == Outcome.ORPHAN,
        "broadcast": status == Outcome.BROADCAST,
        "open": status == Outcome.OPEN,
        "check": bool(flags & BAD_CHECK),
        "noise": kind == Kind.NOISE,
        "event": kind == Kind.EVENT,
        "problem": problem,
    }
    return any(hits[n] for n in names)


def _at(p: TimePoint) -> float:
    if not p.clock:
        return origin() + p.seconds
    return origin() - clock_base() + p.seconds


def _details(i: int, transactions: bool) -> list[FrameDetail]:
    s = capture().store
    out = [describer().detail(i)]
    if transactions and s.kind[i] == Kind.REQUEST and s.partner[i] != NO_PARTNER:
        out.append(describer().detail(s.partner[i]))
    return out


def holds(node: Node, i: int, transactions: bool = False) -> bool:
    s = capture().store
    kind = s.kind[i]
    if isinstance(node, Column):
        if node.key == "kind":
            return kind in node.values
        value = s.unit[i] if node.key == "unit" else s.fc[i] & 0x7F
        return kind in FRAMES and value in node.values
    if isinstance(node, StatusTerm):
        return _named(i, node.names)
    if isinstance(node, Time):
        start, end = node.span.start, node.span.end
        return (start is None or s.t[i] >= _at(start)) and (end is None or s.t[i] < _at(end))
    if isinstance(node, Register):
        if s.unit[i] not in capture().annotator.bindings or kind not in _NAMED:
            return False
        names = [r.name.lower() for d in _details(i, transactions) for r in d.registers]
        return any(p in n for p in node.parts for n in names)
    if isinstance(node, Text):
        return node.word in "\n".join(row_words(d) for d in _details(i, transactions))
    if isinstance(node, Not):
        return not holds(node.part, i, transactions)
    if isinstance(node, And):
        return all(holds(p, i, transactions) for p in node.parts)
    return any(holds(p, i, transactions) for p in node.parts)


_NAMED = (Kind.REQUEST, Kind.RESPONSE)


def reference(node: Node, transactions: bool = False) -> list[int]:
    s = capture().store
    rows: Sequence[int] = range(len(s))
    if transactions:  # answers paired with their request are shown on its row
        rows = [
            i
            for i in rows
            if not (s.kind[i] in (Kind.RESPONSE, Kind.EXCEPTION) and s.partner[i] != NO_PARTNER)
        ]
    return [i for i in rows if holds(node, i, transactions)]


# -- random trees ------------------------------------------------------------------------------


def _spans() -> st.SearchStrategy[TimeSpan]:
    seconds = st.integers(0, 84).map(lambda k: k / 4)  # 0 to 21 s in quarter seconds
    clock = st.integers(0, 24).map(lambda k: float(clock_base() + k))

    def span(clock_time: bool, ends: tuple[float | None, float | None]) -> TimeSpan:
        a, b = ends
        if a is not None and b is not None and b < a:
            a, b = b, a
        return TimeSpan(
            None if a is None else TimePoint(a, clock_time),
            None if b is None else TimePoint(b, clock_time),
        )

    relative = st.tuples(st.none() | seconds, st.none() | seconds).map(lambda e: span(False, e))
    on_the_clock = st.tuples(st.none() | clock, st.none() | clock).map(lambda e: span(True, e))
    return (relative | on_the_clock).filter(lambda s: s.start is not None or s.end is not None)


def _sets(values: Sequence[Any], most: int) -> st.SearchStrategy[frozenset[Any]]:
    return st.frozensets(st.sampled_from(values), min_size=1, max_size=most)


ATOMS: st.SearchStrategy[Node] = st.one_of(
    _sets([0, 1, 3, 5, 7], 3).map(lambda v: Column("unit", v)),
    _sets([3, 4, 6, 16, 17], 2).map(lambda v: Column("fc", v)),
    _sets(sorted(KIND_NAMES), 2).map(lambda v: Column("kind", v)),
    _sets(sorted(set(STATUS_WORDS.values())), 2).map(StatusTerm),
    _spans().map(Time),
    st.lists(
        st.sampled_from(["under voltage", "voltage", "trip", "current", "nothing"]),
        min_size=1,
        max_size=2,
    ).map(lambda parts: Register(tuple(parts))),
    st.sampled_from(["read", "exception", "timeout", "holding", "values", "noise", "zzz"]).map(
        Text
    ),
)


def _combined(kids: st.SearchStrategy[Node]) -> st.SearchStrategy[Node]:
    several = st.lists(kids, min_size=2, max_size=3).map(tuple)
    return st.one_of(kids.map(Not), several.map(And), several.map(Or))


TREES = st.recursive(ATOMS, _combined, max_leaves=7)


@settings(max_examples=150, deadline=None)
@given(TREES, st.booleans())
def test_a_tree_written_out_and_read_back_selects_the_same_rows(
    tree: Node, transactions: bool
) -> None:
    assume(clock_base() + 30 < 86400)  # clock times stay on the capture's day
    text = show(tree)
    read = parse_query(text)
    want = reference(tree, transactions)
    assert selected(tree, transactions) == want, text
    assert selected(read, transactions) == want, text


@settings(max_examples=60, deadline=None)
@given(TREES, TREES)
def test_or_selects_the_union_and_side_by_side_the_intersection(a: Node, b: Node) -> None:
    rows_a, rows_b = set(selected(a)), set(selected(b))
    either = parse_query(f"{show(a)} or {show(b)}")
    assert selected(either) == sorted(rows_a | rows_b)
    both = parse_query(f"({show(a)}) ({show(b)})")
    assert selected(both) == sorted(rows_a & rows_b)
    assert selected(parse_query(f"({show(a)}) and ({show(b)})")) == sorted(rows_a & rows_b)


@settings(max_examples=60, deadline=None)
@given(TREES)
def test_not_selects_the_complement(a: Node) -> None:
    every = set(range(len(capture().store)))
    assert selected(parse_query(f"not ({show(a)})")) == sorted(every - set(selected(a)))


def rows(text: str) -> set[int]:
    return set(selected(parse_query(text)))


def test_the_capture_has_what_the_terms_look_for() -> None:
    assert rows("unit:3") and rows("unit:5") and rows("unit:1")
    assert rows("status:timeout") and rows("status:exception") and rows("status:check")
    assert rows("kind:noise") and rows('reg:"under voltage"') and rows("values")


@pytest.mark.parametrize(
    ("text", "want"),
    [
        # not binds tighter than and, and than or; side by side is and
        ("unit:3 or unit:5 fc:3", lambda: rows("unit:3") | (rows("unit:5") & rows("fc:3"))),
        ("unit:5 fc:3 or unit:3", lambda: (rows("unit:5") & rows("fc:3")) | rows("unit:3")),
        ("unit:5 and fc:3 or unit:1", lambda: (rows("unit:5") & rows("fc:3")) | rows("unit:1")),
        ("not unit:3 and fc:3", lambda: rows("fc:3") - rows("unit:3")),
        ("not unit:3 or fc:3", lambda: rows("-unit:3") | rows("fc:3")),
        ("not (unit:3 or fc:3)", lambda: rows("-unit:3") - rows("fc:3")),
        ("(unit:3 or unit:5) fc:3", lambda: (rows("unit:3") | rows("unit:5")) & rows("fc:3")),
        # a key's plain terms side by side are alternatives, as before; `and` means and
        ("unit:3 unit:5 fc:3", lambda: (rows("unit:3") | rows("unit:5")) & rows("fc:3")),
        ("unit:3 and unit:5", lambda: set()),
        ("reg:trip reg:current", lambda: rows("reg:trip") | rows("reg:current")),
        # words and register names under or and not
        ("unit:5 or values", lambda: rows("unit:5") | rows("values")),
        (
            'not reg:"under voltage"',
            lambda: set(range(len(capture().store))) - rows('reg:"under voltage"'),
        ),
        ("t:3-6 or t:15-", lambda: rows("t:3-6") | rows("t:15-")),
        ("t:3-9 and t:6-12", lambda: rows("t:6-9")),
    ],
)
def test_precedence_and_side_by_side(text: str, want: object) -> None:
    assert callable(want)
    assert rows(text) == want()


def test_a_row_decided_by_its_columns_is_not_dissected() -> None:
    store = capture().store
    query = parse_query("unit:3 or pump")

    def dissect(i: int) -> list[FrameDetail]:
        raise AssertionError(f"row {i} was dissected")

    unit_3 = [i for i in range(len(store)) if store.kind[i] in FRAMES and store.unit[i] == 3]
    assert unit_3
    for i in unit_3:
        assert row_matches(store, i, query, options(), dissect, origin())


# -- the manual's filter section says what the parser does ----------------------------------

MANUAL = Path(__file__).resolve().parent.parent.parent / "docs" / "tui.md"


def _section() -> str:
    text = MANUAL.read_text(encoding="utf-8")
    return text[text.index("## The filter language") : text.index("### How fast")]


def test_the_manuals_examples_are_read() -> None:
    section = _section()
    examples = section[section.index("Examples:") : section.index("A query that cannot")]
    found = re.findall(r"`([^`]+)`", examples)
    assert len(found) >= 10
    for text in found:
        assert not parse_query(text).empty, text


def test_what_the_manual_says_is_refused_is_refused() -> None:
    section = _section()
    table = section[section.index("| written | said |") : section.index("and a time span")]
    written = [
        text.replace("\\|", "|")
        for line in table.splitlines()[2:]
        for text in re.findall(r"`([^`]+)`", line.split(" | ")[0])
    ]
    assert len(written) >= 15
    for text in written:
        with pytest.raises(QueryError):
            parse_query(text)


@given(
    key=st.sampled_from(["u", "U", "fc", "FC"]), value=st.integers(0, 300), zeros=st.integers(0, 2)
)
def test_a_word_that_looks_like_a_column_names_the_term_that_selects_it(
    key: str, value: int, zeros: int
) -> None:
    word = f"{key}{'0' * zeros}{value}"
    hints = parse_query(f"status:ok {word}").hints()
    if value > (255 if key.lower() == "u" else 127) or (value == 0 and key.lower() == "fc"):
        assert hints == []  # no such unit or function code: nothing to point to
        return
    (hint,) = hints
    term = hint.rsplit(" ", 1)[1]
    column = "unit" if key.lower() == "u" else "fc"
    assert term == f"{column}:{value}"
    assert getattr(parse_query(term), "units" if column == "unit" else "functions") == {value}
    assert parse_query(f'"{word}x" unit:3 reg:"u1"').hints() == []

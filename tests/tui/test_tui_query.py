"""Malformed filter terms are refused with a message that names the term and says what to
write, the same words in the TUI's filter bar and in the CLI's --filter; well-formed
queries never raise. `or`, parentheses and `==` are read as a reader means them, and what
the grammar does not have (`||`, `unit == 3` with spaces, `unit>3`) is refused by name,
never searched for as text (which matched nothing, silently)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sniffer.cli import main
from sniffer.meaning.query import QueryError, parse_query, show
from sniffer.meaning.select import _FRAMES  # which rows have a unit
from sniffer.tui.app import ModscopeApp
from sniffer.tui.widgets.prompt import LineInput
from tests.support.tui import burst, hostile_session, ready, screen_text, settle

DEMO = Path(__file__).resolve().parent.parent.parent / "sniffer" / "demo" / "demo.pcapng"

# (query, a part of the message that says what is wrong)
MALFORMED = [
    ("t:20-10", "the end comes before the start"),
    ("t:20s-10", "the end comes before the start"),
    ("t:14:05-14:03", "the end comes before the start"),
    ("t:-", "give a start, an end or both"),
    ("t:1-x", "'x' is not a time"),
    ("t:25:00-26:00", "hours go from 0 to 23"),
    ("t:14:61", "minutes and seconds"),
    ("t:14:03-20", "both ends are seconds from the start"),
    ("t:1-2 t:5-", "a second time span next to t:1-2"),
    ('reg:"Under', "the quote is not closed"),
    ('"pump', "the quote is not closed"),
    ('reg:"a"b', "text right after a closing quote"),
    ('ab"c', "a quote inside a term"),
    ('unit:3"', "a quote inside a term"),
    ('reg:""', "empty quotes"),
    ('""', "empty quotes"),
    ("unit:3,", "an empty value between commas"),
    ("unit:,3", "an empty value between commas"),
    ("fc:3,,4", "an empty value between commas"),
    ("kind:req,", "an empty value between commas"),
    ("status:ok,", "an empty value between commas"),
    ("unit:1-", "is not a number"),
    ("unit:5-1", "values go from 0 to 255"),
    ("unit:256", "values go from 0 to 255"),
    ("fc:0", "values go from 1 to 127"),
    ("unit:", "needs a value"),
    ("unti:3", "unknown key 'unti'"),
    ("-", "write the term to leave out"),
    ("-reg:x", "only unit, fc, kind and status terms can be negated"),
    ("kind:frog", "is not known"),
]


@pytest.mark.parametrize(("text", "what"), MALFORMED)
def test_malformed_terms_are_refused_with_what_to_write(text: str, what: str) -> None:
    with pytest.raises(QueryError) as caught:
        parse_query(text)
    message = str(caught.value)
    assert what in message
    # the message starts with the term it is about (or the key of it), so it can be found
    first = text.split()[-1] if "second time span" in what else text
    assert message.startswith((first, first.lstrip("-").split(":")[0] + ":", "'"))


# (query, the part the message starts with, what it says to write)
GRAMMAR = [
    ("unit:3 or", "unit:3 or", "or needs a term after it"),
    ("or unit:3", "or unit:3", "or needs a term before it"),
    ("unit:3 and or fc:3", "and or", "and needs a term after it"),
    ("(unit:3", "(unit:3", "a ( is not closed"),
    ("unit:3 (fc:3 or fc:4", "(fc:3 or fc:4", "a ( is not closed"),
    ("unit:3)", "unit:3)", "a ) with no ( before it"),
    ("()", "()", "empty parentheses"),
    ("(unit:3)fc:3", ")fc:3", "leave a space after it"),
    ("foo(bar)", "foo(bar)", "a ( right after text"),
    ("-(unit:3)", "-(", "write not (...)"),
    ("not", "not", "not needs a term after it"),
    ("unit:3 not", "not", "not needs a term after it"),
    ("unit == 3", "unit == 3", "together: unit==3"),
    ("unit ==3", "unit ==3", "together: unit==3"),
    ("unit== 3", "unit== 3", "together: unit==3"),
    ("unit != 3", "unit != 3", "together: unit!=3"),
    ("unit>3", "unit>3", "write a range: unit:4-255"),
    ("fc<=4", "fc<=4", "write a range: fc:1-4"),
    ("t>10", "t>10", "write a span: t:10-"),
    ("kind<3", "kind<3", "kind:request"),
    ("unit:3 || unit:4", "||", "write or"),
    ("unit:3 | unit:4", "|", "write or"),
    ("unit:3 && fc:3", "&&", "write and"),
    ("!unit:3", "!unit:3", "write not before what to leave out, e.g. not unit:3"),
    ("unit==x", "unit==x", "'x' is not a number"),
    ("unit!=300", "unit!=300", "values go from 0 to 255"),
    ("-pump", "-pump", "write not pump"),
    ("-reg:x", "-reg:x", "write not reg:x"),
    ("pump=on", "pump=on", "unknown key 'pump'"),
]


@pytest.mark.parametrize(("text", "part", "what"), GRAMMAR)
def test_what_the_grammar_does_not_have_is_refused_by_name(text: str, part: str, what: str) -> None:
    with pytest.raises(QueryError) as caught:
        parse_query(text)
    message = str(caught.value)
    assert message.startswith(part + ": "), message
    assert what in message
    assert "\n" not in message


@pytest.mark.parametrize(
    ("text", "same_as"),
    [
        ("unit==3", "unit:3"),
        ("unit=3", "unit:3"),
        ("(unit:3)", "unit:3"),
        ("((unit:3))", "unit:3"),
        ("unit!=3", "-unit:3"),
        ("not unit:3", "-unit:3"),
        ("NOT unit:3", "-unit:3"),
        ("not not unit:3", "unit:3"),
        ("unit:3 and fc:4", "unit:3 fc:4"),
        ("status==timeout kind!=noise", "status:timeout -kind:noise"),
    ],
)
def test_other_spellings_read_as_the_term(text: str, same_as: str) -> None:
    assert show(parse_query(text).tree) == show(parse_query(same_as).tree)


@pytest.mark.parametrize(
    "text",
    [
        'unit:1,2 fc:0x10 kind:req,resp status:ok,timeout reg:"Under Voltage" t:10-20',
        "t:10-",
        "t:-20",
        "t:500ms-2m",
        "t:14:03-14:05:30",
        "t:10-10",
        "exception -unit:4 -fc:3,4",
        "word: 'quoted'",
        '"two words" pump',
    ],
)
def test_well_formed_queries_parse(text: str) -> None:
    query = parse_query(text)
    assert not query.empty
    if query.time is not None and query.time.start and query.time.end:
        assert query.time.end.seconds >= query.time.start.seconds


@given(st.text(alphabet='unitfcksagr:"-, 0123456789.xmh()=!<>|&', max_size=30))
def test_any_text_parses_or_says_why(text: str) -> None:
    try:
        query = parse_query(text)
    except QueryError as exc:
        message = str(exc)
        assert message and "\n" not in message  # one line, never an empty one
        return
    span = query.time
    if span is not None and span.start is not None and span.end is not None:
        assert span.end.seconds >= span.start.seconds


@given(st.floats(0, 1e5), st.floats(0, 1e5))
def test_a_time_span_is_refused_exactly_when_it_runs_backwards(a: float, b: float) -> None:
    text = f"t:{a:.3f}-{b:.3f}"
    lo, hi = float(f"{a:.3f}"), float(f"{b:.3f}")
    if hi < lo:
        with pytest.raises(QueryError, match="the end comes before the start"):
            parse_query(text)
    else:
        span = parse_query(text).time
        assert span is not None and span.start is not None and span.end is not None
        assert (span.start.seconds, span.end.seconds) == (lo, hi)


@pytest.mark.parametrize(("text", "what"), MALFORMED[:20:3])
def test_the_cli_says_the_same(text: str, what: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(QueryError) as caught:
        parse_query(text)
    code = main(["replay", str(DEMO), "--format", "text", "--filter", text])
    err = capsys.readouterr().err
    assert code == 2
    assert f"--filter: {caught.value}" in err


@pytest.mark.parametrize(("text", "part", "what"), GRAMMAR[::4])
def test_the_cli_refuses_the_grammar_in_one_line(
    text: str, part: str, what: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["replay", str(DEMO), "--format", "text", "--filter", text])
    captured = capsys.readouterr()
    assert code == 2
    assert captured.out == ""
    (line,) = captured.err.splitlines()
    assert line.startswith(f"modscope: error: --filter: {part}: ") and what in line


@pytest.mark.asyncio
@pytest.mark.parametrize("text", ["t:20-10", 'reg:"Under', "unit:3,"])
async def test_the_filter_bar_says_the_same_and_keeps_the_rows(text: str) -> None:
    with pytest.raises(QueryError) as caught:
        parse_query(text)
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(160, 48)) as pilot:
        await ready(pilot, app)
        before = app.frames.count
        app.main.query_one("#filter", LineInput).value = text
        await pilot.press("slash", "enter")
        await settle(pilot, app)
        assert app.main.filter_bar.has_class("-error")
        assert str(caught.value) in screen_text(app).replace("\n", "")
        assert app.frames.count == before
        assert app.filtering.applied == ""


# typed at once in the filter bar: each is applied (and shows the rows a reader means) or
# refused (the bar red, the message on screen, the rows as they were), never read as text
BURST = [
    ("unit:3 or unit:5", {3, 5}),
    ("unit:3 or unit:4", {3}),
    ("(unit:3)", {3}),
    ("unit==3", {3}),
    ("not (unit:3)", None),  # every row but unit 3's
    ("unit:3 or", "or needs a term after it"),
    ("(unit:3", "a ( is not closed"),
    ("unit == 3", "together: unit==3"),
    ("unit:3 || unit:5", "write or"),
    # refused before the grammar grew, but typed at once the Changed messages of the
    # characters, handled after Enter, cleared the refusal: the bar went back to normal
    ("unit:3x", "'3x' is not a number"),
]


@pytest.mark.asyncio
@pytest.mark.parametrize(("text", "expect"), BURST)
async def test_queries_typed_in_one_burst_are_applied_or_refused(
    text: str, expect: set[int] | str | None
) -> None:
    app = ModscopeApp(hostile_session())
    async with app.run_test(size=(160, 48)) as pilot:
        await ready(pilot, app)
        before = app.frames.count
        burst(app, [*("/" + text), "enter"])
        deadline = time.monotonic() + 10
        while not (app.main.filter_bar.has_class("-error") or app.filtering.applied == text):
            assert time.monotonic() < deadline, "neither applied nor refused"
            await pilot.pause(0.02)
        await settle(pilot, app)
        store = app.session.store
        shown = [app.model.view.row(k) for k in range(app.frames.count)]
        if isinstance(expect, str):
            assert app.main.filter_bar.has_class("-error")
            assert expect in app.filtering.error
            assert app.filtering.error in screen_text(app).replace("\n", "")
            assert app.frames.count == before and app.filtering.applied == ""
            return
        assert not app.main.filter_bar.has_class("-error")
        unit_3 = [i for i in range(len(store)) if store.kind[i] in _FRAMES and store.unit[i] == 3]
        if expect is None:
            want = [i for i in range(len(store)) if i not in unit_3]
        else:
            want = [
                i for i in range(len(store)) if store.kind[i] in _FRAMES and store.unit[i] in expect
            ]
        assert want and shown == want

"""Malformed filter terms are refused with a message that names the term and says what to
write, the same words in the TUI's filter bar and in the CLI's --filter; well-formed
queries never raise."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sniffer.cli import main
from sniffer.meaning.query import QueryError, parse_query
from sniffer.tui.app import ModscopeApp
from sniffer.tui.widgets.prompt import LineInput
from tests.support.tui import hostile_session, ready, screen_text, settle

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
    ("t:1-2 t:5-", "one time span per filter"),
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
    first = text.split()[-1] if "one time span" in what else text
    assert message.startswith((first, first.lstrip("-").split(":")[0] + ":", "'"))


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


@given(st.text(alphabet='unitfcksagr:"-, 0123456789.xmh', max_size=30))
def test_any_text_parses_or_says_why(text: str) -> None:
    try:
        query = parse_query(text)
    except QueryError as exc:
        assert str(exc)  # a message, never an empty one
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

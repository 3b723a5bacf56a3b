"""`replay --mqtt` keeps a window of rows, as `replay --stats` does (issue #29): each
row is published, then dropped at the next settled moment, so memory stays flat in the
capture's length. What reaches the broker must be what one store of every row gives:
every value, event and raw read, in the same order on each topic, and the same last
status of each unit; only how often the statuses and the findings fall due differs
(the rows are published at each cut too), and the findings, like a live capture's,
are those of the segment they name. `--stats` beside it counts every row."""

from __future__ import annotations

import io
import json
from collections import defaultdict

import pytest

from sniffer.cli import build_parser
from sniffer.cli import replay as replay_cli
from sniffer.meaning.annotate import load_bindings
from sniffer.outputs.mqtt.publish import BusPublisher, PublisherOptions, publish_replay
from sniffer.outputs.mqtt.target import parse_target
from sniffer.session import streamed
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, open_session
from tests.outputs.test_ha_discovery import PREFIX, KeepingLink
from tests.support.broker import Broker, broker

__all__ = ["broker"]  # (the fixture)


def _published(window: int | None) -> tuple[KeepingLink, list[int]]:
    """The demo published through a link with no broker; the store's size at each cut."""
    bindings = load_bindings(DEMO_BUS)
    session, capture = open_session(DEMO_CAPTURE, bindings=bindings, index=False)
    link = KeepingLink(parse_target("mqtt://127.0.0.1/site/demo", bus="demo"))
    options = PublisherOptions(bus="demo", ha_prefix=PREFIX)
    publisher = BusPublisher(link, session, bindings, options, info=capture.info)
    assert link._on_connect_hook is not None
    link._on_connect_hook()
    publisher.announce()
    kept: list[int] = []

    def segment(s: Session) -> None:
        kept.append(len(s.store))

    publish_replay(session, capture.chunks(), publisher, window=window, segment=segment)
    publisher.rows(final=True)
    return link, kept


def _by_topic(link: KeepingLink) -> dict[str, list[bytes | str]]:
    topics: dict[str, list[bytes | str]] = defaultdict(list)
    for topic, payload in link.messages:
        if topic.endswith("/interface"):  # (names the publishing session: new each run)
            payload = json.dumps({**json.loads(payload), "session": None})
        topics[topic].append(payload)
    return topics


def test_a_windowed_replay_publishes_what_one_store_does() -> None:
    whole, _ = _published(None)
    windowed, kept = _published(50)
    assert len(kept) > 20 and max(kept[:-1]) < 200  # cut, and never near 1,562 rows
    a, b = _by_topic(whole), _by_topic(windowed)
    assert a.keys() == b.keys()
    timed = [t for t in a if t.endswith(("/status", "/findings"))]
    for topic in a.keys() - set(timed):
        assert a[topic] == b[topic], topic  # values, events, raw reads, configs
    for topic in timed:
        assert a[topic][-1] == b[topic][-1] or topic.endswith("/findings"), topic
    last = json.loads(b["site/demo/findings"][-1])
    assert last["first_row"] > 0 and last["first_row"] + last["rows"] == 1562


def test_stats_beside_mqtt_count_every_row(broker: Broker, monkeypatch: pytest.MonkeyPatch) -> None:
    """`replay --mqtt URL --stats` prints what `replay --stats` prints, the rows
    published a window at a time (a window of 40 rows here: the demo is cut)."""
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    monkeypatch.setattr(replay_cli, "REPLAY_WINDOW", 40)
    cut = []
    new_segment = Session.new_segment

    def counting(self: Session) -> bool:
        done = new_segment(self)
        cut.append(done)
        return done

    monkeypatch.setattr(Session, "new_segment", counting)
    url = f"mqtt://127.0.0.1:{broker.port}/modscope/demo"
    outputs, cuts = [], []
    for extra in ([], ["--mqtt", url]):
        args = build_parser().parse_args(["replay", str(DEMO_CAPTURE), "--stats", *extra])
        out, err = io.StringIO(), io.StringIO()
        assert args.func(args, out, err) == 0, err.getvalue()
        outputs.append(out.getvalue())
        cuts.append(sum(cut))
        cut.clear()
    assert cuts[1] > 10  # the published rows went a window at a time
    assert "published" in err.getvalue()
    assert outputs[1] == outputs[0]


def test_a_listing_beside_mqtt_is_the_listing_alone(
    broker: Broker, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`replay --mqtt URL --format jsonl` publishes a window of rows at a time, then
    lists the capture as `replay --format jsonl` does, reading it again in two passes:
    no pass keeps every row (it kept them all for the listing before)."""
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    monkeypatch.setattr(replay_cli, "REPLAY_WINDOW", 40)
    monkeypatch.setattr(streamed, "LEARN_WINDOW", 40)
    monkeypatch.setattr(streamed, "LIST_WINDOW", 60)
    dropped: list[int] = []  # the store's rows at each cut of the run under way
    new_segment = Session.new_segment

    def measuring(self: Session) -> bool:
        dropped.append(len(self.store))
        return new_segment(self)

    monkeypatch.setattr(Session, "new_segment", measuring)
    url = f"mqtt://127.0.0.1:{broker.port}/modscope/demo"
    outputs, cuts = [], []
    for extra in ([], ["--mqtt", url]):
        args = build_parser().parse_args(
            ["replay", str(DEMO_CAPTURE), "--format", "jsonl", "--jobs", "1", *extra]
        )
        out, err = io.StringIO(), io.StringIO()
        assert args.func(args, out, err) == 0, err.getvalue()
        outputs.append(out.getvalue())
        cuts.append(list(dropped))
        dropped.clear()
    assert "values" in err.getvalue() and "published" in err.getvalue()
    rows = outputs[0].count("\n")
    assert outputs[1] == outputs[0] and rows > 1000
    # the listing's two passes, and before them the publishing, each went a segment at
    # a time: more cuts than the listing alone made, none of a store near every row
    assert len(cuts[1]) > len(cuts[0]) + 10
    assert max(cuts[1]) < rows // 4

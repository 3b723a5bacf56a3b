"""`replay --mqtt` exits 1 when messages never reached the broker (dropped once its
buffer was full, or still undelivered at the end), after the line that says how many
and why: data lost on the way to the integration is a failed run, as a capture cut
short is. Found measuring #29: 1M frames to a plain Mosquitto lost most of their
messages when the connection dropped, and the run exited 0."""

from __future__ import annotations

import io
from typing import Any

import pytest

from sniffer.cli import build_parser
from sniffer.outputs.mqtt import command
from sniffer.outputs.mqtt.publish import BusPublisher
from sniffer.session.session import DEMO_CAPTURE
from tests.outputs.test_ha_discovery import KeepingLink


class DroppingLink(KeepingLink):
    """Takes every message but each raw read after the first `keep`, which it drops,
    as a link whose buffer is full drops them."""

    keep = 100

    def publish(
        self, topic: str, payload: bytes | str, *, retain: bool = False, block: bool = False
    ) -> bool:
        self.counts.offered += 1
        if topic.endswith("/raw") and self.counts.offered > self.keep:
            self.counts.dropped += 1
            return False
        self.counts.delivered += 1
        return super().publish(topic, payload, retain=retain, block=block)

    def drain(self, timeout: float) -> bool:
        return True  # (nothing waits in this link)

    def report(self) -> str:
        c = self.counts
        dropped = f", {c.dropped:,} dropped" if c.dropped else ""
        return f"mqtt: {c.delivered:,} messages delivered{dropped}"


@pytest.mark.parametrize(("keep", "status"), [(10**9, 0), (100, 1)])
def test_lost_messages_fail_the_run(
    monkeypatch: pytest.MonkeyPatch, keep: int, status: int
) -> None:
    def opened(target: Any, session: Any, bindings: Any, options: Any, **kw: Any) -> BusPublisher:
        link = DroppingLink(target)
        link.keep = keep
        publisher = BusPublisher(link, session, bindings, options, info=kw.get("info"))
        publisher.announce()
        return publisher

    monkeypatch.setattr(command, "open_publisher", opened)
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")
    for extra in ([], ["--stats"]):
        args = build_parser().parse_args(
            ["replay", str(DEMO_CAPTURE), "--mqtt", "mqtt://127.0.0.1:1/x", *extra]
        )
        out, err = io.StringIO(), io.StringIO()
        assert args.func(args, out, err) == status, err.getvalue()
        said = err.getvalue()
        assert ("dropped" in said.split("published; ")[1]) == bool(status)
        if extra:
            assert "unit" in out.getvalue()  # the statistics printed all the same

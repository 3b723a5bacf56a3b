"""Provides helpers shared by tests (moved from test_describe_shared.py)."""

from __future__ import annotations

from collections.abc import Sequence

from sniffer.meaning.annotate import load_bindings
from sniffer.model import Chunk, LineSettings
from sniffer.session.session import DEMO_BUS, Session

LINE = LineSettings(baud=19200, bytesize=8, parity="E", stopbits=1, mode="rtu")


T0 = 1_700_000_000.0


BINDINGS = load_bindings(DEMO_BUS)  # 1 ved903b, 2 dcrl (parameter windows), 3 rvs-dn


def session(exchanges: Sequence[tuple[bytes, bytes | None, float]], bound: bool = True) -> Session:
    """Each (request, answer or None, seconds to the answer) 0.3 s after the last."""
    s = Session(LINE, bindings=BINDINGS if bound else {})
    t = T0
    for request, reply, delay in exchanges:
        t += 0.3
        end = t + len(request) * LINE.char_time
        s.feed(Chunk(request, end))
        if reply is not None:
            s.feed(Chunk(reply, end + delay + len(reply) * LINE.char_time))
    s.finish()
    return s

"""Provides the `findings` topic: the bus doctor's findings (`sniffer.analysis.doctor`) on
the rows a publisher has seen, as one retained JSON message under the base topic.

The rows are those the session holds: a publisher's memory starts a new segment every
`sniffer.live.engine.WINDOW_ROWS` rows or so live, and every 65,536 in a replay (a
network capture's once no request waits for an answer: `Session.settled`), so the
findings are those of the current segment. The message says which: `first_row`, the
capture's number of the first of them, and `rows`, how many (a finding that needs
older rows cannot be made, and none is claimed of them).

The findings are worked out again at most every FINDINGS_EVERY seconds of the
publisher's own time (the doctor reads every row, so a long replay must not do it at
each status message), and always once more at the end.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Mapping

from sniffer.analysis.doctor import diagnose, response_bounds
from sniffer.meaning.annotate import Binding
from sniffer.outputs.mqtt.payload import iso_time
from sniffer.session.session import Session

FINDINGS_EVERY = 10.0  # seconds (monotonic) between two findings messages


class FindingsClock:
    """When the findings are due again: at the first look, every FINDINGS_EVERY
    seconds after, and at the end."""

    def __init__(
        self, every: float = FINDINGS_EVERY, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.every = every
        self.clock = clock
        self._last: float | None = None

    def due(self, final: bool) -> bool:
        now = self.clock()
        if final or self._last is None or now - self._last >= self.every:
            self._last = now
            return True
        return False


def findings_payload(session: Session, bindings: Mapping[int, Binding]) -> str:
    """The message: when (the newest row's time), which rows (the first's number in the
    capture, how many), the counts by severity, and the findings as `modscope doctor
    --format json` gives them."""
    store = session.store
    bounds = response_bounds({u: b.dictionary.timing for u, b in bindings.items()})
    diagnosis = diagnose(store, session.line, session.pipeline.pairer.timeout, bounds)
    counts = diagnosis.counts()
    n = len(store)
    t = store.t_end[n - 1] if n else None
    message = {
        "t": t,
        "time": None if t is None else iso_time(t),
        "first_row": session.base,
        "rows": n,
        "errors": counts["error"],
        "warnings": counts["warning"],
        "info": counts["info"],
        "findings": [f.record() for f in diagnosis.findings],
    }
    return json.dumps(message, ensure_ascii=False)

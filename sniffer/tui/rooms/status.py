"""Provides the status line's room: what the status bar says (source, line, rows, rate,
errors, indexing, recording, losses), on the main screen and the screens that show it."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

from sniffer.analysis.liveness import LineLiveness, liveness
from sniffer.framing.tcp import NetPipeline
from sniffer.session.session import Session
from sniffer.sources.net.carrier import parse_label
from sniffer.tui.feed import LiveStatus, live_status
from sniffer.tui.rooms.base import Room
from sniffer.tui.screens.ladder import LadderScreen
from sniffer.tui.screens.regtable import TableScreen
from sniffer.tui.widgets.status import StatusInfo

if TYPE_CHECKING:
    from sniffer.tui.app import ModscopeApp


class StatusLine(Room):
    """Gathers the status bar's facts from the rooms and shows them."""

    def __init__(self, app: ModscopeApp) -> None:
        super().__init__(app)
        self._rate_mark: tuple[float, int] = (time.monotonic(), 0)
        self._rate: float | None = None

    def reset_rate(self) -> None:
        """The rows start over (a restart): the rate is measured again."""
        self._rate_mark, self._rate = (time.monotonic(), 0), None

    def measure_rate(self) -> None:
        """Rows a second while they arrive, over a second or more (called every tick)."""
        now = time.monotonic()
        mark_t, mark_rows = self._rate_mark
        rows = self.model.published
        if rows < mark_rows:  # a restart (s) began again from the first row
            self._rate_mark, self._rate = (now, rows), None
        elif now - mark_t >= 1.0:
            self._rate = (rows - mark_rows) / (now - mark_t) if not self.model.done else None
            self._rate_mark = (now, rows)

    def now(self) -> float:
        """The time ages are measured to: a live capture's clock (`LiveCapture.now`, the
        clock its stamps come from), else the newest frame (a capture's end)."""
        clock = getattr(self.app.live, "now", None)
        return float(clock()) if callable(clock) else self.model.latest

    def liveness(self) -> LineLiveness | None:
        """The live line's state from the clock; None for a capture file or a live
        source without a clock (nothing to judge it by)."""
        app = self.app
        if app.live is None or not callable(getattr(app.live, "now", None)):
            return None
        stats = app.session.stats
        return liveness(
            list(stats.units.values()),
            dict(self.model.last_answer),
            self.now(),
            self.model.reader.resolution,
        )

    def show(self) -> None:
        app = self.app
        model, session = self.model, app.session
        stats = session.stats
        errors = sum(u.check_errors for u in list(stats.units.values())) + stats.noise_spans
        rate = self._rate
        if model.done:  # the capture's own rate
            span = model.latest - model.origin
            rate = model.published / span if span > 0 else None
        live = app.live
        alive = self.liveness()
        status = live_status(live) if live is not None else LiveStatus()
        info = StatusInfo(
            source=Path(session.source).name if live is None else session.source,
            line=carried(session),
            rows=model.published,
            bytes=model.reader.bytes_total,
            errors=errors,
            rate=rate,
            indexing=not model.done and live is None and app.pacing.speed is None,
            paused=app.paused,
            following=self.frames.at_newest,
            speed="1x" if app.pacing.speed else "",
            recording=Path(status.recording).name if status.recording else "",
            recorded_bytes=status.recorded_bytes,
            losses=status.lost_bytes,
            note=app.feeding.note or status.failure,
            live=live is not None,
            reconnecting=status.reconnecting,
            progress=app.feeding.index_progress(),
            liveness=alive.state.value if alive is not None else "",
            since_frame=alive.since_frame if alive is not None else None,
            resolution=alive.resolution if alive is not None else 0.0,
        )
        self.main.status.show(info)
        screen = app.screen
        if isinstance(screen, LadderScreen | TableScreen):
            screen.status.show(info)


def carried(session: Session) -> str:
    """What the status bar says the capture carries: the serial line's settings and mode,
    or, for a network capture (no serial line: `--baud` does not apply), its carriers."""
    pipeline = session.pipeline
    if isinstance(pipeline, NetPipeline):
        labels = map(parse_label, pipeline.channel_labels.values())
        carriers = sorted({label.carrier for label in labels if label is not None})
        return f"network: {', '.join(carriers)}" if carriers else "network"
    line = session.line.describe()
    if session.mode != session.line.mode:
        line += f" ({session.mode})"
    return line

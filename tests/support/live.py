"""Provides helpers shared by tests (moved from test_live_updates.py)."""

from __future__ import annotations

import io
import json
from collections.abc import Sequence
from typing import Any

from sniffer.cli.backlog import Backlog
from sniffer.cli.filtering import Selection
from sniffer.cli.live import stream
from sniffer.framing.pipeline import LIVE_MERGE_SLACK
from sniffer.live.engine import GlobalRows, LiveCapture
from sniffer.live.port import ChunkFeed, PortSpec, PortStats
from sniffer.model import Chunk, LineSettings
from sniffer.outputs.export import PcapExporter
from sniffer.outputs.listing import UPDATED_KEYS, Lister
from sniffer.session.session import Session
from sniffer.text import json_line


def applied(lines: list[str]) -> list[str]:
    """The frames of a live JSONL listing with every update put into its row: the
    `transaction` replaced, the line written again as the lister writes it."""
    frames: dict[int, dict[str, Any]] = {}
    order: list[int] = []
    kept: dict[int, str] = {}
    for line in lines:
        rec = json.loads(line)
        if "raw" in rec:
            frames[rec["index"]] = rec
            kept[rec["index"]] = line
            order.append(rec["index"])
        else:
            assert set(rec) <= {"update", *UPDATED_KEYS}, rec
            row = frames[rec["update"]]
            assert row["transaction"]["status"] == "open"  # only open rows get one
            # the keys an update carries, where a row has them (problem_details after
            # summary, only when there are problems)
            row.pop("problem_details", None)
            merged: dict[str, Any] = {}
            for key, value in row.items():
                merged[key] = rec.get(key, value)
                if key == "summary" and "problem_details" in rec:
                    merged["problem_details"] = rec["problem_details"]
            frames[rec["update"]] = merged
            kept[rec["update"]] = json_line(merged)
    return [kept[i] for i in order]


FAST = LineSettings(baud=921600, parity="N", stopbits=1, mode="rtu")


T0 = 1_700_000_000.0  # a wall-clock time, as live stamps are


class Batches(ChunkFeed):
    """A feed that hands out one prepared batch of reads per `get`, then is closed."""

    def __init__(self, batches: Sequence[list[Chunk]]) -> None:
        super().__init__()
        self.batches = list(reversed(batches))

    def get(self, timeout: float | None = None) -> list[Chunk]:
        return self.batches.pop() if self.batches else []

    @property
    def closed(self) -> bool:
        return not self.batches


class Clock:
    def now(self) -> float:
        return T0 + 3600


class Played:
    """A reader (sniffer.live.engine.Reader) of prepared batches."""

    def __init__(self, line: LineSettings, batches: Sequence[list[Chunk]]) -> None:
        self.specs = [PortSpec("/dev/played", line)]
        self.clock = Clock()
        self.stats: list[PortStats] = []
        self.warnings: list[str] = []
        self.failure: str | None = None
        self.error: Exception | None = None
        self.feed = Batches(batches)

    @property
    def running(self) -> bool:
        return not self.feed.closed

    def subscribe(self, maxsize: int = 0) -> ChunkFeed:
        return self.feed

    def attach(self, maxsize: int = 0) -> ChunkFeed:
        raise AssertionError("no recording on demand here")

    def detach(self, feed: ChunkFeed) -> None:
        pass

    def start(self) -> None:
        pass

    def stop(self, timeout: float = 2.0) -> None:
        pass


class Run:
    """The live listing of `batches` as `modscope live --format jsonl` writes it, with
    how many rows the store held after each pump."""

    def __init__(
        self,
        line: LineSettings,
        batches: Sequence[list[Chunk]],
        window: int | None,
        timeout: float | None = None,
        fmt: str = "jsonl",
        pcap: bool = False,
    ) -> None:
        session = Session(line, timeout=timeout, source="played", merge_slack=LIVE_MERGE_SLACK)
        # quiet=inf: never idle by the wall clock, so both runs pump alike
        capture = LiveCapture(Played(line, batches), session, quiet=float("inf"), window=window)
        self.sizes: list[int] = []
        pump = capture.pump

        def counted(timeout: float = 0.0) -> range:
            rows = pump(timeout)
            self.sizes.append(len(session.store))
            return rows

        capture.pump = counted  # type: ignore[method-assign]
        out = io.StringIO()
        lister = Lister(io.StringIO(), fmt, GlobalRows(session))
        self.pcap = io.BytesIO()
        exporter = PcapExporter(self.pcap, GlobalRows(session), line) if pcap else None
        stream(capture, lister, exporter, None, Backlog(out), None, Selection(session, None, None))
        self.lines = out.getvalue().splitlines()
        self.session = session
        self.capture = capture


def reads(frames: list[tuple[bytes, float]], every: float, t0: float = T0) -> list[Chunk]:
    """Frames (bytes, start time) on `FAST` as an adapter delivers them: a read every
    `every` seconds holding the bytes on the wire by then (frames cut anywhere)."""
    char = FAST.char_time
    out: list[Chunk] = []
    buf = bytearray()
    due = every
    for raw, start in frames:
        for k, byte in enumerate(raw):
            end = start + (k + 1) * char
            while end > due:
                if buf:
                    out.append(Chunk(bytes(buf), t0 + due))
                    buf.clear()
                due += every
            buf.append(byte)
    if buf:
        out.append(Chunk(bytes(buf), t0 + due))
    return out

"""Provides the pipeline: chunks from any source in, framed and paired frames in a store out.

One framer per channel (a port or probe per direction is framed on its own); frames of
several channels are merged by time before they reach the store. The same pipeline
serves replay and live capture, so a recording frames exactly as the line did.
"""

from __future__ import annotations

import heapq
from collections.abc import Iterable
from dataclasses import dataclass, field

from sniffer.framing import AsciiFramer, Framer, Kind, RtuFramer, looks_ascii
from sniffer.model import Chunk, Direction, LineSettings
from sniffer.pairing import Pairer, default_timeout
from sniffer.store import FrameStore

MERGE_SLACK = 1.0  # seconds a channel's frames are held back so others can catch up


@dataclass
class _Channel:
    framer: Framer | None
    direction: Direction
    sample: bytearray = field(default_factory=bytearray)
    held: list[Chunk] = field(default_factory=list)
    last_t: float = float("-inf")


class Pipeline:
    """Feeds chunks through framing, merging and pairing into `store`."""

    def __init__(
        self,
        line: LineSettings,
        store: FrameStore | None = None,
        *,
        exact_timing: bool = False,
        timeout: float | None = None,
    ) -> None:
        self.line = line
        self.store = store if store is not None else FrameStore()
        self.exact_timing = exact_timing
        self.pairer = Pairer(self.store, timeout if timeout is not None else default_timeout(line))
        self.mode: str | None = None if line.mode == "auto" else line.mode
        self.channels: dict[int, _Channel] = {}
        self._heap: list[tuple[float, int, bytes, float, int, int, int]] = []
        self._seq = 0

    # -- input ---------------------------------------------------------------------------

    def feed(self, chunk: Chunk) -> None:
        ch = self.channels.get(chunk.channel)
        if ch is None:
            ch = _Channel(framer=None, direction=chunk.direction)
            self.channels[chunk.channel] = ch
        if chunk.event and not chunk.data:
            text = chunk.event + (f": {chunk.note}" if chunk.note else "")
            if len(self.channels) <= 1:
                self.store.add_event(chunk.t_end, text, chunk.channel)
            else:
                self._hold(chunk.t_end, b"", chunk.t_end, int(Kind.EVENT), 0, chunk.channel)
                self.store.notes[-self._seq] = text
            self._release(final=False)
            return
        if ch.framer is None:
            if self.mode is None:
                ch.held.append(chunk)
                ch.sample += chunk.data
                verdict = looks_ascii(bytes(ch.sample[:512]))
                if verdict is None and len(ch.sample) < 64:
                    return
                self.mode = "ascii" if verdict else "rtu"
            ch.framer = self._make_framer(chunk.channel, ch.direction)
            held, ch.held = ch.held, []
            for old in held:
                ch.framer.feed(old)
            if held:
                ch.last_t = held[-1].t_end
                self._release(final=False)
                return
        ch.framer.feed(chunk)
        ch.last_t = chunk.t_end
        self._release(final=False)

    def feed_all(self, chunks: Iterable[Chunk]) -> None:
        for chunk in chunks:
            self.feed(chunk)

    def idle(self, now: float) -> None:
        """Live sources call this when the line has been quiet: frames buffered in the
        framers are decided, and overdue requests time out."""
        for ch in self.channels.values():
            if ch.framer is not None and now - ch.last_t >= self.line.t35:
                ch.framer.idle()
        self._release(final=False, now=now)
        self.pairer.tick(now)

    def finish(self) -> None:
        for number, ch in self.channels.items():
            if ch.framer is None:
                self.mode = self.mode or "rtu"
                ch.framer = self._make_framer(number, ch.direction)
                for old in ch.held:
                    ch.framer.feed(old)
                ch.held = []
            ch.framer.finish()
        self._release(final=True)
        self.pairer.finish()

    # -- internals -----------------------------------------------------------------------

    def _make_framer(self, channel: int, direction: Direction) -> Framer:
        cls = AsciiFramer if self.mode == "ascii" else RtuFramer
        return cls(
            self.line,
            self._sink,
            channel=channel,
            direction=direction,
            exact_timing=self.exact_timing,
        )

    def _sink(self, raw: bytes, t0: float, t1: float, kind: int, flags: int, ch: int) -> None:
        if len(self.channels) <= 1:
            self.store.append(raw, t0, t1, kind, flags, ch)
            return
        self._hold(t0, raw, t1, kind, flags, ch)

    def _hold(self, t0: float, raw: bytes, t1: float, kind: int, flags: int, ch: int) -> None:
        self._seq += 1
        heapq.heappush(self._heap, (t0, self._seq, raw, t1, kind, flags, ch))

    def _release(self, final: bool, now: float | None = None) -> None:
        heap = self._heap
        if heap:
            if final:
                watermark = float("inf")
            else:
                latest = [c.last_t for c in self.channels.values()]
                watermark = min(latest) - MERGE_SLACK if latest else float("-inf")
                if now is not None:
                    watermark = max(watermark, now - MERGE_SLACK)
            store = self.store
            while heap and heap[0][0] <= watermark:
                t0, seq, raw, t1, kind, flags, ch = heapq.heappop(heap)
                if kind == Kind.EVENT:
                    store.add_event(t0, store.notes.pop(-seq, ""), ch)
                else:
                    store.append(raw, t0, t1, kind, flags, ch)
        self.pairer.update()


def frame_capture(
    chunks: Iterable[Chunk],
    line: LineSettings,
    *,
    exact_timing: bool = False,
    timeout: float | None = None,
) -> FrameStore:
    """Frame and pair a whole capture."""
    pipeline = Pipeline(line, exact_timing=exact_timing, timeout=timeout)
    pipeline.feed_all(chunks)
    pipeline.finish()
    return pipeline.store

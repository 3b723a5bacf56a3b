"""Provides the pipeline: chunks from any source in, framed and paired frames in a store out.

One framer per channel (a port or probe per direction is framed on its own); rows of
several channels are merged by time before they reach the store. The same pipeline
serves replay and live capture, so a recording frames exactly as the line did.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from dissectors.functions import FUNCTIONS, Registry
from sniffer.framing import AsciiFramer, Framer, RtuFramer, looks_ascii
from sniffer.model import Chunk, Direction, LineSettings
from sniffer.pairing import Pairer, default_timeout
from sniffer.store import FrameStore
from sniffer.vocab import Flag, Kind

CAPTURE_COMPLETE = "capture complete"  # a source's last word: when the capture ended
BYTE_ERRORS = ("framing error", "parity error")  # events about the byte before them
MERGE_SLACK = 1.0  # seconds a channel's rows are held back so that others can catch up
LIVE_MERGE_SLACK = 0.05  # live ports share one clock: a little is enough


@dataclass
class _Channel:
    number: int
    direction: Direction
    framer: Framer | None = None
    staging: FrameStore | None = None  # rows waiting to be merged (several channels)
    read: int = 0  # next staging row to merge
    held: list[Chunk] | None = None  # chunks kept while the mode is being detected
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
        registry: Registry | None = None,
        merge_slack: float = MERGE_SLACK,
    ) -> None:
        self.line = line
        self.merge_slack = merge_slack
        self.store = store if store is not None else FrameStore()
        self.exact_timing = exact_timing
        # the public registry, or one with the vendor codes of the devices on this bus
        self.registry: Registry = registry if registry is not None else FUNCTIONS
        self.pairer = Pairer(
            self.store,
            timeout if timeout is not None else default_timeout(line),
            self.registry.answered_broadcasts,
        )
        self.mode: str | None = None if line.mode == "auto" else line.mode
        self.channels: dict[int, _Channel] = {}
        self._sample = bytearray()
        self._bus_end: float | None = None  # end of the last frame merged, any channel

    @property
    def multi(self) -> bool:
        return len(self.channels) > 1

    # -- input ---------------------------------------------------------------------------

    def feed(self, chunk: Chunk) -> None:
        ch = self.channels.get(chunk.channel)
        if ch is None:
            ch = self._add_channel(chunk.channel, chunk.direction)
        if chunk.event == CAPTURE_COMPLETE and not chunk.data:
            # the recorder stopped here: requests still open by then have timed out
            self.pairer.end_time = max(self.pairer.end_time, chunk.t_end)
            return
        if chunk.event in BYTE_ERRORS and self.exact_timing and ch.framer is not None:
            ch.framer.line_error()  # exact sources report it right after its byte
        if chunk.event and not chunk.data:
            text = chunk.event + (f": {chunk.note}" if chunk.note else "")
            (ch.staging if ch.staging is not None else self.store).add_event(
                chunk.t_end, text, chunk.channel
            )
            ch.last_t = max(ch.last_t, chunk.t_end)
            self._release(final=False)
            return
        if ch.framer is None and not self._detect(ch, chunk):
            return
        assert ch.framer is not None
        ch.framer.feed(chunk)
        ch.last_t = chunk.t_end
        if self.multi:
            self._release(final=False)

    def feed_all(self, chunks: Iterable[Chunk]) -> None:
        for chunk in chunks:
            self.feed(chunk)

    def sync(self) -> None:
        """Bring the store up to date: complete the framers' rows, merge channels, pair.
        Readers of the store call this (Session.refresh does) before they look."""
        self._release(final=False)
        self.pairer.update()

    def idle(self, now: float) -> None:
        """Live sources call this when the line has been quiet: bytes buffered in the
        framers are decided, and overdue requests time out."""
        for ch in self.channels.values():
            if ch.framer is not None and now - ch.last_t >= self.line.t35:
                ch.framer.idle()
        self._release(final=False, now=now)
        self.pairer.tick(now)

    def finish(self) -> None:
        for ch in self.channels.values():
            if ch.framer is None:
                self.mode = self.mode or "rtu"
                self._start_framer(ch)
            assert ch.framer is not None
            ch.framer.finish()
        self._release(final=True)
        self.pairer.finish()

    # -- internals -----------------------------------------------------------------------

    def _add_channel(self, number: int, direction: Direction) -> _Channel:
        ch = _Channel(number, direction)
        self.channels[number] = ch
        if len(self.channels) == 2:
            # from now on every channel's rows wait in staging to be merged by time
            for other in self.channels.values():
                other.staging = FrameStore(self.store.streams)
                if other.framer is not None:
                    # complete the rows its fast path left in the store (their channel
                    # column) before the framer writes elsewhere
                    other.framer.flush()
                    other.framer.out = other.staging
                    other.framer.pair_inline = False
        elif len(self.channels) > 2:
            ch.staging = FrameStore(self.store.streams)
        return ch

    def _detect(self, ch: _Channel, chunk: Chunk) -> bool:
        """Start the channel's framer, once the mode is known. False while still unsure."""
        if self.mode is None:
            if ch.held is None:
                ch.held = []
            ch.held.append(chunk)
            self._sample += chunk.data
            verdict = looks_ascii(bytes(self._sample[:512]))
            if verdict is None and len(self._sample) < 64:
                return False
            self.mode = "ascii" if verdict else "rtu"
            self._start_framer(ch)
            return False
        self._start_framer(ch)
        return True

    def _start_framer(self, ch: _Channel) -> None:
        cls = AsciiFramer if self.mode == "ascii" else RtuFramer
        ch.framer = cls(
            self.line,
            ch.staging if ch.staging is not None else self.store,
            channel=ch.number,
            direction=ch.direction,
            exact_timing=self.exact_timing,
            functions=self.registry,
        )
        if isinstance(ch.framer, RtuFramer):
            ch.framer.pair_inline = ch.staging is None
        held, ch.held = ch.held or [], None
        for old in held:
            ch.framer.feed(old)
            ch.last_t = old.t_end
        for other in self.channels.values():
            if other is not ch and other.held:
                self._start_framer(other)

    def _release(self, final: bool, now: float | None = None) -> None:
        """Complete framed rows and, with several channels, merge those whose time has
        come. Pairing waits for sync(), idle() or finish()."""
        for ch in self.channels.values():
            if ch.framer is not None:
                ch.framer.flush()
        if self.multi:
            if final:
                watermark = float("inf")
            else:
                watermark = min(c.last_t for c in self.channels.values()) - self.merge_slack
                if now is not None:
                    watermark = max(watermark, now - self.merge_slack)
            self._merge(watermark)

    def _merge(self, watermark: float) -> None:
        store = self.store
        staged = [c for c in self.channels.values() if c.staging is not None]
        while True:
            best: _Channel | None = None
            best_t = watermark
            for c in staged:
                st = c.staging
                assert st is not None
                if c.read < len(st) and st.t[c.read] <= best_t:
                    best, best_t = c, st.t[c.read]
            if best is None:
                break
            assert best.staging is not None
            store.copy_row(best.staging, best.read)
            best.read += 1
            if self.exact_timing:
                self._bus_silence(len(store) - 1)
        for c in staged:
            st = c.staging
            assert st is not None
            if c.read and c.read == len(st):
                c.staging = FrameStore(store.streams)
                if c.framer is not None:
                    c.framer.out = c.staging
                c.read = 0

    def _bus_silence(self, row: int) -> None:
        """With one channel per direction, the silence that matters is the bus's: the
        time since the last frame on any channel (a slave answering inside t3.5)."""
        store = self.store
        kind = store.kind[row]
        if kind == Kind.NOISE or kind == Kind.EVENT:
            return
        flags = store.flags[row] & ~Flag.SHORT_SILENCE
        if self._bus_end is not None and store.t[row] - self._bus_end < self.line.t35:
            flags |= Flag.SHORT_SILENCE
        store.flags[row] = flags
        self._bus_end = store.t_end[row]


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


__all__ = ["Pipeline", "frame_capture"]

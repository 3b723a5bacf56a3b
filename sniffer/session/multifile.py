"""Provides several captures replayed together: merged by time into one store, each file
on its own channels, clocks aligned, and both sides of a gateway linked.

Each file is framed and paired on its own (`replay_file`), so a file frames exactly as
it would alone. `merge` then copies every row into one store in time order (each
file's own order kept), with `offset` seconds added to the file's times and its
channels moved up past the previous file's. Pairing is kept (partners renumbered);
network rows keep their `ip:port`.

When one file is a network capture and another a serial one, `link_files` links each
Modbus TCP transaction to the RTU transaction that carried it (`sniffer.analysis.gateway`) and
marks both sides' rows (`FrameStore.links`: `peer`, `delay_ms`, `verdict`, `text`).
"""

from __future__ import annotations

import heapq
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

from sniffer.analysis.gateway import (
    Link,
    Side,
    coarse_offset,
    estimate_offset,
    link_sides,
    transactions,
)
from sniffer.analysis.stats import Stats
from sniffer.framing.store import NO_PARTNER, FrameStore
from sniffer.framing.tcp import NetPipeline
from sniffer.meaning.describe import Describer
from sniffer.model import Stamp
from sniffer.session.session import Session

MAX_CHANNELS = 256  # the store keeps channel numbers in one byte


@dataclass(frozen=True, slots=True)
class Part:
    """One file of a merged replay: its session, whether it is a network capture, the
    seconds added to its times, and where its rows and channels went."""

    name: str
    session: Session
    network: bool
    offset: float
    channel_base: int
    rows: tuple[int, ...]  # merged row of each of the file's rows


@dataclass(frozen=True, slots=True)
class Alignment:
    """How one file's clock was put on the first network file's: given or estimated
    (`spread`: median absolute deviation of the samples, seconds)."""

    name: str
    offset: float
    estimated: bool
    spread: float = 0.0
    samples: int = 0

    def text(self) -> str:
        if not self.estimated:
            return f"{self.name}: clock offset {self.offset:+.6f} s (given)"
        return (
            f"{self.name}: clock offset {self.offset:+.6f} s estimated from {self.samples} "
            f"matching transaction(s), spread {self.spread * 1000:.2f} ms "
            f"(give --offset {self.name}=SECONDS to set it)"
        )


def _rows(store: FrameStore, offset: float, file: int) -> Iterator[tuple[float, int, int]]:
    t = store.t
    for i in range(len(store)):
        yield t[i] + offset, file, i


def _weaker(a: Stamp, b: Stamp) -> Stamp:
    order = (
        Stamp.EXACT,
        Stamp.FRAME_END,
        Stamp.FRAME_START,
        Stamp.READ_END,
        Stamp.PRINT,
        Stamp.NONE,
    )
    return a if order.index(a) >= order.index(b) else b


def merge(
    names: Sequence[str], sessions: Sequence[Session], offsets: Sequence[float]
) -> tuple[Session, list[Part], list[str]]:
    """One session holding the rows of all `sessions` (module doc), its parts, and
    warnings (files whose channels do not fit)."""
    warnings: list[str] = []
    merged = FrameStore()
    bases: list[int] = []
    base = 0
    for name, s in zip(names, sessions, strict=True):
        bases.append(base)
        s.store.sync()
        top = max(s.store.streams, default=-1)
        if base + top >= MAX_CHANNELS:
            warnings.append(
                f"{name}: its channels do not fit beside the files before it; "
                "replay it with fewer files"
            )
        for ch, stream in s.store.streams.items():
            if base + ch < MAX_CHANNELS:
                merged.streams[base + ch] = stream
        for ch, peer in s.store.peers.items():
            merged.peers[base + ch] = peer
        for ch, server in s.store.servers.items():
            merged.servers[base + ch] = server
        base += top + 1
        base += base % 2  # a connection's two channels stay 2k and 2k + 1
    maps = [[0] * len(s.store) for s in sessions]
    stamps = sessions[0].store.stamps
    resolution = 0.0
    for s in sessions:
        stamps = _weaker(stamps, s.store.stamps)
        resolution = max(resolution, s.store.resolution)
    merged.stamps, merged.resolution = stamps, resolution
    streams = [
        _rows(s.store, off, k) for k, (s, off) in enumerate(zip(sessions, offsets, strict=True))
    ]
    for _, k, i in heapq.merge(*streams):
        src = sessions[k].store
        ch = src.channel[i] + bases[k]
        if ch >= MAX_CHANNELS:
            continue
        maps[k][i] = len(merged)
        if i in src.notes:
            merged.notes[len(merged)] = src.notes[i]
        off = offsets[k]
        merged.offset.append(src.offset[i])
        merged.length.append(src.length[i])
        merged.t.append(src.t[i] + off)
        merged.t_end.append(src.t_end[i] + off)
        merged.kind.append(src.kind[i])
        merged.unit.append(src.unit[i])
        merged.fc.append(src.fc[i])
        merged.flags.append(src.flags[i])
        merged.channel.append(ch)
        merged.partner.append(src.partner[i])  # renumbered below
        merged.status.append(src.status[i])
    for k, s in enumerate(sessions):
        m = maps[k]
        for i in range(len(s.store)):
            j = s.store.partner[i]
            if j != NO_PARTNER:
                merged.partner[m[i]] = m[j]
    first = sessions[0]
    session = Session(
        first.line,
        bindings=first.annotator.bindings,
        source=" + ".join(names),
        stamps=stamps,
        resolution=resolution,
    )
    # the merged rows are complete: the session looks at them, its pipeline stays idle
    session.store = merged
    session.stats = Stats(merged)
    session.describer = Describer(merged, session.annotator)
    session.refresh()
    parts = [
        Part(name, s, _network(s), off, b, tuple(m))
        for name, s, off, b, m in zip(names, sessions, offsets, bases, maps, strict=True)
    ]
    return session, parts, warnings


def _network(session: Session) -> bool:
    return isinstance(session.pipeline, NetPipeline)


def align(
    names: Sequence[str],
    sessions: Sequence[Session],
    given: dict[str, float],
) -> list[Alignment]:
    """Each file's offset: given (`--offset`), else estimated against the first network
    file for serial files (0 for the first network file and when nothing matches)."""
    nets = [k for k, s in enumerate(sessions) if _network(s)]
    ref = nets[0] if nets else 0
    ref_sides = transactions(sessions[ref].store) if nets else []
    base = given.get(names[ref], 0.0)
    out = []
    for k, (name, s) in enumerate(zip(names, sessions, strict=True)):
        if name in given:
            out.append(Alignment(name, given[name], False))
            continue
        if k == ref or _network(s) or not nets:
            out.append(Alignment(name, base if k == ref else 0.0, False))
            continue
        serial = transactions(s.store)
        guess = coarse_offset(ref_sides, serial)
        found = (
            None if guess is None else estimate_offset(ref_sides, serial, window=0.1, guess=guess)
        )
        if found is None:
            out.append(Alignment(name, base, False))
            continue
        offset, spread, samples = found
        out.append(Alignment(name, offset + base, True, spread, samples))
    return out


def link_files(session: Session, parts: Sequence[Part], timeout: float = 1.0) -> list[Link]:
    """Link the Modbus TCP transactions of the network files to the RTU transactions of
    the serial files, in the merged store (times already aligned), and mark the rows."""
    store = session.store
    nets = [p for p in parts if p.network]
    serials = [p for p in parts if not p.network]
    if not nets or not serials:
        return []
    tcp_rows = {r for p in nets for r in p.rows}
    serial_rows = {r for p in serials for r in p.rows}
    sides = transactions(store)
    links = link_sides(
        [s for s in sides if s.request in tcp_rows],
        [s for s in sides if s.request in serial_rows],
        timeout=timeout,
    )
    mark_links(store, links)
    return links


def _ms(x: float | None) -> float | None:
    return None if x is None else round(x * 1000, 3)


def mark_links(store: FrameStore, links: Sequence[Link]) -> None:
    """Put each link on the rows of both sides (`FrameStore.links`): a TCP row's `peer`
    is the serial row on the same leg (request to request, answer to answer), and back;
    `delay_ms` is the gateway's delay on that leg."""
    for x in links:
        verdict = x.verdict.value
        s: Side | None = x.serial
        t = x.tcp
        store.links[t.request] = {
            "peer": None if s is None else s.request,
            "delay_ms": _ms(x.delay_in),
            "verdict": verdict,
            "text": x.text,
        }
        has_serial_answer = s is not None and s.answer != NO_PARTNER
        if t.answer != NO_PARTNER:
            store.links[t.answer] = {
                "peer": s.answer if s is not None and has_serial_answer else None,
                "delay_ms": _ms(x.delay_out),
                "verdict": verdict,
                "text": x.text,
            }
        if s is None:
            continue
        store.links[s.request] = {
            "peer": t.request,
            "delay_ms": _ms(x.delay_in),
            "verdict": verdict,
            "text": x.text,
        }
        if has_serial_answer:
            store.links[s.answer] = {
                "peer": None if t.answer == NO_PARTNER else t.answer,
                "delay_ms": _ms(x.delay_out),
                "verdict": verdict,
                "text": x.text,
            }


def verdict_counts(links: Sequence[Link]) -> Counter[str]:
    return Counter(x.verdict.value for x in links)

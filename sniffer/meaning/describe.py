"""Provides frame details on demand: dissection, register names, problems, one-line summary.

Only rows somebody looks at (a screen, an export) are dissected; results are cached
twice: per row (`Describer.detail`, for the views that show the same rows again) and
per content (`Describer.shared`, for the listings and exports that walk a whole
capture). A polling master sends the same requests all day and slaves often answer
with the same values, so most rows say what an earlier row with the same bytes said:
on the 100k-frame benchmark recording 72% of the rows are found in a cache of 256
contents, 74% with any size. The listings and the export walk the rows with
`Describer.contents`, which also gives answers to a read that differ only in their
values one content where what they write lets it (text, JSONL, Modbus/TCP packets):
97% of the benchmark's rows are found then.
"""

from __future__ import annotations

from collections import OrderedDict, deque
from collections.abc import Container, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from dissectors.dictionary import RegisterValue, Timing
from dissectors.dissect import dissect
from dissectors.functions import function_name
from dissectors.values import Dissection, Field, Problem, Role
from sniffer.framing.pairing import measure
from sniffer.framing.store import NO_PARTNER, FrameStore, FrameView
from sniffer.meaning.annotate import Annotator, surely_over
from sniffer.meaning.problems import frame_problems
from sniffer.text import plain
from sniffer.vocab import BAD_CHECK, FLAG_MEANINGS, STATUS_NAMES, WARNING, Flag, Kind

DIRECTION = {Kind.REQUEST: "M>S", Kind.RESPONSE: "S>M", Kind.EXCEPTION: "S>M"}

# the flags as plain ints: `int & IntFlag` goes through the enum's operators (~1.5 us)
_DEVICE_SLOW = int(Flag.DEVICE_SLOW)
_SILENCE_FRAMED = int(Flag.SILENCE_FRAMED)
_MODE = int(Flag.ASCII | Flag.MBAP)  # what decides a row's body besides its bytes
_KEPT_FLAGS = ~_DEVICE_SLOW  # the slow answer's sentence has the row's latency in it
_ANSWERS = (int(Kind.RESPONSE), int(Kind.EXCEPTION))
_NO_REGISTERS: list[RegisterValue] = []  # never written to
_RESPONSE = int(Kind.RESPONSE)
_REQUEST = int(Kind.REQUEST)
# flags that make a read answer's description depend on its bytes or on more than its
# content: the check's verdict (its sentence has the CRC in it), the other framings, the
# slow answer's latency
VALUED_FLAGS = int(BAD_CHECK | Flag.ASCII | Flag.MBAP | Flag.DEVICE_SLOW | Flag.LINE_EVENT)
_READS = (3, 4)


def _valueless(raw: bytes, asked: bytes) -> bool:
    """Whether `raw`, an RTU answer, and `asked`, its RTU request, are an FC 3 or 4
    read and its well-formed answer as `dissectors.pdu.dissect` reads them straight
    from their bytes (`_words_answer`: the request of the same code with its address
    and quantity whole, a byte count that is the bytes that follow and twice that
    quantity). For a unit with no dictionary (and not followed as SunSpec), such an
    answer's name, summary (`N values`) and problems are those of any other answer to
    that request with as many bytes, the same flags and status: its values decide only
    its dissection's data."""
    size = len(raw)
    return (
        size >= 5
        and raw[1] in _READS
        and len(asked) >= 8
        and asked[1] == raw[1]
        and size == 5 + raw[2]
        and raw[2] == 2 * (asked[4] << 8 | asked[5])
    )


_BIT_READS = (1, 2)
_WRITES = (15, 16)


def _bits_valueless(raw: bytes, asked: bytes) -> int | None:
    """For `raw`, an RTU answer, and `asked`, its RTU request, an FC 1 or 2 read and its
    well-formed answer (a byte count that is the bytes that follow and what the
    quantity needs): the padding bits of its last data byte, which decide its one
    problem that reads values (`dissectors.pdu.access.checked_values`); None for any
    other pair. As for `_valueless`, such answers of a unit with no dictionary differ,
    for the listings, only in their values and those bits."""
    size = len(raw)
    if size < 6 or raw[1] not in _BIT_READS or len(asked) < 8 or asked[1] != raw[1]:
        return None
    quantity = asked[4] << 8 | asked[5]
    if not quantity or size != 5 + raw[2] or raw[2] != (quantity + 7) // 8:
        return None
    used = quantity % 8
    return raw[-3] & (0xFF << used) & 0xFF if used else 0


def _written(raw: bytes, asked: bytes) -> bool:
    """Whether `raw`, an RTU answer, and `asked`, its RTU request, are an FC 15 or 16
    write of a well-formed request (a byte count that is the bytes that follow and what
    the quantity needs) and its 8-byte answer echoing the request's unit, code, address
    and quantity. For a unit with no dictionary (and not followed as SunSpec) such an
    answer's description reads, of its request, only those and the request's byte count
    and length (the values written are the request's own); of an FC 15 request also the
    padding bits after the quantity, which a key holds with them (`_write_key`)."""
    if len(raw) != 8 or raw[1] not in _WRITES or len(asked) < 9 or raw[:6] != asked[:6]:
        return False
    quantity = asked[4] << 8 | asked[5]
    need = (quantity + 7) // 8 if raw[1] == 15 else 2 * quantity
    return len(asked) == 9 + asked[6] and asked[6] == need


def _write_key(asked: bytes) -> tuple[bytes, int, int]:
    """What an FC 15/16 answer's description reads of its request (`_written`): the
    request's head, length and, for FC 15, the padding bits of its last data byte."""
    used = (asked[4] << 8 | asked[5]) % 8
    padding = asked[-3] & (0xFF << used) & 0xFF if asked[1] == 15 and used else 0
    return asked[:7], len(asked), padding


def _write_request(raw: bytes) -> bool:
    """Whether `raw`, an RTU request, is a well-formed FC 15 or 16 write (a byte count
    that is the bytes that follow and what the quantity needs). For a unit with no
    dictionary (and not followed as SunSpec) its name, summary and problems read only its
    head, its length and, for FC 15, the padding bits after the quantity (`_write_key`):
    writes of other values share a content for the listings, which splice each row's
    own values into what they keep (`sniffer.outputs.listing`)."""
    if len(raw) < 9 or raw[1] not in _WRITES:
        return False
    quantity = raw[4] << 8 | raw[5]
    need = (quantity + 7) // 8 if raw[1] == 15 else 2 * quantity
    return len(raw) == 9 + raw[6] and raw[6] == need


_SINGLE_WRITES = (5, 6)
_COIL_STATES = (b"\xff\x00", b"\x00\x00")  # ON, OFF: any other value is a problem


def _single_write(raw: bytes) -> bool:
    """Whether `raw`, an RTU frame, is a well-formed FC 5 or 6 write (request or echo):
    8 bytes and, for FC 5, a coil value of 0xFF00 (ON) or 0x0000 (OFF). For a unit with
    no dictionary (and not followed as SunSpec) its name, summary and problems read only
    its head (unit, code, address) and the value, which is said once in the summary
    (`0x1234`, `ON`): writes of other values share a content for the listings, which
    splice each row's own value into what they keep (`sniffer.outputs.listing`). An
    echo is only such when it is its request's bytes, as its description then reads
    nothing of the request but that they are the same."""
    return len(raw) == 8 and (raw[1] == 6 or raw[4:6] in _COIL_STATES)


def _explained(unit: int, asked_unit: int, bound: Container[int], sunspec: Container[int]) -> bool:
    """Whether an exception of `unit` to a request of `asked_unit` may be explained by
    its request (`Describer._content`: the problems of the request's registers), which
    makes its description depend on more than its content: only where a dictionary or
    SunSpec names the request's registers (a unit with neither has none); a bound unit's
    own exceptions are left out too."""
    return unit in bound or asked_unit in bound or asked_unit in sunspec


_EVENT = int(Kind.EVENT)
_NOISE = int(Kind.NOISE)

SHARED_SIZE = 2048  # contents kept (FIFO); 256 already finds 72% of the benchmark's rows
GUARD_WINDOW = 4096  # lookups between looks at the hit rate
GUARD_MIN_HITS = GUARD_WINDOW // 16  # fewer hits than this in a window: stop caching...
GUARD_PAUSE = 16 * GUARD_WINDOW  # ...for this many rows, then try again


@dataclass(slots=True)
class Shared:
    """What a row's content alone decides (its bytes, kind, flags but the slow answer's,
    status, the unit's annotation and, for an answer, its request's bytes): every part
    of its FrameDetail but the view, the latencies and the slow answer's problem.

    Rows with the same content share one, so what a consumer makes of it once (a JSON
    fragment, a text template, a pcapng block) it can keep in `memo` for the next row
    with that content; keys there are the consumer's (`"jsonl"`, `"text"`, ...)."""

    name: str
    summary: str
    dissection: Dissection | None
    registers: tuple[RegisterValue, ...]
    problems: tuple[Problem, ...]
    label: str
    timed: bool = True  # False: no latency and no slow answer (noise, events, a stub)
    memo: dict[str, Any] = field(default_factory=dict)
    raw: bytes = b""  # the bytes of the row it was made from (`dissection` is theirs)


@dataclass(slots=True)
class _Windowed:
    """The contents of one row content on a unit with parameter windows: by the
    parameters the windows its data covers had selected when the row was sent."""

    windows: tuple[int, ...]
    by_selection: dict[tuple[int | None, ...], Shared]


@dataclass(frozen=True, slots=True)
class FrameDetail:
    """Everything modscope can say about one row."""

    view: FrameView
    name: str  # function name, "noise", or the event
    summary: str  # one line, register names included
    dissection: Dissection | None
    registers: tuple[RegisterValue, ...]
    problems: tuple[Problem, ...]
    latency_ms: float | None  # measured; None when the timing cannot give it
    label: str  # the device label from the bus bindings
    latency_max_ms: float | None = None  # when only a bound is known: at most this

    @property
    def problem_texts(self) -> tuple[str, ...]:
        """The problems as the one-line listing and JSONL `problems` say them."""
        return tuple(p.text for p in self.problems)

    @property
    def direction(self) -> str:
        return DIRECTION.get(self.view.kind, "?")

    @property
    def status(self) -> str:
        return STATUS_NAMES[self.view.status]

    @property
    def fields(self) -> tuple[Field, ...]:
        return self.dissection.fields if self.dissection is not None else ()


def _slow_text(store: FrameStore, i: int, ms: float, timing: Timing | None) -> str:
    """What a slow answer (row `i`, `ms` after its request as measured) is slower than:
    beyond the longest response time only where every time its stamps allow is."""
    if timing is None or timing.response_ms is None:
        return f"answer after {ms:.0f} ms, slower than the device's documented response time"
    text = f"answer after {ms:.0f} ms; the device normally answers within {timing.response_ms:g} ms"
    if timing.long_response_ms is not None:
        if surely_over(store, i, timing.long_response_ms):
            return (
                f"answer after {ms:.0f} ms, beyond the longest response time the device "
                f"documents ({timing.long_response_ms:g} ms)"
            )
        text += f" (long answers up to {timing.long_response_ms:g} ms)"
    return text


def register_span(dissection: Dissection | None, reg: RegisterValue) -> tuple[int, int] | None:
    """Where the words of a named register lie in the body, if the dissection shows it."""
    if dissection is None:
        return None
    for data in dissection.data:
        if data.table != reg.table or data.address is None:
            continue
        first = reg.address - data.address
        count = max(1, len(reg.raw))
        if not 0 <= first < len(data.values):
            continue
        for f in dissection.fields:
            if f.children and len(f.children) == len(data.values):
                last = min(len(f.children), first + count) - 1
                return f.children[first].span[0], f.children[last].span[1]
            if f.name == "value" and len(data.values) == 1:
                return f.span
    return None


class Describer:
    """Details of rows of `store`, dissected when asked for and kept in an LRU cache of
    `size` rows; contents shared by rows with the same bytes are kept too (see
    `shared`), up to `shared_size` of them (0: none)."""

    def __init__(
        self,
        store: FrameStore,
        annotator: Annotator | None = None,
        size: int = 4096,
        shared_size: int = SHARED_SIZE,
    ):
        self.store = store
        self.annotator = annotator or Annotator({})
        self.size = size
        self._cache: OrderedDict[int, FrameDetail] = OrderedDict()
        self.shared_size = shared_size
        self._shared: dict[tuple[object, ...], Shared | _Windowed] = {}
        self._order: deque[tuple[object, ...]] = deque()  # its keys, oldest first
        # contents by all but the register values (see `contents`)
        self._valueless: dict[tuple[object, ...], Shared] = {}
        self._lookups = 0
        self._hits = 0
        self._paused = 0  # rows left before the cache is tried again (see GUARD_*)
        self._fresh: FrameView | None = None  # the view the last `shared` call made

    def forget(self, i: int) -> None:
        self._cache.pop(i, None)

    def detail(self, i: int) -> FrameDetail:
        found = self._cache.get(i)
        if found is not None:
            # pairing may have changed since (a live answer arrived): refresh open rows
            if found.view.status != self.store.status[i]:
                self._cache.pop(i)
            else:
                self._cache.move_to_end(i)
                return found
        made = self._make(i)
        self._cache[i] = made
        if len(self._cache) > self.size:
            self._cache.popitem(last=False)
        return made

    def shared(self, i: int) -> Shared | None:
        """What row `i` shares with every row of the same content (see `Shared`), made
        once per content; None when the row's details depend on more than its content
        (an event or a row with a note, a SunSpec unit the tracker follows, an exception
        its request may explain) or when caching does not pay on this capture (fewer
        than one row in 16 found; looked at again later).

        Keyed by everything that decides the content: the row's bytes, kind, flags
        (but the slow answer's, whose sentence is added per row), status and, for an
        answer, its request's bytes and mode; the unit is in the bytes. A unit whose
        dictionary has parameter windows is decoded with the parameters the windows
        had selected when the row was sent: those are part of the key too."""
        return self._shared_of(i, None)

    def view(self, i: int) -> FrameView:
        """Row `i`'s view: the one `shared(i)` made, if it was just called and had to
        describe the row (a new content's view is not made twice), else a new one."""
        fresh = self._fresh
        if fresh is not None and fresh.index == i:
            self._fresh = None
            return fresh
        return self.store.view(i)

    def contents(
        self, rows: Iterable[int], values: bool = True, writes: bool = False
    ) -> Iterator[tuple[int, Shared | None]]:
        """`(i, shared(i))` for each row `i` of `rows`, in order: the listings' and the
        export's way through many rows. The same contents as `shared`, with what every
        row looks up (the store's columns, the cache, the annotator's units) looked up
        once, and an answer's key made with its request's bytes from the row before
        when that is its request: a row found in the cache then costs a fraction of
        what `shared` spends on it.
        `view(i)` gives the view the row's description was made from, as after
        `shared(i)`.

        Without `values`, a well-formed answer to an FC 3 or 4 read of a unit with no
        dictionary may be given the content of another such answer that differs from it
        only in its values (`_valueless`): its name, summary, problems, label and
        `timed` are the row's own, its `dissection` and `registers` those of the answer
        whose bytes are the content's `raw`. So may the answers to FC 15 and 16 writes
        whose requests differ only in the values written (`_written`): the answer's own
        bytes are in the key, and of the request what its description reads; and the
        answers to FC 1 and 2 reads, as FC 3 and 4's, with their padding bits in the key
        (`_bits_valueless`). For
        consumers that read no value (the text listing) or put the row's own bytes and
        values in (the JSONL listing and the Modbus/TCP export, which splice them into
        what they keep per content). On the
        100k-frame benchmark that leaves 3.3k contents to describe instead of 27k.

        With `writes` too (the listings: the text line shows no value written, the JSONL
        line has the row's own values spliced in), a well-formed FC 15 or 16 write of a
        unit with no dictionary may be given the content of another write of other
        values (`_write_request`): the same head, length, flags, status and, for FC 15,
        padding bits; and a well-formed FC 5 or 6 write, or its echo of the same bytes,
        the content of another of the same unit, code, address, flags and status that
        writes another value (`_single_write`): their text and JSONL lines say the value
        (`write 0x1234 to register ...`, `coil ... ON`), which the listings splice in."""
        if type(self).shared is not Describer.shared or self.shared_size <= 0:
            for i in rows:  # a subclass's own contents (the live window's numbering)
                yield i, self.shared(i)
            return
        store = self.store
        store.sync()
        synced = min(len(store.status), len(store.flags))
        kinds, partners, units, fcs = store.kind, store.partner, store.unit, store.fc
        flags, statuses, notes = store.flags, store.status, store.notes
        streams, offsets, lengths, channels = (
            store.streams,
            store.offset,
            store.length,
            store.channel,
        )
        sunspec = self.annotator.sunspec.units
        bound = self.annotator.bindings
        cache = self._shared
        valueless = self._valueless
        sharing = not values
        last, last_raw = -1, b""  # the row before and its bytes
        for i in rows:
            self._fresh = None
            if self._paused:
                self._paused -= 1
                last = -1
                yield i, None
                continue
            if i >= synced:
                store.sync()
                synced = min(len(store.status), len(store.flags))
            kind = kinds[i]
            if kind == _EVENT or i in notes:
                last = -1
                yield i, None
                continue
            partner = partners[i]
            unit = units[i]
            if kind != _NOISE and (
                unit in sunspec
                or (
                    fcs[i] & 0x80
                    and partner != NO_PARTNER
                    and _explained(unit, units[partner], bound, sunspec)
                )
            ):
                last = -1
                yield i, None
                continue
            at = offsets[i]
            raw = bytes(streams[channels[i]][at : at + lengths[i]])
            flag = flags[i]
            kept = flag & _KEPT_FLAGS
            status = statuses[i]
            asked = None
            if kind in _ANSWERS and partner != NO_PARTNER:
                if partner == last:
                    asked = last_raw
                else:
                    at = offsets[partner]
                    asked = bytes(streams[channels[partner]][at : at + lengths[partner]])
            last, last_raw = i, raw
            self._lookups += 1
            # the shape's key, where rows of other values may share a content (see above):
            # looked up first, the row's own key only when it is not found
            free: tuple[object, ...] | None = None
            if sharing and unit and unit not in bound and not flag & VALUED_FLAGS:
                fc = fcs[i]
                if kind == _REQUEST:
                    if writes:
                        if fc in _SINGLE_WRITES:
                            if _single_write(raw):
                                free = (_REQUEST, kept, status, raw[:4])
                        elif fc in _WRITES and _write_request(raw):
                            free = (_REQUEST, kept, status, *_write_key(raw))
                elif asked is not None and kind == _RESPONSE and not flags[partner] & VALUED_FLAGS:
                    if fc in _SINGLE_WRITES:
                        if writes and raw == asked and _single_write(raw):
                            free = (_RESPONSE, kept, status, raw[:4])
                    elif fc in _READS:
                        if _valueless(raw, asked):
                            free = (raw[:3], len(raw), kept, status, asked)
                    elif fc in _WRITES:
                        if _written(raw, asked):  # the values written are the request's
                            free = (raw, kept, status, *_write_key(asked))
                    elif fc in _BIT_READS:
                        padding = _bits_valueless(raw, asked)
                        if padding is not None:
                            free = (raw[:3], len(raw), kept, status, asked, padding)
                if free is not None:
                    alike = valueless.get(free)
                    if alike is not None:
                        self._hits += 1
                        if self._lookups >= GUARD_WINDOW:
                            self._guard()
                        yield i, alike
                        continue
            if asked is not None:
                key: tuple[object, ...] = (
                    raw,
                    kind,
                    kept,
                    status,
                    asked,
                    flags[partner] & _MODE,
                )
            else:
                key = (raw, kind, kept, status)
            found = cache.get(key)
            if type(found) is Shared:
                self._hits += 1
                if self._lookups >= GUARD_WINDOW:
                    self._guard()
                made = found
            else:
                made = self._found(i, None, key, found, kind, partner, unit, asked)
            if free is not None:
                # four times the contents kept: one-off shapes (writes to addresses
                # written once, as FC 5, 6, 15 and 16 often are) filled a table of
                # `shared_size` and cleared it, the shapes that recur with it; contents
                # described for the listings of 200k frames of mix619758287: 8,576 ->
                # 3,496, mix843779584 7,310 -> 2,443 (docs/performance.md, h-fc56)
                if len(valueless) >= 4 * self.shared_size:
                    valueless.clear()
                valueless[free] = made
            yield i, made

    def _shared_of(self, i: int, view: FrameView | None) -> Shared | None:
        self._fresh = None
        if self.shared_size <= 0:
            return None
        if self._paused:
            self._paused -= 1
            return None
        store = self.store
        if i >= len(store.status) or i >= len(store.flags):
            store.sync()
        kind = store.kind[i]
        if kind == _EVENT or i in store.notes:
            return None
        partner = store.partner[i]
        unit = store.unit[i]
        annotator = self.annotator
        sunspec = annotator.sunspec.units
        if kind != _NOISE and (
            unit in sunspec
            or (
                store.fc[i] & 0x80
                and partner != NO_PARTNER
                and _explained(unit, store.unit[partner], annotator.bindings, sunspec)
            )
        ):
            return None
        streams, offset, length, channel = store.streams, store.offset, store.length, store.channel
        at = offset[i]
        raw = bytes(streams[channel[i]][at : at + length[i]])
        flags = store.flags[i]
        asked = None
        if kind in _ANSWERS and partner != NO_PARTNER:
            at = offset[partner]
            asked = bytes(streams[channel[partner]][at : at + length[partner]])
            key: tuple[object, ...] = (
                raw,
                kind,
                flags & _KEPT_FLAGS,
                store.status[i],
                asked,
                store.flags[partner] & _MODE,
            )
        else:
            key = (raw, kind, flags & _KEPT_FLAGS, store.status[i])
        self._lookups += 1
        found = self._shared.get(key)
        if type(found) is Shared:
            self._hits += 1
            if self._lookups >= GUARD_WINDOW:
                self._guard()
            return found
        return self._found(i, view, key, found, kind, partner, unit, asked)

    def _found(
        self,
        i: int,
        view: FrameView | None,
        key: tuple[object, ...],
        found: Shared | _Windowed | None,
        kind: int,
        partner: int,
        unit: int,
        asked: bytes | None,
    ) -> Shared:
        """The content of row `i` under `key`, looked up and not found as a Shared:
        found for its selection, or described and kept."""
        annotator = self.annotator
        store = self.store
        selection: tuple[int | None, ...] = ()
        if found is not None:
            assert isinstance(found, _Windowed)
            selection = tuple(annotator.selected(unit, n, i) for n in found.windows)
            made = found.by_selection.get(selection)
            if made is not None:
                self._hits += 1
                if self._lookups >= GUARD_WINDOW:
                    self._guard()
                return made
        if view is None:
            view = self._fresh = store.view(i)
        request: bytes | None = None
        if asked is not None and not store.flags[partner] & _MODE:
            request = asked[:-2]  # an RTU request's body, as its view would give it
        made = self._content(view, request)
        if found is not None:
            if len(found.by_selection) < 64:
                found.by_selection[selection] = made
        else:
            windows = annotator.windows_read(unit, made.dissection)
            if windows:
                selection = tuple(annotator.selected(unit, n, i) for n in windows)
                self._keep(key, _Windowed(windows, {selection: made}))
            else:
                self._keep(key, made)
        if self._lookups >= GUARD_WINDOW:
            self._guard()
        return made

    def count_found(self, found: int) -> None:
        """Count `found` rows whose content a consumer found in a table of its own (the
        compiled export's, see PcapExporter) as found here: the hit rate the guard looks
        at is then the whole walk's, not only that of the rows it asked about."""
        if found:
            self._lookups += found
            self._hits += found
            if self._lookups >= GUARD_WINDOW:
                self._guard()

    def _guard(self) -> None:
        """After GUARD_WINDOW lookups: rest the cache if it found too few of them."""
        if self._hits < GUARD_MIN_HITS:
            self._paused = GUARD_PAUSE
            self._shared.clear()
            self._order.clear()
            self._valueless.clear()
        self._lookups = self._hits = 0

    def _keep(self, key: tuple[object, ...], entry: Shared | _Windowed) -> None:
        cache = self._shared
        if len(cache) >= self.shared_size:
            # the oldest: a size cap, cheaper than an LRU; from a queue of the keys, as
            # the dict's first key is found past the slots of the keys dropped before it
            del cache[self._order.popleft()]
        cache[key] = entry
        self._order.append(key)

    def _make(self, i: int) -> FrameDetail:
        view = self.store.view(i)
        shared = self._shared_of(i, view)
        return self.complete(view, shared if shared is not None else self._content(view))

    def complete(self, view: FrameView, content: Shared) -> FrameDetail:
        """The details of row `view.index` from what its content says: the latencies
        and the slow answer's problem added."""
        store = self.store
        i = view.index
        problems = content.problems
        if not content.timed:
            c = content
            return FrameDetail(view, c.name, c.summary, None, (), problems, None, c.label)
        binding = self.annotator.bindings.get(view.unit)
        measured = measure(store, i)
        if view.flags & _DEVICE_SLOW:
            slow = FLAG_MEANINGS[Flag.DEVICE_SLOW]
            text = slow.text
            if measured is not None and not measured.bound and binding is not None:
                text = _slow_text(store, i, measured.seconds * 1000, binding.dictionary.timing)
            problems += (Problem(slow.kind, slow.severity, plain(text), None),)
        return FrameDetail(
            view,
            content.name,
            content.summary,
            content.dissection,
            content.registers,
            problems,
            None if measured is None or measured.bound else measured.seconds * 1000,
            content.label,
            measured.seconds * 1000 if measured is not None and measured.bound else None,
        )

    def _content(self, view: FrameView, request: bytes | None = None) -> Shared:
        """What row `view.index` says apart from its latency and the slow answer (an
        answer's `request` body is looked up unless given)."""
        store = self.store
        annotator = self.annotator
        i = view.index
        unit = view.unit
        kind = view.kind
        note = store.notes.get(i, "")
        problems = frame_problems(view, note)
        label = annotator.label(unit)
        if kind == _EVENT:
            return Shared("event", plain(note), None, (), tuple(problems), "", timed=False)
        if kind == _NOISE:
            summary = f"{len(view.raw)} bytes of noise"
            return Shared("noise", summary, None, (), tuple(problems), "", timed=False)
        body = view.body() if view.flags & _MODE else view.raw[:-2]
        if len(body) < 2:
            text = "frame too short to read"
            return Shared("?", text, None, (), tuple(problems), label, timed=False)
        role = Role.RESPONSE if kind in _ANSWERS else Role.REQUEST
        if request is None and view.partner != NO_PARTNER and role is Role.RESPONSE:
            request = store.view(view.partner).body()
        # the annotator's registry holds the bound devices' own codes: one path for all
        d = dissect(body, role, request=request, registry=annotator.registry)
        registers = (
            annotator.registers(unit, i, d)
            if unit in annotator.bindings or unit in annotator.sunspec.units
            else _NO_REGISTERS  # what `registers` gives for them (0.5 us a new content)
        )
        extra_summary = ""
        name = d.name
        if d.problems:
            problems.extend(d.problems)
        for r in registers:
            span = register_span(d, r) if r.problems or r.partial else None
            problems.extend(Problem("value", WARNING, f"{r.name}: {p}", span) for p in r.problems)
            if r.partial:
                text = f"{r.name}: the read cuts this value in half"
                problems.append(Problem("cut-value", WARNING, text, span))
        if d.exception:
            code = d.field("exception_code")
            if code is not None and isinstance(code.value, int):
                meaning = annotator.exception_meaning(unit, code.value)
                said = d.summary.split(" ", 2)[-1].lower()  # the standard name, said already
                if meaning.lower().startswith(said):
                    meaning = meaning[len(said) :].lstrip(" :;,-")
                if meaning:
                    extra_summary = f"device says: {meaning}"
                if view.partner != NO_PARTNER:
                    # an answer refusing a write the dictionary says is out of range
                    asked = self.detail(view.partner)
                    reasons = [p for r in asked.registers for p in r.problems]
                    if reasons:
                        extra_summary = "; ".join(
                            x
                            for x in (extra_summary, "explained by the request: " + reasons[0])
                            if x
                        )
        summary = d.summary
        if registers:
            summary += ": " + ", ".join(plain(r.text) for r in registers[:6])
            if len(registers) > 6:
                summary += f", ... ({len(registers)} values)"
        elif extra_summary:
            summary += ": " + extra_summary
        if view.flags & _SILENCE_FRAMED and name.startswith(("Unknown", "User", "Reserved")):
            name = function_name(view.function)
        return Shared(
            plain(name),
            plain(summary),
            d,
            tuple(registers),
            tuple(map(_plain_problem, problems)) if problems else (),
            label,
            raw=view.raw,
        )


def _plain_problem(p: Problem) -> Problem:
    text = plain(p.text)
    return p if text is p.text else Problem(p.kind, p.severity, text, p.span)

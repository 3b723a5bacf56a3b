"""Provides frame details on demand: dissection, register names, problems, one-line summary.

Only rows somebody looks at (a screen, an export) are dissected; results are cached.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

from dissectors.dictionary import RegisterValue, Timing
from dissectors.dissect import dissect
from dissectors.functions import function_name
from dissectors.values import Dissection, Field, Problem, Role
from sniffer.annotate import Annotator
from sniffer.pairing import latency, measure
from sniffer.problems import frame_problems
from sniffer.store import NO_PARTNER, FrameStore, FrameView
from sniffer.text import plain
from sniffer.vocab import FLAG_MEANINGS, STATUS_NAMES, WARNING, Flag, Kind

DIRECTION = {Kind.REQUEST: "M>S", Kind.RESPONSE: "S>M", Kind.EXCEPTION: "S>M"}


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


def _slow_text(ms: float, timing: Timing | None) -> str:
    if timing is None or timing.response_ms is None:
        return f"answer after {ms:.0f} ms, slower than the device's documented response time"
    text = f"answer after {ms:.0f} ms; the device normally answers within {timing.response_ms:g} ms"
    if timing.long_response_ms is not None:
        if ms > timing.long_response_ms:
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
    """Details of rows of `store`, dissected when asked for and kept in an LRU cache."""

    def __init__(self, store: FrameStore, annotator: Annotator | None = None, size: int = 4096):
        self.store = store
        self.annotator = annotator or Annotator({})
        self.size = size
        self._cache: OrderedDict[int, FrameDetail] = OrderedDict()

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

    def _make(self, i: int) -> FrameDetail:
        store = self.store
        view = store.view(i)
        note = store.notes.get(i, "")
        problems = frame_problems(view, note)
        label = self.annotator.label(view.unit)
        if view.kind == Kind.EVENT:
            return FrameDetail(view, "event", plain(note), None, (), tuple(problems), None, "")
        if view.kind == Kind.NOISE:
            summary = f"{len(view.raw)} bytes of noise"
            return FrameDetail(view, "noise", summary, None, (), tuple(problems), None, "")
        body = view.body()
        if len(body) < 2:
            return FrameDetail(
                view, "?", "frame too short to read", None, (), tuple(problems), None, label
            )
        role = Role.RESPONSE if view.kind in (Kind.RESPONSE, Kind.EXCEPTION) else Role.REQUEST
        request: bytes | None = None
        if role == Role.RESPONSE and view.partner != NO_PARTNER:
            request = store.view(view.partner).body()
        # the annotator's registry holds the bound devices' own codes: one path for all
        d = dissect(body, role, request=request, registry=self.annotator.registry)
        registers = self.annotator.registers(view.unit, i, d)
        extra_summary = ""
        name = d.name
        binding = self.annotator.bindings.get(view.unit)
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
                meaning = self.annotator.exception_meaning(view.unit, code.value)
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
        lat = latency(store, i)
        measured = measure(store, i)
        if view.flags & Flag.DEVICE_SLOW:
            slow = FLAG_MEANINGS[Flag.DEVICE_SLOW]
            text = slow.text
            if lat is not None and binding is not None:
                text = _slow_text(lat * 1000, binding.dictionary.timing)
            problems.append(Problem(slow.kind, slow.severity, text, None))
        if view.flags & Flag.SILENCE_FRAMED and name.startswith(("Unknown", "User", "Reserved")):
            name = function_name(view.function)
        return FrameDetail(
            view,
            plain(name),
            plain(summary),
            d,
            tuple(registers),
            tuple(Problem(p.kind, p.severity, plain(p.text), p.span) for p in problems),
            None if measured is None or measured.bound else measured.seconds * 1000,
            label,
            measured.seconds * 1000 if measured is not None and measured.bound else None,
        )

"""Provides the register watch: every named register seen, its latest value and its history.

Filled by a pass over the frames of bound units (the only ones with names), a slice
at a time from a worker thread, following the capture as it grows. Memory stays
bounded: at most `MAX_SERIES` registers and `HISTORY` samples each (older samples are
thinned, keeping every other one, so the whole capture stays in view).
"""

from __future__ import annotations

import threading
import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field

from dissectors.dictionary import RegisterValue
from sniffer.framing.store import FrameStore
from sniffer.meaning.annotate import Annotator
from sniffer.meaning.describe import Describer
from sniffer.text import plain
from sniffer.vocab import BAD_CHECK, Kind

HISTORY = 2048
MAX_SERIES = 4096
_ECHO_FUNCTIONS = (5, 6, 15, 16)  # answers that repeat what the request wrote

SeriesKey = tuple[int, str, int, str]  # unit, table, address, name


@dataclass(frozen=True, slots=True)
class Sample:
    t: float
    value: float | None  # numeric value, for plots
    text: str  # the value as shown ("300 V")
    row: int  # the frame that carried it


@dataclass
class Series:
    """One named register of one unit."""

    key: SeriesKey
    name: str
    unit_text: str  # engineering unit ("V")
    label: str  # the device label
    samples: list[Sample] = field(default_factory=list)
    seen: int = 0
    changed: float | None = None  # time the value last changed (None: it never did)
    stride: int = 1  # keep every `stride`-th sample (grows as history is thinned)

    @property
    def latest(self) -> Sample | None:
        return self.samples[-1] if self.samples else None

    def add(self, sample: Sample) -> None:
        last = self.samples[-1] if self.samples else None
        if last is not None and last.text != sample.text:
            self.changed = sample.t
        self.seen += 1
        if self.seen % self.stride and last is not None and last.text == sample.text:
            return  # thinned: an unchanged value between kept samples
        self.samples.append(sample)
        if len(self.samples) > HISTORY:
            self.samples = thin(self.samples)
            self.stride *= 2

    def numbers(self) -> list[tuple[float, float]]:
        return [(s.t, s.value) for s in self.samples if s.value is not None]


def thin(samples: list[Sample]) -> list[Sample]:
    """Half the samples: of each four, the lowest and the highest value (in time order),
    so thinning never loses a spike or a sag (samples without a number: every other)."""
    out: list[Sample] = []
    for k in range(0, len(samples), 4):
        group = samples[k : k + 4]
        numeric = [s for s in group if s.value is not None]
        if len(numeric) < 2:
            out += group[::2]
            continue
        lo = min(numeric, key=lambda s: s.value if s.value is not None else 0.0)
        hi = max(numeric, key=lambda s: s.value if s.value is not None else 0.0)
        out += sorted({id(lo): lo, id(hi): hi}.values(), key=lambda s: s.row)
    return out


def _number(r: RegisterValue) -> float | None:
    v = r.value
    if isinstance(v, bool):
        return float(v)
    if isinstance(v, int | float):
        return float(v)
    return None


def value_text(r: RegisterValue) -> str:
    """The shown value without the name: `300 V` for `Under Voltage Trip = 300 V`."""
    head = r.name + " = "
    text = r.text[len(head) :] if r.text.startswith(head) else r.text
    return plain(text, 120)


class Watch:
    """Named registers seen in a store, filled by `advance(upto)` (any thread)."""

    def __init__(self, store: FrameStore, annotator: Annotator) -> None:
        self.store = store
        self.annotator = annotator
        self.describer = Describer(store, annotator, size=256)
        self.bound = frozenset(annotator.bindings)
        self.series: dict[SeriesKey, Series] = {}
        self.next = 0
        self.lock = threading.Lock()  # held while series change; the UI reads under it
        self.version = 0  # bumped when something changed

    def advance(
        self, upto: int, should_stop: Callable[[], bool] | None = None, budget: float = 0.05
    ) -> bool:
        """Take in rows below `upto` for about `budget` seconds; True if work is left."""
        if not self.bound:
            self.next = upto
            return False
        store = self.store
        kind, unit, fc, flags = store.kind, store.unit, store.fc, store.flags
        deadline = _time.monotonic() + budget
        i = self.next
        bound = self.bound
        while i < upto:
            if should_stop is not None and i % 256 == 0 and should_stop():
                break
            k = kind[i]
            if (
                unit[i] in bound
                and not flags[i] & BAD_CHECK
                and (k == Kind.REQUEST or (k == Kind.RESPONSE and fc[i] not in _ECHO_FUNCTIONS))
            ):
                d = self.describer.detail(i)
                if d.registers:
                    self._take(i, d.view.t, d.view.unit, d.label, d.registers)
            i += 1
            if i % 64 == 0 and _time.monotonic() > deadline:
                break
        self.next = i
        return i < upto

    def _take(
        self, row: int, t: float, unit: int, label: str, regs: tuple[RegisterValue, ...]
    ) -> None:
        with self.lock:
            for r in regs:
                if r.partial:
                    continue
                key: SeriesKey = (unit, r.table, r.address, r.name)
                s = self.series.get(key)
                if s is None:
                    if len(self.series) >= MAX_SERIES:
                        continue
                    s = self.series[key] = Series(key, plain(r.name, 80), plain(r.unit, 16), label)
                s.add(Sample(t, _number(r), value_text(r), row))
            self.version += 1

    def snapshot(self) -> list[Series]:
        """The series sorted by unit, then name (a copy of the list, not of the series)."""
        with self.lock:
            return sorted(self.series.values(), key=lambda s: (s.key[0], s.name.lower()))

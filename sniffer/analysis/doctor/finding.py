"""Provides what the bus doctor finds: `Finding` and `Diagnosis`, the kinds in the order
they are fixed, and the findings as the text `modscope doctor` and the TUI show."""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field

from dissectors.dictionary.model import Timing
from sniffer.text import json_line, plain
from sniffer.vocab import ERROR, INFO, WARNING

# the kinds, in the order a finding of one severity is fixed first: a cause that makes
# other findings meaningless (settings, a second master, a shared address) before its
# symptoms
KINDS = (
    "wrong-line-settings",
    "two-masters",
    "address-conflict",
    "line-overload",
    "errors-follow-station",
    "silent-unit",
    "timing-violation",
    "intermittent-unit",
    "slow-answers",
    "exception-poll",
    "write-effect",
)
RANK = {severity: n for n, severity in enumerate((ERROR, WARNING, INFO))}


@dataclass(frozen=True, slots=True)
class Finding:
    """One diagnosis: what, for whom, how bad, the evidence and what to check next."""

    kind: str
    severity: str
    units: tuple[int, ...]
    summary: str
    meaning: str
    advice: str
    evidence: dict[str, object] = field(default_factory=dict)
    rows: tuple[int, ...] = ()
    excerpt: tuple[str, ...] = ()

    def record(self) -> dict[str, object]:
        """The finding as `--format json` and MQTT give it."""
        out: dict[str, object] = {"kind": self.kind, "severity": self.severity}
        if len(self.units) == 1:
            out["unit"] = self.units[0]
        elif self.units:
            out["units"] = list(self.units)
        evidence = dict(self.evidence)
        evidence["rows"] = list(self.rows)
        evidence["excerpt"] = list(self.excerpt)
        out.update(summary=self.summary, meaning=self.meaning, evidence=evidence)
        out["advice"] = self.advice
        return out


@dataclass(frozen=True, slots=True)
class Diagnosis:
    """What `diagnose` found, ranked, and what the timing allowed it to look at."""

    findings: tuple[Finding, ...]
    notes: tuple[str, ...] = ()

    @property
    def status(self) -> int:
        """The exit status: 1 when any finding is a warning or an error, else 0."""
        return 1 if any(f.severity != INFO for f in self.findings) else 0

    def counts(self) -> Counter[str]:
        return Counter(f.severity for f in self.findings)


def response_bounds(timings: Mapping[int, Timing | None]) -> dict[int, float]:
    """unit -> the response time (s) its dictionary documents, where it documents one."""
    return {
        unit: t.response_ms / 1000
        for unit, t in timings.items()
        if t is not None and t.response_ms is not None
    }


# -- the findings as text ---------------------------------------------------------------

_TAG = {ERROR: "ERROR", WARNING: "WARNING", INFO: "info"}


def report(diagnosis: Diagnosis, title: str, labels: Mapping[int, str] | None = None) -> str:
    """The findings as text: a head line, then each finding ranked, with its meaning on
    site, its evidence and what to check next."""
    findings = diagnosis.findings
    counts = diagnosis.counts()
    title = plain(title, 400)
    if not findings:
        head = f"{title}: no findings: nothing wrong seen on this bus"
    else:
        parts = [f"{counts[s]} {s}{'s' if counts[s] > 1 else ''}" for s in _TAG if counts[s]]
        many = "s" if len(findings) > 1 else ""
        head = f"{title}: {len(findings)} finding{many} ({', '.join(parts)})"
    lines = [head]
    lines += [f"  note: {plain(n)}" for n in diagnosis.notes]
    for n, f in enumerate(findings, 1):
        lines.append("")
        lines += finding_lines(f, n, labels or {})
    return "\n".join(lines) + "\n"


def finding_lines(f: Finding, n: int, labels: Mapping[int, str]) -> list[str]:
    who = ", ".join(f"{u} ({plain(labels[u], 60)})" if u in labels else str(u) for u in f.units)
    target = f" [unit{'s' if len(f.units) > 1 else ''} {who}]" if f.units else ""
    lines = [f"{n}. {_TAG[f.severity]} {f.kind}{target}: {plain(f.summary, 400)}"]
    lines.append(f"   on site: {plain(f.meaning, 400)}")
    facts = [f"{k}={_fact(v)}" for k, v in f.evidence.items() if v is not None and v != []]
    if facts:
        lines.append(f"   evidence: {plain(', '.join(facts), 800)}")
    if f.rows:
        lines.append(f"   rows: {', '.join(str(r) for r in f.rows)}")
    lines += [f"     {plain(x, 200)}" for x in f.excerpt]
    lines.append(f"   check next: {plain(f.advice, 400)}")
    return lines


def _fact(value: object) -> str:
    if isinstance(value, (list, dict)):
        return json_line(value)
    return str(value)

"""Provides `modscope doctor`: a capture read to the end and turned into ranked findings
(`sniffer.analysis.doctor`), as text or JSON, with an exit status a script can act on."""

from __future__ import annotations

import argparse
import json
from collections.abc import Mapping
from pathlib import Path
from typing import TextIO

from sniffer.analysis.doctor import Diagnosis, Finding, diagnose
from sniffer.cli.options import (
    SubParsers,
    add_device_options,
    add_line_options,
    add_network_options,
    bindings_for,
    line_warnings,
    read_options,
)
from sniffer.cli.verdicts import finish_read
from sniffer.errors import UsageError
from sniffer.meaning.annotate import Binding
from sniffer.session.session import open_session
from sniffer.text import json_line, plain
from sniffer.vocab import ERROR, INFO, WARNING


def cmd_doctor(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    path = Path(args.capture)
    if path.is_char_device():
        raise UsageError(
            f"{path}: doctor reads capture files; record the line first "
            f"(`modscope record {path} -o bus.pcapng --duration 60`) and give the recording"
        )
    options = read_options(args)
    bindings = bindings_for(args)
    session, capture = open_session(path, options, bindings=bindings, timeout=args.timeout)
    session.ingest(capture.chunks())
    session.warnings.extend(capture.warnings)
    for w in [*line_warnings(options, capture.info.recorded_line, str(path)), *session.warnings]:
        err.write(f"modscope: warning: {plain(w)}\n")
    if capture.empty:
        return finish_read(capture, session, err)  # (2: nothing could be read)
    diagnosis = diagnose(
        session.store, session.line, session.pipeline.pairer.timeout, response_bounds(bindings)
    )
    if args.format == "json":
        out.write(json.dumps([f.record() for f in diagnosis.findings], indent=2) + "\n")
    else:
        labels = {u: plain(b.label, 60) for u, b in bindings.items()}
        what = f"{session.line.describe()}, mode {session.mode}"
        out.write(report(diagnosis, f"{plain(str(path))} ({plain(what)})", labels))
    return diagnosis.status


def response_bounds(bindings: Mapping[int, Binding]) -> dict[int, float]:
    """unit -> the response time (s) its dictionary documents, where it documents one."""
    out: dict[int, float] = {}
    for unit, b in bindings.items():
        timing = b.dictionary.timing
        if timing is not None and timing.response_ms is not None:
            out[unit] = timing.response_ms / 1000
    return out


_TAG = {ERROR: "ERROR", WARNING: "WARNING", INFO: "info"}


def report(diagnosis: Diagnosis, title: str, labels: Mapping[int, str] | None = None) -> str:
    """The findings as text: a head line, then each finding ranked, with its meaning on
    site, its evidence and what to check next."""
    findings = diagnosis.findings
    counts = diagnosis.counts()
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
    who = ", ".join(f"{u} ({labels[u]})" if u in labels else str(u) for u in f.units)
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


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "doctor",
        help="diagnose a bus from a capture: ranked findings with evidence and advice",
        description=(
            "Read a capture to the end and say what is wrong with the bus: silent and "
            "intermittent units, slow answers, two devices on one address, two masters, "
            "an overloaded line, errors that follow one station, polls that always earn "
            "an exception, wrong line settings, RTU timing violations (exact times only) "
            "and what writes changed. Ranked by what to fix first (docs/doctor.md)."
        ),
        epilog=(
            "exit status:\n"
            "  0  no finding is a warning or an error\n"
            "  1  some finding is a warning or an error\n"
            "  2  the capture cannot be read, or a usage error\n\n"
            "examples:\n"
            "  modscope doctor bus.pcapng\n"
            "  modscope doctor bus.pcapng --format json --bus site.toml\n"
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("capture", metavar="CAPTURE", help="the capture file to diagnose")
    p.add_argument(
        "--format", choices=("text", "json"), default="text", help="text (default) or json"
    )
    add_line_options(p)
    add_network_options(p)
    add_device_options(p)
    p.set_defaults(func=cmd_doctor)

"""The bus doctor on buses built with one known fault each (tests/captures/doctor/, made by
`tests/analysis/test_doctor_bus.py`), on the clean control, and on every capture of the
repository, where a healthy capture must give no warning."""

from __future__ import annotations

from pathlib import Path

import pytest

from sniffer.analysis.doctor import KINDS, Diagnosis, diagnose
from sniffer.session.session import open_session
from sniffer.sources import ReadOptions
from tests.analysis.test_doctor_bus import BUSES

ROOT = Path(__file__).resolve().parents[2]
DOCTOR = ROOT / "tests" / "captures" / "doctor"


def doctor(path: Path, options: ReadOptions) -> Diagnosis:
    session, capture = open_session(path, options, index=False)
    session.ingest(capture.chunks())
    return diagnose(session.store, session.line, session.pipeline.pairer.timeout)


def read_with(extra: tuple[str, ...]) -> ReadOptions:
    parity = extra[extra.index("--parity") + 1] if "--parity" in extra else "E"
    return ReadOptions(baud=19200, parity=parity)


# each capture's fault: the kind, the units it must name, its severity
EXPECTED = {
    "silent-unit": ("silent-unit", (7,), "error"),
    "intermittent-unit": ("intermittent-unit", (2,), "warning"),
    "slow-answers": ("slow-answers", (3,), "warning"),
    "address-conflict": ("address-conflict", (5,), "error"),
    "two-masters": ("two-masters", (1, 3), "error"),
    "line-overload": ("line-overload", (), "warning"),
    "errors-follow-station": ("errors-follow-station", (2,), "warning"),
    "exception-poll": ("exception-poll", (3,), "warning"),
    "wrong-line-settings": ("wrong-line-settings", (), "error"),
    "wrong-baud": ("wrong-line-settings", (), "error"),
    "timing-violation": ("timing-violation", (), "warning"),
    "write-effect": ("write-effect", (1,), "info"),
}


def test_every_kind_has_a_capture() -> None:
    assert {kind for kind, _, _ in EXPECTED.values()} == set(KINDS)
    assert set(BUSES) == {*EXPECTED, "clean"}


@pytest.mark.parametrize("name", sorted(BUSES))
def test_committed_captures_are_what_the_builder_makes(name: str) -> None:
    build, _ = BUSES[name]
    assert (DOCTOR / f"{name}.csv").read_text() == build().csv()


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_each_fault_is_found_on_its_capture_and_nothing_else_is_alarmed(name: str) -> None:
    kind, units, severity = EXPECTED[name]
    found = doctor(DOCTOR / f"{name}.csv", read_with(BUSES[name][1])).findings
    mine = [f for f in found if f.kind == kind and f.units == units]
    assert mine, [(f.kind, f.units) for f in found]
    assert mine[0].severity == severity
    # ranked first, and no other warning or error: one cause, one finding
    assert found[0] is mine[0]
    others = [(f.kind, f.units, f.severity) for f in found if f is not mine[0]]
    assert all(s == "info" for _, _, s in others), others


def test_the_clean_control_gives_no_finding() -> None:
    diagnosis = doctor(DOCTOR / "clean.csv", read_with(()))
    assert diagnosis.findings == ()
    assert diagnosis.status == 0


def test_evidence_is_the_capture_s() -> None:
    found = doctor(DOCTOR / "intermittent-unit.csv", read_with(())).findings[0]
    ev = found.evidence
    # cycles 5 and 20-25 of 40 miss (test_doctor_bus.intermittent_unit)
    assert (ev["polls"], ev["missed"], ev["longest_run"]) == (40, 7, 6)
    assert "6 in a row" in found.summary
    overload = doctor(DOCTOR / "line-overload.csv", read_with(())).findings[0].evidence
    assert isinstance(overload["occupancy"], float) and overload["occupancy"] > 0.9
    period, shortest = overload["fastest_poll_period_s"], overload["shortest_period_allowed_s"]
    assert isinstance(period, float) and isinstance(shortest, float) and shortest <= period
    settings = doctor(DOCTOR / "wrong-line-settings.csv", read_with(("--parity", "N")))
    assert settings.findings[0].evidence["guess"] == "--bytesize 7 --parity E --mode ascii"
    baud = doctor(DOCTOR / "wrong-baud.csv", read_with(())).findings[0].evidence
    # bytes garbled by a UART at twice the line's speed: no setting is guessed from them
    assert baud["guess"] is None
    assert isinstance(baud["line_errors"], int) and baud["line_errors"] > 1000
    write = doctor(DOCTOR / "write-effect.csv", read_with(())).findings[0]
    assert "holding 5: 100 -> 500" in write.summary


def test_record_has_the_interface_fields() -> None:
    found = doctor(DOCTOR / "two-masters.csv", read_with(())).findings
    record = found[0].record()
    assert {"kind", "severity", "summary", "evidence", "advice"} <= set(record)
    assert record["units"] == [1, 3] and "unit" not in record
    evidence = record["evidence"]
    assert isinstance(evidence, dict) and evidence["rows"] and evidence["excerpt"]


SIGROK = {
    "brainchild_io_16do": ReadOptions(baud=19200, parity="E", probes=("1", "0"), invert=True),
    "flowmeter": ReadOptions(baud=9600, parity="N", probes=("RXTX",)),
    "wizmodbus": ReadOptions(baud=9600, parity="N", probes=("RX", "TX")),
}
# the captures with a fault in them on purpose, and what the doctor must say of them
FAULTY = {
    "captures/demo.pcapng": [("error", "silent-unit", (4,)), ("warning", "exception-poll", (3,))],
}


def _sweep() -> list[Path]:
    found = [p for p in (ROOT / "tests" / "captures").rglob("*") if p.is_file()]
    found += [p for p in (ROOT / "captures").iterdir() if p.is_file()]
    return sorted(
        p for p in found if p.suffix not in (".md", ".toml") and p.parent.name != "doctor"
    )


@pytest.mark.parametrize("path", _sweep(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_false_warnings_on_the_repository_captures(path: Path) -> None:
    options = SIGROK.get(path.parent.name, ReadOptions())
    diagnosis = doctor(path, options)
    alarms = [(f.severity, f.kind, f.units) for f in diagnosis.findings if f.severity != "info"]
    assert alarms == FAULTY.get(str(path.relative_to(ROOT)), [])

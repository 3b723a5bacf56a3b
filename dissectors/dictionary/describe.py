"""Provides describe(): a dictionary as plain text, one line per entry, for `dict show`."""

from __future__ import annotations

from collections.abc import Sequence

from .decode import number_text
from .device import DeviceDictionary
from .model import ValueSpec
from .vendor import VendorField


def _limits(spec: ValueSpec) -> str:
    parts: list[str] = []
    if spec.min is not None or spec.max is not None:
        low = number_text(spec.min) if spec.min is not None else ""
        high = number_text(spec.max) if spec.max is not None else ""
        parts.append(f"{low}..{high}")
    if spec.default is not None:
        default = spec.default
        shown = number_text(default) if isinstance(default, (int, float)) else str(default)
        parts.append(f"default {shown}")
    return " ".join(parts)


def _meaning(spec: ValueSpec) -> str:
    if spec.special:
        return "; ".join(f"raw {key}={name}" for key, name in sorted(spec.special.items()))
    if spec.enum:
        return "; ".join(f"{key}={name}" for key, name in sorted(spec.enum.items()))
    if spec.bits:
        return "; ".join(f"bit {key}={name}" for key, name in sorted(spec.bits.items()))
    if spec.sign_bit is not None or spec.flag_bits:
        parts = [f"sign bit {spec.sign_bit}"] if spec.sign_bit is not None else []
        for bit, flag in sorted(spec.flag_bits.items()):
            parts.append(f"bit {bit}: {flag.clear or '-'}/{flag.set or '-'}")
        return "; ".join(parts)
    return ""


def _columns(rows: Sequence[Sequence[str]]) -> list[str]:
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return ["  ".join(cell.ljust(widths[i]) for i, cell in enumerate(row)).rstrip() for row in rows]


def _fields(fields: Sequence[VendorField]) -> str:
    if not fields:
        return "(none)"
    parts = []
    for item in fields:
        size = f"[{item.length}]" if item.length is not None else ""
        parts.append(f"{item.name}: {item.type}{size}")
    return ", ".join(parts)


def describe(d: DeviceDictionary) -> str:
    """Every entry of `d` on one line: table, PDU address, ref, name, type, unit, range, access."""
    lines = [f"{d.model}: {d.name}", f"file: {d.path}"]
    if d.manual:
        lines.append(f"manual: {d.manual}")
    for note in d.notes:
        lines.append(f"note: {note}")
    if d.timing is not None:
        t = d.timing
        parts = []
        if t.response_ms is not None:
            parts.append(f"answers within {number_text(t.response_ms)} ms")
        if t.long_response_ms is not None:
            codes = ", ".join(map(str, t.long_response_functions)) or "some functions"
            parts.append(f"up to {number_text(t.long_response_ms)} ms for FC {codes}")
        if t.quiet_after_write_ms is not None:
            codes = ", ".join(map(str, t.quiet_after_functions)) or "writes"
            parts.append(f"quiet {number_text(t.quiet_after_write_ms)} ms after FC {codes}")
        lines.append("timing: " + "; ".join(parts))
    for space in d.spaces.values():
        default = " (default)" if space.name == d.default_space else ""
        lines.append(
            f"space {space.name}{default}: {space.table}, {space.example()} is PDU {space.pdu}"
        )
    lines.append(f"entries: {len(d.entries)}")
    if d.entries:
        rows = [
            ["table", "pdu", "ref", "name", "type", "unit", "range/default", "access", "values"]
        ]
        ordered = sorted(d.entries, key=lambda e: (e.table, e.address, e.spec.bit or 0))
        for entry in ordered:
            rows.append(
                [
                    entry.table,
                    str(entry.address),
                    entry.ref,
                    entry.name,
                    entry.spec.type_text(),
                    entry.unit,
                    _limits(entry.spec),
                    entry.access,
                    _meaning(entry.spec),
                ]
            )
        lines.extend("  " + row for row in _columns(rows))
    for window in d.windows:
        lines.append(
            f"window: {window.name}: select {window.select_ref} (pdu {window.select}), "
            f"value {window.value_ref} (pdu {window.value}), {len(window.parameters)} parameters"
        )
        if window.parameters:
            rows = [["number", "name", "type", "unit", "range/default", "access", "values"]]
            for number, parameter in sorted(window.parameters.items()):
                spec = parameter.spec
                rows.append(
                    [
                        str(number),
                        parameter.name,
                        spec.type_text(),
                        spec.unit,
                        _limits(spec),
                        spec.access,
                        _meaning(spec),
                    ]
                )
            lines.extend("  " + row for row in _columns(rows))
    for code, function in sorted(d.functions.items()):
        broadcast = " (broadcast)" if function.broadcast else ""
        lines.append(
            f"function 0x{code:02X} ({code}) {function.name}{broadcast}: "
            f"request {_fields(function.request)}; response {_fields(function.response)}"
        )
    if d.report_server_id is not None:
        lines.append(f"report server id: {_fields(d.report_server_id.fields)}")
    for code, meaning in sorted(d.exceptions.items()):
        lines.append(f"exception {code}: {meaning}")
    return "\n".join(lines)

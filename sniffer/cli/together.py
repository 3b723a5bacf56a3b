"""Provides `modscope replay FILE FILE...`: several captures replayed together, merged by
time, and both sides of a gateway linked (see `sniffer.session.multifile`)."""

from __future__ import annotations

import argparse
import sys
from contextlib import ExitStack
from pathlib import Path
from typing import TextIO

from sniffer.analysis.gateway_report import gateway_table, server_table
from sniffer.cli.filtering import query_of
from sniffer.cli.metrics import finish_metrics, open_metrics
from sniffer.cli.options import bindings_for, read_options
from sniffer.cli.replaying import stdin_copy, write_listing
from sniffer.cli.verdicts import finish_read
from sniffer.errors import UsageError
from sniffer.meaning.annotate import Binding
from sniffer.meaning.query import Query
from sniffer.outputs.metrics import Metrics
from sniffer.session.multifile import align, link_files, merge
from sniffer.session.session import open_session
from sniffer.session.verdict import ALL_READ, READ_WITH_WARNINGS
from sniffer.sources import ReadOptions
from sniffer.text import plain


def parse_offsets(texts: list[str], files: list[str]) -> dict[str, float]:
    """`--offset FILE=SECONDS` options keyed by the file as given; FILE may be the path
    as given or its name alone."""
    out: dict[str, float] = {}
    for text in texts:
        name, sep, value = text.rpartition("=")
        if not sep or not name:
            raise UsageError(f"--offset {text!r}: write FILE=SECONDS, e.g. serial.pcapng=-3.2")
        try:
            seconds = float(value)
        except ValueError:
            raise UsageError(f"--offset {text!r}: {value!r} is not a number of seconds") from None
        match = [f for f in files if f == name] or [f for f in files if Path(f).name == name]
        if len(match) != 1:
            raise UsageError(
                f"--offset {text!r}: {name!r} is not one of the files given ({', '.join(files)})"
                if not match
                else f"--offset {text!r}: {name!r} names several files; give its path"
            )
        out[match[0]] = seconds
    return out


def replay_together(
    args: argparse.Namespace, files: list[str], out: TextIO, err: TextIO, *, tui: bool = False
) -> int:
    """`replay FILE FILE...` (and `tui FILE FILE...`, `tui` set: the TUI whatever stdout is)."""
    if files.count("-") > 1:
        raise UsageError("standard input (-) can be given once")
    if args.timeout is not None and not args.timeout > 0:
        raise UsageError(f"--timeout must be a positive number of seconds, not {args.timeout:g}")
    if not args.gateway_timeout > 0:
        raise UsageError(
            f"--gateway-timeout must be a positive number of seconds, not {args.gateway_timeout:g}"
        )
    given = parse_offsets(args.offset, files)
    query = query_of(args, err)
    bindings = bindings_for(args)
    options = read_options(args)
    if getattr(args, "mqtt", None):
        raise UsageError("--mqtt takes one capture; replay the files one at a time")
    metrics = open_metrics(args, err, several=True)  # a `bus` label: each file's name
    try:
        status = _together(args, files, out, err, given, query, bindings, options, metrics, tui)
    except BaseException:
        if metrics is not None:
            metrics.close()
        raise
    finish_metrics(metrics, getattr(args, "metrics_hold", 0.0))
    return status


def _together(
    args: argparse.Namespace,
    files: list[str],
    out: TextIO,
    err: TextIO,
    given: dict[str, float],
    query: Query | None,
    bindings: dict[int, Binding],
    options: ReadOptions,
    metrics: Metrics | None,
    tui: bool,
) -> int:
    with ExitStack() as stack:
        paths = []
        for f in files:
            if f == "-":
                paths.append(stack.enter_context(stdin_copy()))
            else:
                paths.append(Path(f))
        sessions = []
        statuses = []  # each file's verdict, as replay of it alone would give it
        for f, path in zip(files, paths, strict=True):
            if f != "-" and not path.exists():
                raise UsageError(f"{f}: no such file")
            session, capture = open_session(path, options, bindings=bindings, timeout=args.timeout)
            shown = "standard input" if f == "-" else f
            if metrics is not None:
                metrics.watch(shown, session, bindings)
                session.ingest(capture.chunks(), lambda done, rows: metrics.update())
            else:
                session.ingest(capture.chunks())
            session.warnings.extend(capture.warnings)
            for note in [*capture.info.notes, *session.notes]:
                err.write(f"modscope: note: {plain(shown)}: {plain(note)}\n")
            for w in session.warnings:
                err.write(f"modscope: warning: {plain(w)}\n")
            statuses.append(finish_read(capture, session, err))
            sessions.append(session)
    alignments = align(files, sessions, given)
    for a in alignments:
        if a.estimated or a.name in given:
            err.write(f"modscope: note: {plain(a.text())}\n")
    merged, parts, warnings = merge(files, sessions, [a.offset for a in alignments])
    for w in warnings:
        err.write(f"modscope: warning: {plain(w)}\n")
    links = link_files(merged, parts, timeout=args.gateway_timeout)
    if any(p.network for p in parts) and any(not p.network for p in parts):
        unaligned = [a.name for a in alignments if not a.estimated and a.name not in given]
        serial_unaligned = [n for n, p in zip(files, parts, strict=True) if not p.network]
        if set(serial_unaligned) & set(unaligned):
            err.write(
                "modscope: warning: no transaction matched on both sides to align the "
                "clocks; the files are merged as their clocks say (give --offset "
                "FILE=SECONDS)\n"
            )
    status = max([*statuses, READ_WITH_WARNINGS if warnings else ALL_READ])
    use_tui = tui or (
        args.format is None
        and not args.stats
        and query is None
        and args.count is None
        and out.isatty()
        and sys.stdin.isatty()
        and "-" not in files
    )
    if use_tui:
        from sniffer.tui.app import run_tui  # here: only the commands that open it load Textual

        return run_tui(merged)
    if args.stats:
        labels = {u: plain(b.label) for u, b in bindings.items()}
        for part in parts:
            what = "network" if part.network else part.session.line.describe()
            out.write(
                f"file {plain(part.name)}: {what}, {len(part.rows)} rows, channels from "
                f"{part.channel_base}, clock {part.offset:+.6f} s\n"
            )
        out.write("\n" + merged.stats.table(labels) + "\n")
        servers = server_table(merged.store)
        if servers:
            out.write("\n" + servers + "\n")
        if links:
            out.write("\n" + gateway_table(links) + "\n")
        return status
    write_listing(out, args, merged, query)
    return status

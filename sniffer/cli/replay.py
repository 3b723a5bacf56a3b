"""Provides `modscope replay`: a capture file framed, paired and decoded, as a listing,
statistics or the TUI."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TextIO

from sniffer.analysis.baud import SpeedCheck, wrong_speed
from sniffer.analysis.gateway_report import ServerCounts
from sniffer.analysis.pollcycle import PollCycles, cycle_table
from sniffer.cli.filtering import add_filter_options, query_of
from sniffer.cli.heap import settle
from sniffer.cli.metrics import add_metrics_options, finish_metrics, open_metrics, reading_with
from sniffer.cli.options import (
    READ_EPILOG,
    SubParsers,
    add_device_options,
    add_index_option,
    add_jobs_option,
    add_line_options,
    add_network_options,
    add_output_options,
    bindings_for,
    line_warnings,
    read_options,
)
from sniffer.cli.progress import Progress
from sniffer.cli.replaying import first_pass, stdin_copy, write_streamed
from sniffer.cli.together import replay_together
from sniffer.cli.verdicts import finish_read
from sniffer.errors import UsageError
from sniffer.meaning.annotate import Binding
from sniffer.outputs.metrics import Metrics
from sniffer.outputs.mqtt.command import add_mqtt_options, cmd_replay_mqtt
from sniffer.session.index import DamagedError
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, open_session
from sniffer.session.streamed import Learnt
from sniffer.sources import Capture, ReadOptions
from sniffer.sources.net import summary as net_summary
from sniffer.text import plain


def cmd_replay(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    files: list[str] = list(args.file or [])
    if args.read is not None:
        if files:
            raise UsageError("give the capture once: as FILE or as -r FILE")
        files = [args.read]
    if len(files) > 1:
        return replay_together(args, files, out, err)
    if args.offset:
        raise UsageError("--offset is for several files replayed together; give two files")
    args.file = files[0] if files else None
    if args.file == "-":
        with stdin_copy() as path:
            args.file = str(path)
            return _replay(args, out, err, "standard input")
    return _replay(args, out, err, None)


def _replay(args: argparse.Namespace, out: TextIO, err: TextIO, shown: str | None) -> int:
    query = query_of(args, err)
    path = Path(args.file) if args.file else DEMO_CAPTURE
    bindings = bindings_for(args, DEMO_BUS if not args.file else None)
    if not args.file and not DEMO_CAPTURE.exists():
        raise UsageError(f"the demo capture {DEMO_CAPTURE} is missing; give a capture FILE")
    options = read_options(args)
    use_tui = (
        args.format is None
        and not args.stats
        and query is None
        and args.count is None
        and shown is None
        and out.isatty()
        and sys.stdin.isatty()
    )
    session, capture = open_session(
        path,
        options,
        bindings=bindings,
        timeout=args.timeout,
        index=not args.no_index,
        interactive=use_tui,
    )
    told = line_warnings(options, capture.info.recorded_line, str(path))
    if use_tui and getattr(args, "metrics", None):
        raise UsageError(
            "--metrics serves what a listing or --stats reads: add --format or --stats"
        )
    metrics = open_metrics(args, err)
    if metrics is not None:
        metrics.watch(path.name, session, bindings)
    try:
        status = _read(
            args, out, err, shown, path, bindings, session, capture, told, metrics, use_tui
        )
    except BaseException:
        if metrics is not None:
            metrics.close()
        raise
    finish_metrics(metrics, args.metrics_hold)  # the totals, served a while longer if asked
    return status


def _read(
    args: argparse.Namespace,
    out: TextIO,
    err: TextIO,
    shown: str | None,
    path: Path,
    bindings: dict[int, Binding],
    session: Session,
    capture: Capture,
    told: list[str],
    metrics: Metrics | None,
    use_tui: bool,
) -> int:
    query = query_of(args)
    options = read_options(args)
    published = bool(getattr(args, "mqtt", None))
    if use_tui and not published:
        from sniffer.tui.app import run_tui  # here: only the commands that open it load Textual

        def reopen() -> tuple[Session, Capture]:
            return open_session(
                path, options, bindings=bindings, timeout=args.timeout, interactive=True
            )

        return run_tui(session, capture, reopen=reopen)
    progress = Progress(err, shown or path.name, None if shown else path)
    reading = reading_with(metrics, progress.reading)  # (the metrics' figures taken too)
    settle()
    counted: Counted | None = None  # what --stats counts of every row, a segment at a time
    speed: SpeedCheck | None = None  # the line-speed check of every row
    learnt: Learnt | None = None  # a listing's first pass (see sniffer.session.streamed)
    publish_status = 0  # --mqtt: 1 where messages never reached the broker

    def anew(index: bool) -> tuple[Session, Capture]:
        opened = open_session(path, options, bindings=bindings, timeout=args.timeout, index=index)
        if metrics is not None:
            metrics.rewatch(path.name, opened[0])
        return opened

    if published:
        # --mqtt publishes every row as it is read, then drops it (a window of rows, as
        # --stats alone): the statistics and the poll cycle asked for alongside are
        # counted a segment at a time; a listing asked for alongside (--format) reads
        # the capture again, in the two passes of a listing alone
        counted = Counted()
        publish_status = cmd_replay_mqtt(
            args, session, capture, bindings, path.name, err, window=REPLAY_WINDOW, segment=counted
        )
        speed = counted.speed
        if args.format and not args.stats:
            session, capture = anew(not args.no_index)
            session, capture, learnt = first_pass(
                session, capture, reading, anew, not args.no_index
            )
            speed = learnt.speed
    elif args.stats:
        # nothing needs every row at the end: the rows go a segment at a time
        try:
            counted = _windowed(session, capture, reading)
        except DamagedError:  # a sidecar damaged after rows of it were counted
            session, capture = open_session(
                path, options, bindings=bindings, timeout=args.timeout, index=not args.no_index
            )  # (the damaged sidecar is not read again: indexed, and written anew)
            if metrics is not None:
                metrics.rewatch(path.name, session)
            counted = _windowed(session, capture, reading)
        speed = counted.speed
    else:
        # a listing: a first pass keeping a window of rows, then the rows listed a
        # segment at a time by a second one
        session, capture, learnt = first_pass(session, capture, reading, anew, not args.no_index)
        speed = learnt.speed
    progress.done()
    session.warnings.extend(capture.warnings)
    slow = None
    if not capture.info.network:
        slow = wrong_speed(session.store) if speed is None else speed.warning()
    if slow is not None:
        session.warnings.append(f"{shown or path}: {slow}")
    unused = _network_line_note(options, str(shown or path)) if capture.info.network else []
    for note in [*capture.info.notes, *session.notes, *unused]:
        err.write(f"modscope: note: {plain(note)}\n")
    for w in [*told, *session.warnings]:
        err.write(f"modscope: warning: {plain(w)}\n")
    # (1 too where messages never reached the broker: `cmd_replay_mqtt`)
    status = max(finish_read(capture, session, err), publish_status)
    if args.stats:
        labels = {u: plain(b.label) for u, b in bindings.items()}
        # a network capture has no serial line: say what it carries instead
        what = (
            net_summary(capture.info.channels)
            if capture.info.network
            else f"{session.line.describe()}, mode {session.mode}"
        )
        out.write(f"{plain(str(shown or path))} ({plain(what)})\n")
        out.write(session.stats.table(labels) + "\n\n")
        assert counted is not None  # (--stats counts every row a segment at a time: above)
        table = counted.servers.text()
        if table:
            out.write(table + "\n\n")
        found = counted.cycles.cycles()
        out.write(cycle_table(found, labels, counted.first or 0.0) + "\n")
        return status
    if learnt is not None:  # (--mqtt without --format lists nothing)
        second = open_session(
            path, options, bindings=bindings, timeout=args.timeout, index=learnt.indexed
        )
        write_streamed(out, args, learnt, second, query)
    return status


def _network_line_note(options: ReadOptions, name: str) -> list[str]:
    """Serial line flags mean nothing to TCP or UDP payloads: say so rather than seem to
    apply them."""
    given = [
        flag
        for flag, value in (
            ("--baud", options.baud),
            ("--bytesize", options.bytesize),
            ("--parity", options.parity),
            ("--stopbits", options.stopbits),
        )
        if value is not None
    ]
    if not given:
        return []
    return [
        f"{name}: a network capture: {', '.join(given)} not used for TCP or UDP payloads "
        "(times are packet times; no serial line speed applies to them)"
    ]


# rows a replay keeps in memory when nothing needs them all at the end (`--stats`): about
# 4 MB of store (65 bytes a row), whatever the size of the capture; a larger window
# holds more memory and saves no work
REPLAY_WINDOW = 1 << 16


class Counted:
    """What `--stats` counts of every row, a segment at a time (`segment` of
    `Session.ingest`): the poll cycle, the baud check, the network server table, the
    first row's time."""

    def __init__(self) -> None:
        self.cycles = PollCycles()
        self.speed = SpeedCheck()
        self.servers = ServerCounts()
        self.first: float | None = None

    def __call__(self, s: Session) -> None:
        if self.first is None and len(s.store):
            self.first = s.store.t[0]
        self.cycles.add(s.store)
        self.speed.add(s.store)
        self.servers.add(s.store)


def _windowed(session: Session, capture: Capture, reading: Callable[[int, int], None]) -> Counted:
    """Ingest the capture keeping a window of rows (`Session.ingest`): the poll cycle, the
    baud check and the network server table count each segment before it goes, the
    statistics carry on, bounded (their values kept on disk for a sidecar being written:
    `index.Spill`), the sidecar index is written (or read) a segment at a time. A
    segment ends only where no request waits for an answer (`Session.settled`)."""
    counted = Counted()
    # the statistics bounded, a sidecar being written given their values on disk
    session.ingest(capture.chunks(), reading, window=REPLAY_WINDOW, segment=counted, bounded=True)
    return counted


REPLAY_EXAMPLES = """\
examples:
  modscope replay site.pcapng --format jsonl      one JSON object per frame
  modscope replay eth.pcap --port 502 --stats      Modbus TCP, statistics per server
  modscope replay nport.pcap --carrier rtu-over-tcp --port 4001
  tcpdump -i eth0 -U -w - -c 5000 'tcp port 502' | modscope replay - --format text
  modscope replay tcp.pcap serial.pcapng --stats   both sides of a gateway, linked
  modscope replay tcp.pcap serial.pcapng --offset serial.pcapng=-3.25

"""


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "replay",
        help="frame, pair and decode a capture file (the bundled demo without FILE)",
        description=(
            "Read a capture (pcap/pcapng, sigrok .sr, socat -x or hexdump text, raw bytes; "
            "recognised from its content) and show every frame: in the TUI on a terminal, "
            "as a listing with --format or when piped. Line settings: the flags, else what "
            "the capture recorded, else 19200 8E1 (a flag that contradicts the file is "
            "used, with a warning)."
        ),
        epilog=REPLAY_EXAMPLES + READ_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "file",
        nargs="*",
        help="capture file, - for standard input (default: the bundled demo); several files "
        "replay together, merged by time (e.g. both sides of a gateway: TCP.pcap SERIAL.pcapng)",
    )
    p.add_argument("-r", "--read", metavar="FILE", help="the capture file (as tcpdump -r)")
    add_line_options(p)
    add_network_options(p)
    add_index_option(p)
    g = p.add_argument_group("logic analyser captures (.sr)")
    g.add_argument(
        "--probe",
        action="append",
        metavar="NAME|N",
        help="probe carrying UART data; give it twice for one probe per direction "
        "(requests first, then responses)",
    )
    g.add_argument("--invert", action="store_true", help="idle-low levels (RS-232 side)")
    add_device_options(p)
    add_output_options(p)
    add_jobs_option(p)
    add_filter_options(p)
    p.add_argument(
        "--stats", action="store_true", help="print the per-unit statistics and poll cycle"
    )
    g = p.add_argument_group("several files (both sides of a gateway)")
    g.add_argument(
        "--offset",
        action="append",
        default=[],
        metavar="FILE=SECONDS",
        help="add SECONDS to FILE's times to put its clock on the others' (repeatable; "
        "default: estimated from transactions seen on both sides, and shown)",
    )
    g.add_argument(
        "--gateway-timeout",
        type=float,
        default=1.0,
        metavar="S",
        help="longest a gateway takes to put a TCP request on the serial line (default 1 s)",
    )
    add_mqtt_options(p, replay=True)
    add_metrics_options(p, replay=True)
    p.set_defaults(func=cmd_replay)

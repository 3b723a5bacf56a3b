"""Provides `modscope live`: watch serial lines as they run, in the TUI or as a listing
flushed per row, optionally recording (-w) and streaming to Wireshark (--pcap)."""

from __future__ import annotations

import argparse
import gc
import importlib
import importlib.util
import io
import os
import sys
import time
from collections.abc import Sequence
from typing import TextIO

from sniffer.analysis.liveness import Heard, liveness, liveness_lines
from sniffer.analysis.pollcycle import PollCycles, cycle_table, poll_cycles
from sniffer.cli.backlog import BACKLOG_BYTES, Backlog
from sniffer.cli.filtering import Selection, add_filter_options, query_of
from sniffer.cli.lines import (
    add_port_options,
    add_recording_options,
    announce,
    check_reader,
    duration_option,
    notifier,
    open_reader,
    open_recorder,
    port_specs,
    queue_option,
    quiet_stdout,
    ring_options,
    stop_requests,
)
from sniffer.cli.metrics import add_metrics_options, live_outputs, open_metrics
from sniffer.cli.options import SubParsers, add_device_options, add_output_options, bindings_for
from sniffer.cli.scan import AUTO, accept_auto_baud, scan_for_live
from sniffer.errors import UsageError
from sniffer.framing.pipeline import LIVE_MERGE_SLACK
from sniffer.live.engine import (
    PUMP_GATHER,
    PUMP_SECONDS,
    WINDOW_ROWS,
    GlobalRows,
    LiveCapture,
    Notify,
    Reader,
)
from sniffer.live.recorder import parse_size
from sniffer.meaning.select import FilterJob
from sniffer.outputs.export import PcapExporter
from sniffer.outputs.listing import Lister
from sniffer.outputs.mqtt.command import (
    MQTT_QUIET,
    add_mqtt_options,
    live_publisher,
    mqtt_session,
    mqtt_source,
    published_bindings,
)
from sniffer.session.session import Session
from sniffer.vocab import Status

RENDER_ROWS = 256  # rows rendered between two looks at the output and at Ctrl-C
STOP_GRACE = 0.5  # seconds the last rows get to reach the output after a stop


def cmd_live(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    source = mqtt_source(args, notifier(err))  # a bus another modscope publishes
    if source is None and args.baud == AUTO:
        scan_for_live(args, err)  # the line's settings into args, before anything opens
    specs = list(source.specs) if source is not None else port_specs(args)
    ring = ring_options(args)
    deadline = duration_option(args)
    queue = queue_option(args)
    if args.write == "-":
        raise UsageError("live writes its listing to standard output; record with -w FILE")
    if args.pcap == "-" and args.format is not None:
        raise UsageError("--pcap - takes standard output for itself; drop --format")
    if args.pcap and args.write and os.path.abspath(args.pcap) == os.path.abspath(args.write):
        raise UsageError("--pcap and -w name the same file; give each its own")
    bindings = (
        published_bindings(bindings_for(args), source, notifier(err))
        if source is not None
        else bindings_for(args)
    )
    session = (
        mqtt_session(source, bindings, args.timeout)
        if source is not None
        else Session(
            specs[0].line,
            bindings=bindings,
            timeout=args.timeout,
            source=", ".join(s.name for s in specs),
            merge_slack=LIVE_MERGE_SLACK,
        )
    )
    use_tui = (
        args.format is None
        and args.pcap is None
        and out.isatty()
        and sys.stdin.isatty()
        and _tui_available()
    )
    reader: Reader = source if source is not None else open_reader(specs, err)
    notify = notifier(err)

    def tell(text: str) -> None:  # the publisher's news: in the TUI, or on stderr
        if use_tui:
            capture.messages.append(text)
        else:
            notify(text)

    try:
        recorder = open_recorder(args, specs, ring)
    except BaseException:
        reader.stop()
        raise
    metrics = None
    try:
        metrics = open_metrics(args, err)
        publisher = live_publisher(args, session, bindings, specs, reader.clock.now, tell, err)
    except BaseException:
        reader.stop()
        if recorder is not None:
            recorder.close(reader.clock.now())
        if metrics is not None:
            metrics.close()
        raise
    if metrics is not None:
        metrics.watch(
            session.source,
            session,
            bindings,
            clock=reader.clock.now,
            lost=lambda: capture.lost_bytes,
        )
    capture = LiveCapture(
        reader,
        session,
        recorder=recorder,
        queue_size=queue,
        notify=None if use_tui else notify,
        quiet=MQTT_QUIET if source is not None else None,
        publisher=live_outputs(publisher, metrics),  # (the metrics taken after each pump)
        # headless, rows listed and settled are let go (the TUI scrolls back through all)
        window=None if use_tui else WINDOW_ROWS,
        gather=0.0 if use_tui else PUMP_GATHER,
    )
    exporter: PcapExporter | None = None
    pcap_file = None
    try:
        if args.pcap:
            try:
                pcap_file = sys.stdout.buffer if args.pcap == "-" else open(args.pcap, "wb")  # noqa: SIM115
            except OSError as exc:
                raise UsageError(
                    f"{args.pcap}: cannot be written ({exc.strerror or exc}); choose a "
                    "folder you can write to"
                ) from None
            exporter = PcapExporter(
                pcap_file, GlobalRows(session), specs[0].line, name=specs[0].name
            )
        capture.start()
        if use_tui:
            # what the ports said while opening shows in the TUI, not behind it
            capture.messages.extend(f"warning: {w}" for w in reader.warnings)
            from sniffer.tui.app import run_tui

            return run_tui(session, None, live=capture)
        # what start-up built (modules, schemas, dictionaries) lives as long as the
        # capture: frozen, the collector's full passes walk only what the capture made
        # since, which keeps their pauses out of the listing's latency (see
        # docs/performance.md, "Live")
        gc.collect()
        gc.freeze()
        announce(err, "listening on", specs, recorder)
        lister = None
        if args.pcap != "-":
            lister = Lister(
                io.StringIO(),
                args.format or "text",
                GlobalRows(session),
                absolute=args.time == "abs",
                raw_csv=args.raw_csv,
                updates=True,  # text: the rows its updates cite are numbered
            )
        backlog = None if lister is None else Backlog(out, args.backlog)
        selection = Selection(session, query_of(args, err), args.count)
        if lister is not None and selection.query is not None:
            lister.origin = None  # counted from the first row listed, as without a filter
        labels = {u: b.label for u, b in bindings.items()}
        every = args.stats if args.stats and args.stats > 0 else None
        return stream(
            capture,
            lister,
            exporter,
            deadline,
            backlog,
            notify,
            selection,
            Summary(session, err, labels, every, capture if args.stats is not None else None),
        )
    finally:
        capture.stop()
        if metrics is not None:
            metrics.close()
        if pcap_file is not None and pcap_file is not sys.stdout.buffer:
            pcap_file.close()


def parse_backlog(text: str) -> int:
    """--backlog SIZE (hidden; tests use it): listing bytes held for a slow reader."""
    try:
        return parse_size(text, minimum=1)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _tui_available() -> bool:
    try:
        return importlib.util.find_spec("sniffer.tui.app") is not None
    except ModuleNotFoundError:
        return False


class Summary:
    """The --stats table, poll cycle and liveness lines on standard error: every `every`
    seconds while capturing, and once when the capture ends."""

    def __init__(
        self,
        session: Session,
        err: TextIO,
        labels: dict[int, str],
        every: float | None,
        whole: LiveCapture | None = None,
    ) -> None:
        """`whole`: the poll cycle covers the whole capture, not only the rows of its
        window still in memory: the requests of each segment are counted before it goes
        (8 bytes each: asked for with --stats); the liveness lines measure the ages to
        its clock (`LiveCapture.now`), so they grow while no frame comes."""
        self.cycles: PollCycles | None = None
        self.capture = whole
        self.heard = Heard()  # the newest frame and answers, over every segment
        if whole is not None:
            cycles = self.cycles = PollCycles()
            heard = self.heard

            def segment(s: Session) -> None:
                cycles.add(s.store)
                heard.update(s.store)

            whole.segment = segment
        self.session = session
        self.err = err
        self.labels = labels
        self.every = every
        self.next = time.monotonic() + every if every else None

    def tick(self) -> None:
        if self.capture is not None:
            self.heard.update(self.session.store)
        if self.next is not None and time.monotonic() >= self.next:
            assert self.every is not None
            self.next = time.monotonic() + self.every
            self.write()

    def write(self) -> None:
        session = self.session
        session.store.sync()
        session.stats.update()
        self.err.write(f"\n{session.source} ({session.line.describe()})\n")
        self.err.write(session.stats.table(self.labels) + "\n")
        found = (
            poll_cycles(session.store) if self.cycles is None else self.cycles.cycles(session.store)
        )
        self.err.write(cycle_table(found, self.labels) + "\n")
        heard = self.heard
        heard.update(session.store)
        # live, the ages run to the port's clock; without one (no --stats: its rows were
        # not followed), to the newest frame, and the line is not judged
        clock = self.capture
        now = clock.now() if clock is not None else (heard.last_frame or 0.0)
        alive = liveness(
            list(session.stats.units.values()),
            heard.last_answer,
            now,
            session.store.resolution,
            last_frame=heard.last_frame,
            ended=clock is None,
        )
        self.err.write("\n".join(liveness_lines(alive, self.labels)) + "\n")
        self.err.flush()


def stream(
    capture: LiveCapture,
    lister: Lister | None,
    exporter: PcapExporter | None,
    duration: float | None,
    backlog: Backlog | None = None,
    notify: Notify | None = None,
    selection: Selection | None = None,
    summary: Summary | None = None,
) -> int:
    """The listing loop: rows out as they are framed, until stopped (Ctrl-C, --duration,
    -c N frames listed, or the port gone for good); then the summary. The listing goes
    through `backlog` (see `sniffer.cli.backlog`): a slow reader of the output never
    stops the capture, rows it cannot take are dropped and reported, and Ctrl-C ends
    the loop within about a second whatever the output does."""
    end = None if duration is None else time.monotonic() + duration
    session = capture.session
    assert session is not None
    # rows by their number in the whole capture: the capture may start a new segment of
    # its session now and then (LiveCapture's window), numbering rows on from
    # `session.base`; the lister and the exporter read them through GlobalRows
    base = session.base
    waiting: list[int] = []  # requests listed while open: each gets one update record
    sink = io.StringIO()
    if lister is not None:
        if not isinstance(lister.out, io.StringIO):
            raise TypeError("the live lister renders into a StringIO; the backlog writes it")
        sink = lister.out
        backlog = backlog or Backlog(sys.stdout)
        backlog.add(sink.getvalue())  # a CSV header
        sink.seek(0)
        sink.truncate()
    said = 0
    last_said = 0.0

    def emit(rows: range, deadline: float | None = None, final: bool = False) -> None:
        nonlocal waiting, said, last_said, base
        if session.base != base:  # a new segment: its rows count from 0 in its store
            base = session.base
            if selection is not None:
                _new_segment(selection)
        picked: Sequence[int] | None = None  # the rows a filter or -c lets through
        if selection is not None and (selection.query is not None or selection.left is not None):
            picked = selection.take(rows.stop, final=final) if rows.stop else range(0)
        todo: list[int] | range = (
            range(rows.start + base, rows.stop + base)
            if picked is None
            else [i + base for i in picked]
        )
        if lister is not None and backlog is not None:
            # each frame is listed once; what is learnt later about a request listed
            # while open (its answer, its timeout) follows as one update record
            store = session.store
            store.sync()
            status = store.status
            # (a new segment starts only when no request is open: none is below base)
            settled = [i for i in waiting if status[i - base] != Status.OPEN]
            waiting = [i for i in waiting if status[i - base] == Status.OPEN]
            if settled:
                if backlog.full:
                    backlog.drop(len(settled))
                else:
                    lister.write_updates(settled)
                    backlog.add(sink.getvalue())
                    sink.seek(0)
                    sink.truncate()
            for k in range(0, len(todo), RENDER_ROWS):
                late = deadline is not None and time.monotonic() >= deadline
                if backlog.full or late:
                    backlog.drop(len(todo) - k)
                    break
                part = todo[k : k + RENDER_ROWS]
                lister.write(part, flush=False)
                waiting += [i for i in part if status[i - base] == Status.OPEN]
                backlog.add(sink.getvalue())
                sink.seek(0)
                sink.truncate()
                backlog.send()
            if backlog.dropped > said and notify is not None:
                now = time.monotonic()
                if now - last_said >= 1.0:
                    notify(_dropped_text(backlog.dropped))
                    said, last_said = backlog.dropped, now
        if exporter is not None:
            exporter.write(todo)

    try:
        with stop_requests() as stop:
            # the ports, not the recording: a recording stopped by a full disk said so
            # once, and the listing (and MQTT) go on
            while capture.reader.running and not stop.is_set():
                if end is not None and time.monotonic() >= end:
                    break
                if selection is not None and selection.done:
                    break
                behind = backlog is not None and bool(backlog.pending)
                emit(capture.pump(0.0 if behind else PUMP_SECONDS))
                if backlog is not None:
                    backlog.send(PUMP_SECONDS if behind else 0.0)
                if summary is not None:
                    summary.tick()
            deadline = time.monotonic() + STOP_GRACE
            emit(capture.stop(), deadline, final=True)
            if backlog is not None:
                lost = backlog.finish(max(0.0, deadline - time.monotonic()))
                if lost and notify is not None:
                    notify(f"stopped; {lost:,} bytes of the listing were not taken by its reader")
                if backlog.dropped > said and notify is not None:
                    notify(_dropped_text(backlog.dropped))
    except BrokenPipeError:
        quiet_stdout()
        capture.stop()
        return 0
    if summary is not None:
        summary.write()
    check_reader(capture)
    recorder = capture.recorder
    if capture.failure is not None and recorder is not None and recorder.stopped is not None:
        # the recording stopped (a full disk): its one line was said as it happened; the
        # status is record's for the same stop (1)
        return recorder.status
    if capture.failure is not None:
        raise UsageError(capture.failure)
    if getattr(capture.reader, "trouble", False):  # a watcher: reads lost, bad messages
        return 1
    return 0


def _new_segment(selection: Selection) -> None:
    """The capture started a new segment: the selection goes on over its store, from its
    first row (a filter keeps the time origin it had)."""
    selection.given = 0
    job = selection.job
    if job is not None:
        session = selection.session
        selection.job = FilterJob(
            session.store, job.query, job.options, session.annotator, job.origin
        )


def _dropped_text(rows: int) -> str:
    return (
        f"data lost: the listing fell behind the reader of its output; {rows:,} rows not "
        "listed so far (the gaps show in the index column; a recording with -w is complete)"
    )


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "live",
        help="watch a serial line as it runs (never transmits)",
        description=(
            "Listen to one or two serial ports without ever transmitting (RTS and DTR are "
            "not asserted, nothing is written) and show every frame as it comes: in the "
            "TUI on a terminal, else as a listing flushed per line (--format). Each frame "
            "is listed once; a request's later answer or timeout follows as an update "
            'record naming its row (JSONL {"update": N, ...}, with no raw: jq '
            "'select(.raw)' keeps the frames; see docs/output.md). --write "
            "records what the ports read; --pcap streams frames for Wireshark "
            "(modscope live /dev/ttyUSB0 --pcap - | wireshark -k -i -). --baud auto first "
            "scans the port for its baud rate and format, as `modscope scan` does, and "
            "says what it chose. --mqtt URL publishes the bus to a broker; a broker URL "
            "instead of a port watches a bus another modscope publishes (modscope live "
            "mqtt://broker/modscope/line1). See docs/mqtt.md."
        ),
    )
    add_port_options(p)
    accept_auto_baud(p)
    add_device_options(p)
    add_output_options(p)
    p.add_argument(
        "--pcap",
        metavar="FILE",
        help="also write frames as Wireshark pcapng (each PDU for Wireshark's Modbus/TCP "
        "dissector, decoded and paired with no setup; see modscope export); - for "
        "standard output, which then carries nothing else",
    )
    add_recording_options(p, required=False)
    p.add_argument("--backlog", type=parse_backlog, default=BACKLOG_BYTES, help=argparse.SUPPRESS)
    add_filter_options(p)
    p.add_argument(
        "--stats",
        type=float,
        nargs="?",
        const=10.0,
        metavar="S",
        help="print the statistics, poll cycle and liveness (seconds since the last frame "
        "and each unit's last answer, the line idle or a unit silent after 3 of its poll "
        "periods) to stderr every S seconds (default 10); they are printed once anyway "
        "when the capture ends",
    )
    add_mqtt_options(p)
    add_metrics_options(p)
    p.set_defaults(func=cmd_live)

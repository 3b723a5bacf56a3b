"""Provides `modscope live`, `record` and `ports`: watching and recording serial lines as they run.

`LiveCapture` ties a `LiveReader` (threads reading the ports) to a `Session` (framing,
pairing, annotation) and a `Recorder` (pcapng link type 250). The recorder drains its
own feed in its own thread, so a slow screen or pipe never costs the recording a byte;
the session is fed by whoever calls `pump()`: the command line loop here, or the TUI.

For the TUI: `run_tui(session, None, live=capture)` gets a started `LiveCapture`. Call
`capture.pump(timeout)` from one thread (it feeds the session and returns the range of
new rows in `session.store`); `capture.messages` holds what happened on the ports
(port lost, reconnect, data lost); `capture.stop()` ends it (idempotent).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import json
import os
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from types import FrameType
from typing import TextIO

from sniffer.cli import (
    UsageError,
    add_device_options,
    add_line_options,
    add_output_options,
    bindings_for,
    read_options,
)
from sniffer.export import PcapExporter
from sniffer.listing import Lister
from sniffer.model import Chunk, Direction
from sniffer.pipeline import LIVE_MERGE_SLACK
from sniffer.recorder import Recorder, RecordError, Ring, parse_duration, parse_size
from sniffer.serial_source import (
    DEFAULT_QUEUE,
    ChunkFeed,
    LiveReader,
    PortError,
    PortFactory,
    PortSpec,
    list_ports,
)
from sniffer.session import Session
from sniffer.text import plain
from sniffer.vocab import Status

IDLE_QUIET = 0.02  # seconds without bytes after which the session is told the line is idle
PUMP_SECONDS = 0.05  # longest wait of one pump for new chunks
RECORD_GATHER = 0.002  # seconds the recorder lets reads gather before writing them
ROLES = {
    "master": Direction.MASTER,
    "requests": Direction.MASTER,
    "m": Direction.MASTER,
    "slave": Direction.SLAVE,
    "responses": Direction.SLAVE,
    "s": Direction.SLAVE,
    "unknown": Direction.UNKNOWN,
    "both": Direction.UNKNOWN,
    "-": Direction.UNKNOWN,
}

Notify = Callable[[str], None]


def event_text(chunk: Chunk) -> str:
    return chunk.event + (f": {chunk.note}" if chunk.note else "")


class LiveCapture:
    """Ports being read, framed into `session` and written by `recorder`, as they run."""

    def __init__(
        self,
        reader: LiveReader,
        session: Session | None,
        *,
        recorder: Recorder | None = None,
        queue_size: int = DEFAULT_QUEUE,
        notify: Notify | None = None,
        quiet: float | None = None,
    ) -> None:
        self.reader = reader
        self.session = session
        self.recorder = recorder
        self.notify = notify
        self.queue_size = queue_size
        line = session.line if session is not None else reader.specs[0].line
        self.quiet = quiet if quiet is not None else max(line.t35, IDLE_QUIET)
        self.messages: deque[str] = deque(maxlen=200)
        self.failure: str | None = None
        self.shown = 0
        self.feed: ChunkFeed | None = None
        if session is not None:
            self.feed = reader.subscribe(queue_size)
        self._rec_feed: ChunkFeed | None = None
        if recorder is not None:
            self._rec_feed = reader.subscribe(queue_size)
        self._rec_thread: threading.Thread | None = None
        self._last_data = time.monotonic()
        self._lock = threading.Lock()
        self._pumping = threading.Lock()  # pump() and stop() feed the session in turn
        self._stopped = False

    # -- lifetime --------------------------------------------------------------------------

    def start(self) -> None:
        self.reader.start()
        if self._rec_feed is not None:
            self._rec_thread = threading.Thread(
                target=self._record, name="modscope-recorder", daemon=True
            )
            self._rec_thread.start()

    def stop(self) -> range:
        """Stop reading, frame what is left, close the recording. Returns the last rows."""
        with self._lock:
            if self._stopped:
                return range(self.shown, self.shown)
            self._stopped = True
        self.reader.stop()
        rows = range(self.shown, self.shown)
        if self.session is not None and self.feed is not None:
            with self._pumping:
                while not self.feed.closed:
                    self._take(self.feed.get(0))
                self.session.finish()
                rows = self._new_rows()
        if self._rec_thread is not None:
            self._rec_thread.join(30)
            if self._rec_thread.is_alive():
                self._report("error: the recording did not finish writing; its disk is stuck")
                return rows
        if self.recorder is not None:
            self.recorder.close(self.reader.clock.now())
        return rows

    # -- recording on demand (the TUI's `r`) ----------------------------------------------

    def start_recording(self, path: str | Path) -> Recorder:
        """Record from now on into `path` (pcapng, link type 250), while reading goes on.
        RecordError if the file cannot be written or a recording is already running."""
        with self._lock:
            if self.recorder is not None:
                raise RecordError(f"already recording to {self.recorder.path}; stop it first")
            recorder = Recorder(path, self.reader.specs)
            self.recorder = recorder
            self._rec_feed = self.reader.attach(self.queue_size)
            self._rec_thread = threading.Thread(
                target=self._record, name="modscope-recorder", daemon=True
            )
            self._rec_thread.start()
        return recorder

    def stop_recording(self) -> list[Path]:
        """Finish the running recording (everything read so far is written); its files."""
        with self._lock:
            recorder, feed, thread = self.recorder, self._rec_feed, self._rec_thread
            self.recorder, self._rec_feed, self._rec_thread = None, None, None
        if recorder is None or feed is None:
            return []
        self.reader.detach(feed)
        if thread is not None:
            thread.join(30)
        recorder.close(self.reader.clock.now())
        return list(recorder.files)

    @property
    def lost_bytes(self) -> int:
        """Bytes the display and the recording could not keep up with, together."""
        feeds = (self.feed, self._rec_feed)
        return sum(f.lost_bytes for f in feeds if f is not None)

    @property
    def running(self) -> bool:
        return self.reader.running and self.failure is None

    def _report(self, text: str) -> None:
        self.messages.append(text)
        if self.notify is not None:
            self.notify(text)

    # -- the session side ------------------------------------------------------------------

    def pump(self, timeout: float = PUMP_SECONDS) -> range:
        """Feed what the ports read since the last call (waiting up to `timeout` for it)
        to the session; tell it when the line went quiet. Returns the new rows."""
        if self.session is None or self.feed is None:
            raise RuntimeError("this capture has no session to pump")
        with self._pumping:
            if self._stopped:
                return range(self.shown, self.shown)
            self._take(self.feed.get(timeout))
            if time.monotonic() - self._last_data >= self.quiet:
                self.session.idle(self.reader.clock.now())
            else:
                self.session.refresh()
            return self._new_rows()

    def _take(self, chunks: list[Chunk]) -> None:
        assert self.session is not None
        feed = self.session.feed
        got_data = False
        for chunk in chunks:
            if chunk.event:
                self._report(event_text(chunk))
            feed(chunk)
            got_data = got_data or bool(chunk.data)
        if got_data:
            self._last_data = time.monotonic()

    def _new_rows(self) -> range:
        assert self.session is not None
        end = len(self.session.store)
        rows = range(self.shown, end)
        self.shown = end
        return rows

    # -- the recording side ------------------------------------------------------------------

    def _record(self) -> None:
        feed, recorder = self._rec_feed, self.recorder
        assert feed is not None and recorder is not None
        lost = 0
        while not feed.closed:
            chunks = feed.get(0.5)
            if chunks and not feed.closed:
                # let a few more reads gather: one wake-up per few reads, not per read
                time.sleep(RECORD_GATHER)
                chunks += feed.get(0)
            try:
                for chunk in chunks:
                    recorder.write(chunk)
                    if chunk.event and self.session is None:
                        self._report(event_text(chunk))
            except RecordError as exc:
                self.failure = str(exc)
                self._report(f"error: {exc}")
                return
            if feed.lost_bytes > lost and self.session is not None:
                self._report(
                    f"data lost: the recording fell behind; {feed.lost_bytes - lost} bytes "
                    "not recorded (marked in the file)"
                )
                lost = feed.lost_bytes


# -- command line --------------------------------------------------------------------------


def parse_roles(text: str | None, count: int) -> list[Direction]:
    """`--directions master,slave` -> a direction per port (UNKNOWN without the option)."""
    if text is None:
        return [Direction.UNKNOWN] * count
    words = [w.strip().lower() for w in text.split(",") if w.strip()]
    bad = [w for w in words if w not in ROLES]
    if bad:
        raise UsageError(
            f"--directions: {bad[0]!r} is not a role; write master (requests) or slave "
            "(responses) per port, e.g. --directions master,slave (a bare --directions "
            "goes after the ports)"
        )
    if len(words) != count:
        raise UsageError(
            f"--directions names {len(words)} roles for {count} port(s); give one per port "
            "in the order the ports are named"
        )
    return [ROLES[w] for w in words]


def port_specs(args: argparse.Namespace) -> list[PortSpec]:
    names = [*args.ports, *args.extra_ports]
    if not names:
        raise UsageError(
            "name the port to listen on, e.g. /dev/ttyUSB0 or socket://host:4001 "
            "(`modscope ports` lists this machine's ports)"
        )
    if len(set(names)) != len(names):
        raise UsageError("a port is named twice; give each port once")
    if len(names) > 8:
        raise UsageError(f"{len(names)} ports: modscope listens on at most 8 at once")
    try:
        line = read_options(args).line(None)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    roles = parse_roles(args.directions, len(names))
    return [
        PortSpec(n, line, channel=k, direction=r)
        for k, (n, r) in enumerate(zip(names, roles, strict=True))
    ]


def ring_options(args: argparse.Namespace) -> Ring:
    try:
        size = parse_size(args.rotate_size) if args.rotate_size else None
        seconds = parse_duration(args.rotate_time) if args.rotate_time else None
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    ring = Ring(size=size, seconds=seconds, keep=args.keep)
    if (ring.active or args.keep is not None) and not args.write:
        raise UsageError("--rotate-size, --rotate-time and --keep need -w FILE")
    return ring


def duration_option(args: argparse.Namespace) -> float | None:
    if args.duration is None:
        return None
    try:
        return parse_duration(args.duration)
    except ValueError as exc:
        raise UsageError(f"--duration: {exc}") from None


@contextlib.contextmanager
def stop_requests() -> Iterator[threading.Event]:
    """An event set by Ctrl-C, SIGTERM or SIGHUP, so that a capture ends between two
    rows (never in the middle of writing one) and closes its files properly. A second
    Ctrl-C interrupts at once."""
    stop = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def request(signum: int, frame: FrameType | None) -> None:
        if stop.is_set():  # asked twice: stop at once
            raise KeyboardInterrupt
        stop.set()

    saved = {}
    for sig in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if sig is not None:
            saved[sig] = signal.signal(sig, request)
    try:
        yield stop
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def _open_reader(
    specs: Sequence[PortSpec], err: TextIO, factory: PortFactory | None = None
) -> LiveReader:
    reader = LiveReader(specs, factory=factory)
    try:
        reader.open()
    except PortError as exc:
        raise UsageError(str(exc)) from None
    for w in reader.warnings:
        err.write(f"modscope: warning: {plain(w)}\n")
    return reader


def _open_recorder(
    args: argparse.Namespace, specs: Sequence[PortSpec], ring: Ring
) -> Recorder | None:
    if not args.write:
        return None
    try:
        if args.write == "-":
            return Recorder("-", specs, ring=ring, stream=sys.stdout.buffer)
        return Recorder(args.write, specs, ring=ring)
    except RecordError as exc:
        raise UsageError(str(exc)) from None


def _announce(err: TextIO, verb: str, specs: Sequence[PortSpec], recorder: Recorder | None) -> None:
    names = ", ".join(s.name for s in specs)
    line = specs[0].line.describe()
    where = (
        f"; recording to {recorder.files[0] if recorder.files else 'stdout'}" if recorder else ""
    )
    err.write(f"modscope: {verb} {names} ({line}), never transmitting{where}; Ctrl-C stops\n")
    err.flush()


def _notifier(err: TextIO) -> Notify:
    def notify(text: str) -> None:
        with contextlib.suppress(OSError, ValueError):
            err.write(f"modscope: {plain(text)}\n")
            err.flush()

    return notify


def _quiet_stdout() -> None:
    """After the reader of our stdout went away: send the rest nowhere, quietly."""
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)


def cmd_live(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    specs = port_specs(args)
    ring = ring_options(args)
    deadline = duration_option(args)
    if args.write == "-":
        raise UsageError("live writes its listing to standard output; record with -w FILE")
    if args.pcap == "-" and args.format is not None:
        raise UsageError("--pcap - takes standard output for itself; drop --format")
    if args.pcap and args.write and os.path.abspath(args.pcap) == os.path.abspath(args.write):
        raise UsageError("--pcap and -w name the same file; give each its own")
    bindings = bindings_for(args)
    session = Session(
        specs[0].line,
        bindings=bindings,
        timeout=args.timeout,
        source=", ".join(s.name for s in specs),
        merge_slack=LIVE_MERGE_SLACK,
    )
    use_tui = (
        args.format is None
        and args.pcap is None
        and out.isatty()
        and sys.stdin.isatty()
        and _tui_available()
    )
    reader = _open_reader(specs, err)
    try:
        recorder = _open_recorder(args, specs, ring)
    except BaseException:
        reader.stop()
        raise
    capture = LiveCapture(
        reader,
        session,
        recorder=recorder,
        queue_size=args.queue,
        notify=None if use_tui else _notifier(err),
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
            exporter = PcapExporter(pcap_file, session.describer, specs[0].line, name=specs[0].name)
        capture.start()
        if use_tui:
            # what the ports said while opening shows in the TUI, not behind it
            capture.messages.extend(f"warning: {w}" for w in reader.warnings)
            run_tui: Callable[..., int] = importlib.import_module("sniffer.tui.app").run_tui
            return run_tui(session, None, live=capture)
        _announce(err, "listening on", specs, recorder)
        lister = None
        if args.pcap != "-":
            lister = Lister(
                out, args.format or "text", session.describer, absolute=args.time == "abs"
            )
        return _stream(capture, lister, exporter, deadline)
    finally:
        capture.stop()
        if pcap_file is not None and pcap_file is not sys.stdout.buffer:
            pcap_file.close()


def _tui_available() -> bool:
    try:
        return importlib.util.find_spec("sniffer.tui.app") is not None
    except ModuleNotFoundError:
        return False


def _stream(
    capture: LiveCapture,
    lister: Lister | None,
    exporter: PcapExporter | None,
    duration: float | None,
) -> int:
    """The listing loop: rows out as they are framed, each flushed, until stopped."""
    end = None if duration is None else time.monotonic() + duration
    assert capture.session is not None
    store = capture.session.store
    waiting: list[int] = []  # requests listed while they waited for their answer

    def emit(rows: range) -> None:
        nonlocal waiting
        if lister is not None:
            store.sync()
            status = store.status
            # a request listed as open that then got no answer is listed again
            again = [i for i in waiting if status[i] == Status.TIMEOUT]
            waiting = [i for i in waiting if status[i] == Status.OPEN]
            waiting += [i for i in rows if status[i] == Status.OPEN]
            lister.write(again)
            lister.write(rows)
        if exporter is not None:
            exporter.write(rows)

    try:
        with stop_requests() as stop:
            while capture.running and not stop.is_set():
                if end is not None and time.monotonic() >= end:
                    break
                emit(capture.pump())
            emit(capture.stop())
    except BrokenPipeError:
        _quiet_stdout()
        capture.stop()
        return 0
    if capture.failure is not None:
        raise UsageError(capture.failure)
    return 0


def cmd_record(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    specs = port_specs(args)
    ring = ring_options(args)
    deadline = duration_option(args)
    reader = _open_reader(specs, err)
    try:
        recorder = _open_recorder(args, specs, ring)
    except BaseException:
        reader.stop()
        raise
    assert recorder is not None
    capture = LiveCapture(
        reader, None, recorder=recorder, queue_size=args.queue, notify=_notifier(err)
    )
    _announce(err, "recording", specs, recorder)
    end = None if deadline is None else time.monotonic() + deadline
    show = err.isatty()
    try:
        with stop_requests() as stop:
            capture.start()
            while capture.running and not stop.is_set():
                wait = 0.2 if end is None else min(0.2, end - time.monotonic())
                if wait <= 0:
                    break
                stop.wait(wait)
                if show:
                    err.write("\r" + _status(capture) + "\x1b[K")
                    err.flush()
    finally:
        capture.stop()
    if show:
        err.write("\r\x1b[K")
    err.write(f"modscope: {_status(capture)}\n")
    if capture.failure is not None:
        raise UsageError(capture.failure)
    return 0


def _status(capture: LiveCapture) -> str:
    stats = capture.reader.stats
    parts = [f"{s.name}: {s.bytes:,} bytes in {s.reads:,} reads" for s in stats]
    rec = capture.recorder
    if rec is not None:
        where = str(rec.files[-1]) if rec.files else "stdout"
        parts.append(f"{rec.packets:,} packets to {where}")
    if capture.lost_bytes:
        parts.append(f"{capture.lost_bytes:,} bytes lost")
    if any(not s.connected for s in stats):
        parts.append("waiting for a lost port")
    return "; ".join(parts)


def cmd_ports(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    ports = list(list_ports(include_links=True))
    if args.format == "jsonl":
        for p in ports:
            rec = {
                "device": p.device,
                "description": p.description,
                "usb_id": p.usb_id or None,
                "serial_number": p.serial_number,
                "manufacturer": p.manufacturer,
                "product": p.product,
                "location": p.location,
                "hwid": p.hwid,
            }
            out.write(json.dumps(rec) + "\n")
        return 0
    if not ports:
        err.write(
            "modscope: no serial ports found; plug in the adapter (dmesg shows whether the "
            "kernel saw it), or give a device path or URL to `modscope live` directly\n"
        )
        return 0
    width = max(len(p.device) for p in ports)
    for p in ports:
        usb = f"  USB {p.usb_id}" if p.usb_id else ""
        serial_no = f"  serial {p.serial_number}" if p.serial_number else ""
        out.write(f"{p.device:<{width}}  {plain(p.description)}{usb}{serial_no}\n")
    return 0


# -- registration --------------------------------------------------------------------------


def _add_port_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "ports",
        nargs="*",
        metavar="PORT",
        help="device path (/dev/ttyUSB0) or pyserial URL (rfc2217://host:port, "
        "socket://host:port); two for a 4-wire bus or one adapter per direction",
    )
    p.add_argument(
        "--port",
        action="append",
        default=[],
        dest="extra_ports",
        metavar="PORT",
        help="another port to listen on (repeatable)",
    )
    add_line_options(p)
    p.add_argument(
        "--directions",
        nargs="?",
        const="master,slave",
        metavar="ROLES",
        help="what each port carries, in port order: master (requests) or slave "
        "(responses); bare --directions means master,slave",
    )


def _add_recording_options(p: argparse.ArgumentParser, required: bool) -> None:
    g = p.add_argument_group("recording (pcapng, link type 250: every read as the port gave it)")
    g.add_argument(
        "-w",
        "--write",
        required=required,
        metavar="FILE",
        help="record to FILE.pcapng" + (" (- for standard output)" if required else ""),
    )
    g.add_argument("--rotate-size", metavar="SIZE", help="ring buffer: new file past SIZE (10M)")
    g.add_argument("--rotate-time", metavar="TIME", help="ring buffer: new file every TIME (1h)")
    g.add_argument("--keep", type=int, metavar="N", help="ring buffer: keep the newest N files")
    p.add_argument("--duration", metavar="TIME", help="stop after TIME (30s, 15m, 1h)")
    p.add_argument("--queue", type=int, default=DEFAULT_QUEUE, help=argparse.SUPPRESS)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "live",
        help="watch a serial line as it runs (never transmits)",
        description=(
            "Listen to one or two serial ports without ever transmitting (RTS and DTR are "
            "not asserted, nothing is written) and show every frame as it comes: in the "
            "TUI on a terminal, else as a listing flushed per line (--format). --write "
            "records what the ports read; --pcap streams frames for Wireshark "
            "(modscope live /dev/ttyUSB0 --pcap - | wireshark -k -i -)."
        ),
    )
    _add_port_options(p)
    add_device_options(p)
    add_output_options(p)
    p.add_argument(
        "--pcap",
        metavar="FILE",
        help="also write frames as Wireshark pcapng (link type 252, Modbus RTU); - for "
        "standard output, which then carries nothing else",
    )
    _add_recording_options(p, required=False)
    p.set_defaults(func=cmd_live)

    p = sub.add_parser(
        "record",
        help="record a serial line to pcapng without decoding (never transmits)",
        description=(
            "Record every read of one or two ports, as the ports gave it, to pcapng (link "
            "type 250, line settings in the interface description) for `modscope replay`, "
            "with an optional ring buffer. Nothing is ever transmitted."
        ),
    )
    _add_port_options(p)
    _add_recording_options(p, required=True)
    p.set_defaults(func=cmd_record)

    p = sub.add_parser(
        "ports",
        help="list this machine's serial ports with their USB ids",
        description="List serial ports (pyserial's list_ports): device, description, USB ids.",
    )
    p.add_argument("--format", choices=("text", "jsonl"), default="text", help="output style")
    p.set_defaults(func=cmd_ports)

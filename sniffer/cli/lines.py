"""Provides what `live` and `record` share: port and recording options, opening the ports
and the recorder, stopping on Ctrl-C between two rows, and status lines."""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator, Sequence
from types import FrameType
from typing import TextIO

from sniffer.cli.options import add_line_options, line_of, read_options
from sniffer.errors import UsageError
from sniffer.live.engine import LiveCapture, Notify
from sniffer.live.port import DEFAULT_QUEUE, LiveReader, PortFactory, PortSpec
from sniffer.live.recorder import Recorder, Ring, parse_duration, parse_size
from sniffer.model import Direction
from sniffer.text import plain

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
    line = line_of(read_options(args))
    roles = parse_roles(args.directions, len(names))
    return [
        PortSpec(n, line, channel=k, direction=r)
        for k, (n, r) in enumerate(zip(names, roles, strict=True))
    ]


def ring_options(args: argparse.Namespace) -> Ring:
    try:
        size = parse_size(args.rotate_size) if args.rotate_size else None
    except ValueError as exc:
        raise UsageError(f"--rotate-size: {exc}") from None
    try:
        seconds = parse_duration(args.rotate_time) if args.rotate_time else None
    except ValueError as exc:
        raise UsageError(f"--rotate-time: {exc}") from None
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


def queue_option(args: argparse.Namespace) -> int:
    if args.queue < 1:
        raise UsageError(f"--queue: a feed holds at least one chunk, not {args.queue}")
    return int(args.queue)


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


def open_reader(
    specs: Sequence[PortSpec], err: TextIO, factory: PortFactory | None = None
) -> LiveReader:
    """The ports opened (PortError, a user error, if one cannot be), warnings printed."""
    reader = LiveReader(specs, factory=factory)
    reader.open()
    for w in reader.warnings:
        err.write(f"modscope: warning: {plain(w)}\n")
    return reader


def open_recorder(
    args: argparse.Namespace, specs: Sequence[PortSpec], ring: Ring
) -> Recorder | None:
    """The recording -w asks for (RecordError, a user error, if it cannot be written)."""
    if not args.write:
        return None
    if args.write == "-":
        return Recorder("-", specs, ring=ring, stream=sys.stdout.buffer)
    return Recorder(args.write, specs, ring=ring)


def announce(err: TextIO, verb: str, specs: Sequence[PortSpec], recorder: Recorder | None) -> None:
    names = ", ".join(s.name for s in specs)
    line = specs[0].line.describe()
    where = (
        f"; recording to {recorder.files[0] if recorder.files else 'stdout'}" if recorder else ""
    )
    err.write(f"modscope: {verb} {names} ({line}), never transmitting{where}; Ctrl-C stops\n")
    err.flush()


def notifier(err: TextIO) -> Notify:
    def notify(text: str) -> None:
        with contextlib.suppress(OSError, ValueError):
            err.write(f"modscope: {plain(text)}\n")
            err.flush()

    return notify


def quiet_stdout() -> None:
    """After the reader of our stdout went away: send the rest nowhere, quietly."""
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)


def check_reader(capture: LiveCapture) -> None:
    """A reading thread that ended through a bug ends the command as a bug (exit 70, with
    the thread's own traceback), after what was read has been written out."""
    reader = capture.reader
    if reader.error is not None:
        raise RuntimeError(reader.failure) from reader.error


def status(capture: LiveCapture) -> str:
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


def add_port_options(p: argparse.ArgumentParser) -> None:
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


def add_recording_options(p: argparse.ArgumentParser, required: bool) -> None:
    g = p.add_argument_group("recording (pcapng, link type 250: every read as the port gave it)")
    g.add_argument(
        "-w",
        "--write",
        required=required,
        metavar="FILE",
        help="record to FILE, pcapng, under exactly the name given, as tcpdump -w does "
        "(name it .pcapng so other tools know it)"
        + (" (- for standard output)" if required else ""),
    )
    g.add_argument("--rotate-size", metavar="SIZE", help="ring buffer: new file past SIZE (10M)")
    g.add_argument("--rotate-time", metavar="TIME", help="ring buffer: new file every TIME (1h)")
    g.add_argument("--keep", type=int, metavar="N", help="ring buffer: keep the newest N files")
    p.add_argument("--duration", metavar="TIME", help="stop after TIME (30s, 15m, 1h)")
    p.add_argument("--queue", type=int, default=DEFAULT_QUEUE, help=argparse.SUPPRESS)

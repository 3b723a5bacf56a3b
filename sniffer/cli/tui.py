"""Provides `modscope tui`: the TUI on a capture even when stdout is not a terminal
(textual-serve runs it that way). Textual is imported only when it runs."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TextIO

from sniffer.cli.options import (
    SubParsers,
    add_device_options,
    add_line_options,
    add_network_options,
    bindings_for,
    read_options,
)
from sniffer.cli.together import replay_together
from sniffer.errors import UsageError
from sniffer.live.engine import LiveCapture
from sniffer.outputs.mqtt.command import (
    MQTT_QUIET,
    add_broker_options,
    mqtt_session,
    open_mqtt_source,
    published_bindings,
)
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, open_session
from sniffer.text import plain


def capture_path(file: str | None) -> Path:
    """The capture FILE names, or the bundled demo; UsageError if there is none."""
    if file:
        path = Path(file)
        if not path.is_file():
            raise UsageError(f"{path}: no such file; give the path of a capture to show")
        return path
    if not DEMO_CAPTURE.exists():
        raise UsageError(f"the demo capture {DEMO_CAPTURE} is missing; give a capture FILE")
    return DEMO_CAPTURE


def cmd_tui(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    files: list[str] = list(args.file or [])
    if any(f.lower().startswith(("mqtt://", "mqtts://")) for f in files):
        if len(files) > 1:
            raise UsageError(f"{files[0]}: watch a published bus alone, without other files")
        return _watch(args, err, files[0])
    if len(files) > 1:
        # what `replay A B` opens on a terminal: the files merged by time, gateways linked
        together = argparse.Namespace(
            **vars(args), format=None, stats=False, filter=None, count=None, offset=[]
        )
        together.gateway_timeout = 1.0
        return replay_together(together, files, out, err, tui=True)
    path = capture_path(files[0] if files else None)
    bindings = bindings_for(args, DEMO_BUS if not files else None)
    options = read_options(args)
    session, capture = open_session(
        path, options, bindings=bindings, timeout=args.timeout, interactive=True
    )
    from sniffer.tui.app import run_tui  # here: only the commands that open it load Textual

    return run_tui(session, capture, speed=1.0 if args.speed == "original" else None)


def _watch(args: argparse.Namespace, err: TextIO, url: str) -> int:
    """`modscope tui mqtt://host/base`: the TUI on a bus another modscope publishes."""
    messages: list[str] = []

    def tell(text: str) -> None:  # before the TUI is up (waiting for the publisher): stderr too
        messages.append(text)
        err.write(f"modscope: {plain(text)}\n")
        err.flush()

    reader = open_mqtt_source(url, args, tell)
    bindings = published_bindings(bindings_for(args), reader, messages.append)
    session = mqtt_session(reader, bindings, args.timeout)
    capture = LiveCapture(reader, session, quiet=MQTT_QUIET)
    capture.messages.extend(messages)
    reader.notify = capture.messages.append
    from sniffer.tui.app import run_tui  # here: only the commands that open it load Textual

    capture.start()
    try:
        return run_tui(session, None, live=capture)
    finally:
        capture.stop()


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "tui",
        help="open the TUI on a capture (the bundled demo without FILE)",
        description="Open the TUI on a capture, even when stdout is not a terminal.",
    )
    p.add_argument(
        "file",
        nargs="*",
        help="capture file (default: the bundled demo); several files open together, merged "
        "by time, as replay does; or mqtt://host/base to watch a bus another modscope "
        "publishes",
    )
    add_broker_options(p)  # --mqtt-ca, --mqtt-password-file
    add_line_options(p)
    add_network_options(p)
    add_device_options(p)
    p.add_argument(
        "--speed",
        choices=("fast", "original"),
        default="fast",
        help="index as fast as possible (default) or replay at the capture's own speed",
    )
    p.set_defaults(func=cmd_tui)

"""Provides the command-line side of MQTT: the options and `replay --mqtt`."""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from typing import TextIO

from sniffer.annotate import Binding
from sniffer.errors import UsageError
from sniffer.mqtt import MqttError
from sniffer.mqtt.publish import DEFAULT_EVERY, PublisherOptions, open_publisher, publish_replay
from sniffer.mqtt.target import bus_slug, parse_target
from sniffer.session import Session
from sniffer.sources import Capture
from sniffer.text import plain


def add_mqtt_options(p: argparse.ArgumentParser, *, replay: bool = False) -> None:
    g = p.add_argument_group("MQTT (pip install 'modscope[mqtt]'; see docs/mqtt.md)")
    g.add_argument(
        "--mqtt",
        metavar="URL",
        help="publish the bus to a broker: mqtt://[user:pass@]host[:port]/base/topic "
        "(mqtts:// for TLS; MODSCOPE_MQTT_USER/_PASSWORD keep credentials out of history)",
    )
    g.add_argument("--mqtt-ca", metavar="FILE", help="CA certificate for mqtts://")
    g.add_argument("--bus-name", metavar="NAME", help="bus name (default: the file or port name)")
    g.add_argument(
        "--mqtt-every",
        type=float,
        default=DEFAULT_EVERY,
        metavar="S",
        help=f"publish unchanged values at least every S seconds (default {DEFAULT_EVERY:g})",
    )
    g.add_argument(
        "--ha-discovery",
        nargs="?",
        const="homeassistant",
        metavar="PREFIX",
        help="Home Assistant MQTT discovery (default prefix: homeassistant)",
    )
    if replay:
        g.add_argument(
            "--speed",
            choices=("fast", "original"),
            default="fast",
            help="publish as fast as the file reads (default) or at the recorded pace",
        )


def cmd_replay_mqtt(
    args: argparse.Namespace,
    session: Session,
    capture: Capture,
    bindings: Mapping[int, Binding],
    name: str,
    err: TextIO,
) -> int:
    """`modscope replay FILE --mqtt URL`: publish the capture, report what was delivered."""
    bus = args.bus_name or bus_slug(name)

    def notify(text: str) -> None:
        err.write(f"modscope: {plain(text)}\n")
        err.flush()

    try:
        target = parse_target(args.mqtt, bus=bus, ca=args.mqtt_ca)
        options = PublisherOptions(bus=bus, every=args.mqtt_every, ha_prefix=args.ha_discovery)
        publisher = open_publisher(
            target, session, bindings, options, info=capture.info, notify=notify
        )
    except MqttError as exc:
        raise UsageError(str(exc)) from None
    err.write(f"modscope: publishing {name} to {target.describe()}\n")
    try:
        publish_replay(
            session, capture.chunks(), publisher, original_speed=args.speed == "original"
        )
    finally:
        report = publisher.close()
    err.write(
        f"modscope: {publisher.raw:,} reads, {publisher.values:,} values, "
        f"{publisher.events:,} events published; {report}\n"
    )
    return 0

"""Provides the command-line side of MQTT: the options and `replay --mqtt`."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping, Sequence
from typing import TextIO

from dissectors.dictionary.errors import DictionaryError
from dissectors.dictionary.loader import load_model
from sniffer.errors import UsageError
from sniffer.framing.pipeline import LIVE_MERGE_SLACK
from sniffer.live.port import PortSpec
from sniffer.meaning.annotate import Binding
from sniffer.outputs.mqtt import MqttError
from sniffer.outputs.mqtt.publish import (
    DEFAULT_EVERY,
    BusPublisher,
    PublisherOptions,
    open_publisher,
    publish_replay,
)
from sniffer.outputs.mqtt.subscribe import MqttReader
from sniffer.outputs.mqtt.target import bus_slug, parse_target
from sniffer.session.session import Session
from sniffer.sources import Capture
from sniffer.text import plain


def add_mqtt_options(p: argparse.ArgumentParser, *, replay: bool = False) -> None:
    g = p.add_argument_group("MQTT (pip install 'modscope[mqtt]'; see docs/mqtt.md)")
    g.add_argument(
        "--mqtt",
        metavar="URL",
        help="publish the bus to a broker: mqtt://[user@]host[:port]/base/topic "
        "(mqtts:// for TLS; the password from --mqtt-password-file or MODSCOPE_MQTT_PASSWORD "
        "stays out of history and the process list)",
    )
    add_broker_options(g)
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


def add_broker_options(g: argparse._ArgumentGroup | argparse.ArgumentParser) -> None:
    """The options of a broker connection, for publishing or watching."""
    g.add_argument("--mqtt-ca", metavar="FILE", help="CA certificate for mqtts://")
    g.add_argument(
        "--mqtt-password-file",
        metavar="FILE",
        help="the broker password: the first line of FILE (not shown, not in `ps`)",
    )


def cmd_replay_mqtt(
    args: argparse.Namespace,
    session: Session,
    capture: Capture,
    bindings: Mapping[int, Binding],
    name: str,
    err: TextIO,
    *,
    window: int | None = None,
    segment: Callable[[Session], None] | None = None,
) -> int:
    """`modscope replay FILE --mqtt URL`: publish the capture, report what was delivered.
    `window`, `segment`: see `publish_replay` (rows dropped once published)."""
    bus = args.bus_name or bus_slug(name)

    def notify(text: str) -> None:
        err.write(f"modscope: {plain(text)}\n")
        err.flush()

    try:
        target = parse_target(
            args.mqtt, bus=bus, ca=args.mqtt_ca, password_file=args.mqtt_password_file
        )
        options = PublisherOptions(bus=bus, every=args.mqtt_every, ha_prefix=args.ha_discovery)
        publisher = open_publisher(
            target, session, bindings, options, info=capture.info, notify=notify
        )
    except MqttError as exc:
        raise UsageError(str(exc)) from None
    err.write(f"modscope: publishing {name} to {target.describe()}\n")
    try:
        publish_replay(
            session,
            capture.chunks(),
            publisher,
            original_speed=args.speed == "original",
            window=window,
            segment=segment,
        )
    finally:
        report = publisher.close()
    err.write(
        f"modscope: {publisher.raw:,} reads, {publisher.values:,} values, "
        f"{publisher.events:,} events published; {report}\n"
    )
    # messages the broker never took are data lost to whoever reads it: the run failed
    # (the line above says how many and why), as a capture cut short exits 1
    counts = publisher.link.counts
    return 1 if counts.dropped or counts.pending else 0


LIVE_LIMIT = 20_000  # messages a live capture buffers while the broker is away or slow


def is_broker_url(text: str) -> bool:
    """`mqtt://...` or `mqtts://...`: a bus another modscope publishes, not a port."""
    return text.lower().startswith(("mqtt://", "mqtts://"))


def live_publisher(
    args: argparse.Namespace,
    session: Session,
    bindings: Mapping[int, Binding],
    specs: Sequence[PortSpec],
    clock: Callable[[], float],
    notify: Callable[[str], None],
    err: TextIO,
) -> BusPublisher | None:
    """The publisher `live --mqtt URL` and `record --mqtt URL` feed (None without --mqtt).

    It never waits for the broker: past `LIVE_LIMIT` undelivered messages it drops,
    counts and says so, and reconnects by itself (see `sniffer.outputs.mqtt.link`)."""
    if not getattr(args, "mqtt", None):
        return None
    bus = args.bus_name or bus_slug(specs[0].name)
    try:
        target = parse_target(
            args.mqtt, bus=bus, ca=args.mqtt_ca, password_file=args.mqtt_password_file
        )
        options = PublisherOptions(
            bus=bus,
            every=args.mqtt_every,
            ha_prefix=args.ha_discovery,
            block=False,
            extra={
                "channels": {
                    str(s.channel): {"name": s.name, "direction": s.direction.name.lower()}
                    for s in specs
                }
            },
        )
        publisher = open_publisher(
            target,
            session,
            bindings,
            options,
            notify=notify,
            limit=LIVE_LIMIT,
            wait=2.0,
            clock=clock,
        )
    except MqttError as exc:
        raise UsageError(str(exc)) from None
    err.write(f"modscope: publishing to {target.describe()}\n")
    return publisher


def open_mqtt_source(
    url: str, args: argparse.Namespace, notify: Callable[[str], None]
) -> MqttReader:
    """`modscope live mqtt://host/base`: the reader of a bus another modscope publishes,
    with the publisher's line settings (UsageError when the broker cannot be used; no
    publisher yet is waited for)."""
    for name in ("directions",):
        if getattr(args, name, None):
            raise UsageError(
                f"--{name} is for serial ports; a published bus keeps the publisher's channels"
            )
    try:
        target = parse_target(
            url,
            bus="bus",
            ca=getattr(args, "mqtt_ca", None),
            password_file=getattr(args, "mqtt_password_file", None),
        )
        reader = MqttReader(target, notify=notify)
        reader.open()  # waits for the publisher (saying so) until there is one
    except MqttError as exc:
        raise UsageError(str(exc)) from None
    return reader


def mqtt_session(
    reader: MqttReader, bindings: Mapping[int, Binding], timeout: float | None
) -> Session:
    """A session that frames the published chunks as the publisher did: its carrier (a
    network capture's connections by their labels), line settings, timing, response
    timeout and merge slack (from its `interface` message), unless --timeout says
    otherwise."""
    return Session(
        reader.specs[0].line,
        bindings=bindings,
        exact_timing=reader.exact_timing,
        timeout=timeout if timeout is not None else reader.timeout,
        source=reader.target.describe(),
        merge_slack=LIVE_MERGE_SLACK if reader.merge_slack is None else reader.merge_slack,
        stamps=reader.stamps,
        resolution=reader.resolution,
        # the reader's own dict: connections the publisher names later are added to it
        network=reader.channel_labels if reader.network else None,
    )


MQTT_QUIET = 1.0  # seconds without messages before a watched bus counts as quiet


def mqtt_source(args: argparse.Namespace, notify: Callable[[str], None]) -> MqttReader | None:
    """The reader when `live`/`tui` name a broker URL instead of a port, else None."""
    names = [*getattr(args, "ports", []), *getattr(args, "extra_ports", [])]
    urls = [n for n in names if is_broker_url(n)]
    if not urls:
        return None
    if len(names) > 1:
        raise UsageError(
            f"{urls[0]} is a published bus; watch it alone (one modscope publishes each bus, "
            "with all its ports)"
        )
    return open_mqtt_source(urls[0], args, notify)


def published_bindings(
    given: Mapping[int, Binding], reader: MqttReader, notify: Callable[[str], None]
) -> dict[int, Binding]:
    """The watcher's bindings: those `given` (--bus, --unit, --dict) if any, else the
    units the publisher's `interface` names, where the model is one of modscope's
    dictionaries."""
    if given:
        return dict(given)
    units = reader.interface.get("units")
    out: dict[int, Binding] = {}
    if not isinstance(units, dict):
        return out
    for key, unit in sorted(units.items()):
        if not isinstance(unit, dict) or not str(key).isdigit():
            continue
        address, model, label = int(key), str(unit.get("model", "")), unit.get("label")
        if not 1 <= address <= 247 or not model:
            continue
        try:
            dictionary = load_model(model)
        except DictionaryError:
            notify(
                f"unit {address}: the publisher's model {model!r} is not one of modscope's "
                "dictionaries; give --bus or --dict for its names"
            )
            continue
        name = label if isinstance(label, str) and label else dictionary.name
        out[address] = Binding(address, name, dictionary)
    return out

"""Provides broker addresses: `mqtt://[user:pass@]host[:port]/base/topic` and `mqtts://`.

Credentials can stay out of the shell history: `MODSCOPE_MQTT_USER` and
`MODSCOPE_MQTT_PASSWORD` fill what the URL leaves out. Without a path the base topic is
`modscope/<bus>`, the bus being the port's or the file's name (or `--bus-name`).
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import PurePath
from urllib.parse import unquote, urlsplit

from sniffer.outputs.mqtt import MqttError

SCHEMES = {"mqtt": (1883, False), "mqtts": (8883, True)}
ENV_USER = "MODSCOPE_MQTT_USER"
ENV_PASSWORD = "MODSCOPE_MQTT_PASSWORD"
_WILDCARDS = re.compile(r"[+#\x00]")


@dataclass(frozen=True, slots=True)
class MqttTarget:
    """Where to publish or subscribe: broker, credentials, TLS and the base topic."""

    host: str
    port: int
    base: str
    tls: bool = False
    username: str | None = None
    password: str | None = None
    ca: str | None = None

    def topic(self, *parts: str) -> str:
        return "/".join((self.base, *parts))

    def describe(self) -> str:
        """`mqtt://host:1883/modscope/demo`: the URL without its credentials."""
        scheme = "mqtts" if self.tls else "mqtt"
        return f"{scheme}://{self.host}:{self.port}/{self.base}"


def bus_slug(name: str) -> str:
    """A topic-safe bus name from a port or file name: `/dev/ttyUSB0` -> `ttyUSB0`,
    `captures/demo.pcapng` -> `demo`."""
    stem = PurePath(name).stem if "." in PurePath(name).name else PurePath(name).name
    slug = re.sub(r"[^A-Za-z0-9_.-]+", "-", stem).strip("-.")
    return slug or "bus"


def parse_target(
    url: str,
    *,
    bus: str = "bus",
    ca: str | None = None,
    environ: Mapping[str, str] | None = None,
) -> MqttTarget:
    """Parse a broker URL (module doc). MqttError says what is wrong and how to write it."""
    env = os.environ if environ is None else environ
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    if scheme not in SCHEMES:
        raise MqttError(
            f"{url!r}: not a broker URL; write mqtt://host[:port]/base/topic (or mqtts:// for TLS)"
        )
    if not parts.hostname:
        raise MqttError(f"{url!r}: names no broker host; write e.g. mqtt://127.0.0.1/modscope/demo")
    default_port, tls = SCHEMES[scheme]
    try:
        port = parts.port or default_port
    except ValueError:
        raise MqttError(f"{url!r}: the port is not a number from 1 to 65535") from None
    base = unquote(parts.path).strip("/")
    if not base:
        base = f"modscope/{bus_slug(bus)}"
    if _WILDCARDS.search(base) or "//" in base:
        raise MqttError(
            f"{url!r}: the base topic {base!r} has a wildcard (+ #) or an empty level; "
            "give a plain topic such as modscope/line1"
        )
    username = unquote(parts.username) if parts.username else env.get(ENV_USER) or None
    password = unquote(parts.password) if parts.password else env.get(ENV_PASSWORD) or None
    if ca is not None and not tls:
        raise MqttError(f"--mqtt-ca {ca}: a CA file is for TLS; write the URL as mqtts://")
    return MqttTarget(parts.hostname, port, base, tls, username, password, ca)

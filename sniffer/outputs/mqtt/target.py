"""Provides broker addresses: `mqtt://[user:pass@]host[:port]/base/topic` and `mqtts://`.

Credentials can stay out of the shell history and the process list: a password file
(`--mqtt-password-file FILE`, its first line) or `MODSCOPE_MQTT_PASSWORD`, and
`MODSCOPE_MQTT_USER`, fill what the URL leaves out (the URL first, then the file, then
the environment). A password is never shown: `describe()` and every error leave it out,
and `redact()` takes it out of a command line before a bug report prints it. Without a
path the base topic is `modscope/<bus>`, the bus being the port's or the file's name (or
`--bus-name`).
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
_USERINFO = re.compile(
    r"(?i)\b([a-z][a-z0-9+.-]*://)(\S*)@"
)  # to the last @: a password may hold one


def redact(text: str) -> str:
    """`text` with the user and password of any URL in it replaced by `***`."""
    return _USERINFO.sub(lambda m: f"{m.group(1)}***@", text)


def _shown(url: str) -> str:
    """A URL as an error may show it: no credentials, as plain text."""
    return repr(redact(url))


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
    password_file: str | None = None,
    environ: Mapping[str, str] | None = None,
) -> MqttTarget:
    """Parse a broker URL (module doc). MqttError says what is wrong and how to write it,
    never showing the password."""
    env = os.environ if environ is None else environ
    try:
        parts = urlsplit(url)
    except ValueError:
        raise MqttError(
            f"{_shown(url)}: not a broker URL; write mqtt://host[:port]/base/topic"
        ) from None
    scheme = parts.scheme.lower()
    if scheme not in SCHEMES:
        raise MqttError(
            f"{_shown(url)}: not a broker URL; write mqtt://host[:port]/base/topic "
            "(or mqtts:// for TLS)"
        )
    if not parts.hostname:
        raise MqttError(
            f"{_shown(url)}: names no broker host; write e.g. mqtt://127.0.0.1/modscope/demo"
        )
    default_port, tls = SCHEMES[scheme]
    try:
        port = parts.port or default_port
    except ValueError:
        raise MqttError(f"{_shown(url)}: the port is not a number from 1 to 65535") from None
    base = unquote(parts.path).strip("/")
    if not base:
        base = f"modscope/{bus_slug(bus)}"
    if _WILDCARDS.search(base) or "//" in base:
        raise MqttError(
            f"{_shown(url)}: the base topic {base!r} has a wildcard (+ #) or an empty level; "
            "give a plain topic such as modscope/line1"
        )
    username = unquote(parts.username) if parts.username else env.get(ENV_USER) or None
    password = unquote(parts.password) if parts.password else None
    if password is None and password_file is not None:
        password = read_password(password_file)
    if password is None:
        password = env.get(ENV_PASSWORD) or None
    if password is not None and username is None:
        raise MqttError(
            f"{_shown(url)}: a password without a user name; write mqtt://USER@host/... "
            f"or set {ENV_USER}"
        )
    if ca is not None and not tls:
        raise MqttError(f"--mqtt-ca {ca}: a CA file is for TLS; write the URL as mqtts://")
    return MqttTarget(parts.hostname, port, base, tls, username, password, ca)


def read_password(path: str) -> str:
    """The first line of a password file (MqttError naming the file if unreadable)."""
    try:
        with open(path, encoding="utf-8") as f:
            line = f.readline(4096)
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else "not UTF-8 text"
        raise MqttError(
            f"--mqtt-password-file {path}: cannot read it ({reason}); give a readable file "
            "whose first line is the password"
        ) from None
    password = line.rstrip("\r\n")
    if not password:
        raise MqttError(
            f"--mqtt-password-file {path}: the first line is empty; write the password there"
        )
    return password

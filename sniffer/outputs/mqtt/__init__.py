"""Provides modscope over MQTT: a bus published to a broker, and a broker's bus as a source.

`target` parses broker URLs, `payload` turns chunks into `raw` messages and back and
builds the JSON messages, `ha` builds Home Assistant discovery configs (all three pure,
no network), `publish` is the publisher (a paho client with a bounded buffer) and
`subscribe` the source that reads a published bus back. paho-mqtt is an optional extra:
`pip install 'modscope[mqtt]'`.
"""

from __future__ import annotations

import importlib.util

EXTRA_HINT = "MQTT needs the paho-mqtt library: pip install 'modscope[mqtt]'"


class MqttError(Exception):
    """MQTT cannot be used as asked. The message says what to do."""


def require_paho() -> None:
    """Raise MqttError naming the extra when paho-mqtt is not installed."""
    if importlib.util.find_spec("paho") is None or importlib.util.find_spec("paho.mqtt") is None:
        raise MqttError(EXTRA_HINT)

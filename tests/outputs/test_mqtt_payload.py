"""MQTT without a broker: raw message blocks, broker URLs, topic slugs (Home Assistant
discovery: test_ha_discovery.py)."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sniffer.model import Chunk, Direction
from sniffer.outputs.mqtt import MqttError
from sniffer.outputs.mqtt.payload import (
    PayloadError,
    RegisterKey,
    Slugs,
    chunk_from_raw,
    iso_time,
    raw_payload,
    slug,
)
from sniffer.outputs.mqtt.target import bus_slug, parse_target

# -- raw messages -------------------------------------------------------------------------------


def test_raw_payload_is_the_pcapng_block_byte_for_byte() -> None:
    chunk = Chunk(
        b"\x01\x03\x00\x00\x00\x01\x84\x0a", 1.5, 1.25, channel=1, direction=Direction.MASTER
    )
    expected = (
        b"\x06\x00\x00\x00"  # enhanced packet block
        + struct.pack("<I", 64)  # total length: 28 + 20 + 12 + 4
        + b"\x01\x00\x00\x00"  # interface 1 = channel
        + struct.pack("<II", 0, 1_500_000_000)  # 1.5 s in ns (high, low)
        + struct.pack("<II", 20, 20)  # 12-byte RTAC header + 8 bytes
        + struct.pack(">IIBBH", 1, 250_000, 2, 0, 0)  # t_start 1.25 s, RX start
        + b"\x01\x03\x00\x00\x00\x01\x84\x0a"
        + b"\x02\x00\x04\x00\x02\x00\x00\x00"  # epb_flags: outbound (master)
        + b"\x00\x00\x00\x00"  # end of options
        + struct.pack("<I", 64)
    )
    assert raw_payload(chunk) == expected
    assert chunk_from_raw(expected) == chunk


def test_event_chunks_keep_their_event_and_note() -> None:
    chunk = Chunk(b"", 1768464000.5, channel=0, event="port lost", note="/dev/ttyUSB0 vanished")
    back = chunk_from_raw(raw_payload(chunk))
    assert back == chunk
    complete = Chunk(b"", 1768464060.0, event="capture complete")
    assert chunk_from_raw(raw_payload(complete)) == complete


@given(
    data=st.binary(max_size=300),
    t_end=st.one_of(
        st.floats(min_value=1e9, max_value=4e9),  # Unix times
        st.integers(min_value=0, max_value=10**15).map(lambda ns: ns / 1e9),  # relative
    ),
    start_us=st.one_of(st.none(), st.integers(min_value=1, max_value=4_000_000_000 * 10**6)),
    channel=st.integers(min_value=0, max_value=255),
    direction=st.sampled_from(list(Direction)),
    event=st.sampled_from(["", "framing error", "parity error", "data lost", "reconnect", "break"]),
    note=st.text(max_size=40).filter(lambda s: "\x00" not in s),
)
def test_raw_round_trip(
    data: bytes,
    t_end: float,
    start_us: int | None,
    channel: int,
    direction: Direction,
    event: str,
    note: str,
) -> None:
    """Every chunk a source makes (start times in whole microseconds) comes back equal."""
    t_start = None if start_us is None else start_us / 1e6
    if event and ": " in note:
        note = note.replace(": ", ":")
    chunk = Chunk(data, t_end, t_start, channel, direction, event, note if event or data else "")
    back = chunk_from_raw(raw_payload(chunk))
    assert back.data == chunk.data and back.t_end == chunk.t_end
    assert back.channel == channel and back.direction == direction
    assert back.event == chunk.event and back.note == chunk.note
    if t_start is None:
        assert back.t_start is None
    else:
        assert back.t_start is not None and abs(back.t_start - t_start) < 1e-6


@pytest.mark.parametrize(
    ("payload", "words"),
    [
        (b"", "shorter than"),
        (b"\x01\x00\x00\x00" + b"\x00" * 28, "not an enhanced packet block"),
        (b"\x06\x00\x00\x00\x40\x00\x00\x00" + b"\x00" * 24, "does not match"),
        (
            b"\x06\x00\x00\x00\x24\x00\x00\x00"
            + b"\x00" * 12
            + b"\x04\x00\x00\x00" * 2
            + b"\x00" * 4
            + b"\x24\x00\x00\x00",
            "shorter than the 12-byte RTAC header",
        ),
    ],
)
def test_broken_raw_messages_are_named(payload: bytes, words: str) -> None:
    with pytest.raises(PayloadError, match=words):
        chunk_from_raw(payload)


# -- broker URLs --------------------------------------------------------------------------------


def test_url_with_credentials_port_and_base() -> None:
    t = parse_target("mqtt://ann:s%40cret@broker.site:1884/plant/line1", environ={})
    assert (t.host, t.port, t.base, t.tls) == ("broker.site", 1884, "plant/line1", False)
    assert (t.username, t.password) == ("ann", "s@cret")
    assert t.topic("unit", "3", "status") == "plant/line1/unit/3/status"
    assert t.describe() == "mqtt://broker.site:1884/plant/line1"  # no password shown


def test_default_base_is_the_bus_name_and_env_gives_credentials() -> None:
    env = {"MODSCOPE_MQTT_USER": "pi", "MODSCOPE_MQTT_PASSWORD": "pw"}
    t = parse_target("mqtts://10.0.0.5", bus="/dev/ttyUSB0", environ=env, ca="/etc/ca.pem")
    assert (t.port, t.tls, t.base, t.ca) == (8883, True, "modscope/ttyUSB0", "/etc/ca.pem")
    assert (t.username, t.password) == ("pi", "pw")
    assert bus_slug("captures/demo.pcapng") == "demo"


@pytest.mark.parametrize(
    ("url", "words"),
    [
        ("tcp://host/x", "mqtt://host"),
        ("mqtt:///x", "names no broker host"),
        ("mqtt://host:99999/x", "port"),
        ("mqtt://host/a/+/b", "wildcard"),
    ],
)
def test_bad_urls_say_how_to_write_them(url: str, words: str) -> None:
    with pytest.raises(MqttError, match=words):
        parse_target(url, environ={})


def test_ca_needs_tls() -> None:
    with pytest.raises(MqttError, match="mqtts://"):
        parse_target("mqtt://host/x", ca="ca.pem", environ={})


# -- names --------------------------------------------------------------------------------------


def test_slugs_are_unique_per_unit() -> None:
    assert slug("04.9A: Power Factor Read Point") == "04-9a-power-factor-read-point"
    slugs = Slugs()
    assert slugs.add(RegisterKey(3, "coils", 3, "Energy Save")) == "energy-save"
    assert slugs.add(RegisterKey(3, "holding_registers", 9, "Energy Save")) == (
        "energy-save-holding-registers-9"
    )
    assert slugs.add(RegisterKey(4, "coils", 3, "Energy Save")) == "energy-save"
    assert slugs.add(RegisterKey(3, "coils", 3, "Energy Save")) == "energy-save"


def test_iso_time_only_for_dates() -> None:
    assert iso_time(1768464000.5) == "2026-01-15T08:00:00.500000Z"
    assert iso_time(12.5) is None

"""Tests that the existing readers say what their timestamps mean and how far their
direction labels hold (`SourceInfo.stamps`, `resolution`, `labels`)."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from dissectors.checks import with_crc
from sniffer.model import Labels, Stamp
from sniffer.sources import ReadOptions, open_capture
from sniffer.sources.pcapng_writer import (
    EPB_FLAG_INBOUND,
    EPB_FLAG_OUTBOUND,
    LINKTYPE_RTAC_SERIAL,
    LINKTYPE_USER0,
    PcapngWriter,
    rtac_record,
)

CAPTURES = Path(__file__).parent.parent / "captures"
REQUEST = with_crc(bytes.fromhex("010300000002"))
T0 = 1_714_564_800.0


def pcapng(tmp_path: Path, linktype: int, packet: bytes, flags: int | None) -> Path:
    stream = io.BytesIO()
    writer = PcapngWriter(stream)
    iface = writer.add_interface(linktype)
    writer.write_packet(iface, T0, packet, flags=flags)
    path = tmp_path / "c.pcapng"
    path.write_bytes(stream.getvalue())
    return path


@pytest.mark.parametrize(
    ("linktype", "start", "flags", "stamps", "labels"),
    [
        (LINKTYPE_USER0, None, None, Stamp.READ_END, Labels.NONE),
        (LINKTYPE_USER0, None, EPB_FLAG_INBOUND, Stamp.READ_END, Labels.HINT),
        (LINKTYPE_USER0, None, EPB_FLAG_OUTBOUND, Stamp.READ_END, Labels.HINT),
        (LINKTYPE_RTAC_SERIAL, T0 - 0.004, None, Stamp.EXACT, Labels.NONE),
        (LINKTYPE_RTAC_SERIAL, T0, None, Stamp.READ_END, Labels.NONE),
    ],
)
def test_pcapng_says_what_its_first_packet_shows(
    tmp_path: Path,
    linktype: int,
    start: float | None,
    flags: int | None,
    stamps: Stamp,
    labels: Labels,
) -> None:
    packet = rtac_record(start, REQUEST) if start is not None else REQUEST
    info = open_capture(pcapng(tmp_path, linktype, packet, flags)).info
    assert (info.stamps, info.labels) == (stamps, labels)


def test_raw_has_no_time(tmp_path: Path) -> None:
    raw = tmp_path / "raw.bin"
    raw.write_bytes(REQUEST * 2)
    info = open_capture(raw).info
    assert (info.format, info.stamps, info.labels) == ("raw", Stamp.NONE, Labels.NONE)


@pytest.mark.parametrize(
    ("name", "stamps", "resolution", "labels"),
    [
        ("text2pcap_modbus.txt", Stamp.PRINT, 1e-6, Labels.HINT),
        ("od_modbus.txt", Stamp.NONE, 0.0, Labels.NONE),
        ("socat_modbus.log", Stamp.PRINT, 1e-6, Labels.HINT),
    ],
)
def test_hex_dumps(name: str, stamps: Stamp, resolution: float, labels: Labels) -> None:
    info = open_capture(CAPTURES / "hexdump" / name).info
    assert (info.stamps, info.labels) == (stamps, labels)
    assert info.resolution == pytest.approx(resolution)


def test_sigrok_is_exact_and_certain_with_a_probe_per_direction() -> None:
    path = CAPTURES / "sigrok" / "wizmodbus" / "wizmodbus.sr"
    two = open_capture(path, ReadOptions(baud=9600, parity="N", probes=("RX", "TX"))).info
    one = open_capture(path, ReadOptions(baud=9600, parity="N", probes=("RX",))).info
    assert (two.stamps, two.labels) == (Stamp.EXACT, Labels.CERTAIN)
    assert (one.stamps, one.labels) == (Stamp.EXACT, Labels.NONE)


@pytest.mark.parametrize(
    ("name", "stamps", "resolution", "labels", "network"),
    [
        ("evcc_rtu.log", Stamp.PRINT, 1.0, Labels.HINT, False),  # Go's log.Ltime
        ("evcc_tcp.log", Stamp.PRINT, 1.0, Labels.CERTAIN, True),  # a socket's two ways
        ("modbustools_client.log", Stamp.PRINT, 1e-3, Labels.HINT, False),
        ("modbustools_ascii_notime.log", Stamp.NONE, 0.0, Labels.HINT, False),
        ("modbustools_server_tcp.log", Stamp.PRINT, 1.0, Labels.CERTAIN, True),
        ("cas_newest_first.log", Stamp.PRINT, 1.0, Labels.HINT, False),
        ("mbpoll_tcp.log", Stamp.NONE, 0.0, Labels.CERTAIN, True),
        ("libmodbus_client.log", Stamp.NONE, 0.0, Labels.HINT, False),
        ("pymodbus_sync_37.log", Stamp.PRINT, 1e-3, Labels.HINT, False),
        ("pymodbus_sync_38.log", Stamp.PRINT, 1e-3, Labels.HINT, False),
        ("pymodbus_tcp.log", Stamp.PRINT, 1e-3, Labels.CERTAIN, True),
        ("saleae_logic1_ascii_hex.csv", Stamp.EXACT, 0.0, Labels.NONE, False),
    ],
)
def test_logs(name: str, stamps: Stamp, resolution: float, labels: Labels, network: bool) -> None:
    info = open_capture(CAPTURES / "logs" / name).info
    assert (info.stamps, info.labels, info.network) == (stamps, labels, network)
    assert info.resolution == pytest.approx(resolution)

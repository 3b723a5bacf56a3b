"""Provides the reading of Modbus carried over Ethernet: packets, TCP streams, carriers.

The pcap and pcapng readers hand packets of Ethernet-family link types (see
`packets.NET_LINKTYPES`) to a `NetDecoder` (`decoder`), which reassembles TCP (`tcp`),
tells Modbus TCP from RTU over TCP/UDP (`carrier`), and gives chunks with a channel per
connection direction. `for_capture` is the one call the readers make.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace

from sniffer.model import Labels, SourceInfo, Stamp
from sniffer.sources.base import ReadOptions
from sniffer.sources.net.carrier import ChannelLabel, parse_label, summary
from sniffer.sources.net.decoder import NetDecoder
from sniffer.sources.net.packets import NET_LINKTYPES

__all__ = [
    "NET_LINKTYPES",
    "ChannelLabel",
    "NetDecoder",
    "for_capture",
    "parse_label",
    "summary",
]


def for_capture(
    info: SourceInfo,
    linktypes: Iterable[tuple[int, int]],
    options: ReadOptions,
    warnings: list[str],
    *,
    nanoseconds: bool = False,
) -> tuple[SourceInfo, NetDecoder | None]:
    """A decoder for a capture whose interfaces are `linktypes` ((channel, link type)
    pairs), and its info saying what network timestamps and directions mean; `(info,
    None)` when no interface is Ethernet-family."""
    pairs = list(linktypes)
    if not any(linktype in NET_LINKTYPES for _, linktype in pairs):
        return info, None
    reserved = frozenset(ch for ch, linktype in pairs if linktype not in NET_LINKTYPES)
    decoder = NetDecoder(
        info.channels,
        warnings,
        carrier=options.carrier,
        port=options.port,
        reserved=reserved,
    )
    for ch, linktype in pairs:
        if linktype in NET_LINKTYPES:
            info.channels.pop(ch, None)  # the connections' channels replace the interface's
    info = replace(
        info,
        stamps=Stamp.FRAME_END,
        resolution=1e-9 if nanoseconds else 1e-6,
        labels=Labels.CERTAIN,
        network=True,
    )
    return info, decoder

"""Provides capture readers: each turns a file into chunks of timestamped bytes.

`open_capture(path, options)` recognises the format from the content, not the name, and
returns a `Capture`: what the file says about itself (`info`) and its chunks in time
order. Readers never raise on bad content once the format is recognised: a truncated or
damaged file gives every complete record and a warning naming the offset.

Formats (see each module): pcap and pcapng with link types 147, 250 and 252 (`pcap`),
and with Ethernet-family link types carrying Modbus TCP or RTU over TCP/UDP (`net`),
sigrok `.sr` logic captures decoded as UART (`sigrok`), `socat -x -v` logs and
text2pcap-style hex dumps (`hexdump`), Saleae Logic CSV exports (`saleae`), text logs
of ESPHome, pymodbus, libmodbus and mbpoll, evcc, ModbusTools, CAS Modbus Scanner and
serial monitors (`logs`, a module per format; logs of Modbus TCP framed as Modbus TCP),
and raw binary (`raw`).
Recognition order is in `detect`. The pcapng writer is `pcapng_writer`.
"""

from __future__ import annotations

from pathlib import Path

from sniffer.errors import CaptureError
from sniffer.model import SourceInfo, Stamp
from sniffer.sources import detect
from sniffer.sources.base import Capture, ReadOptions
from sniffer.sources.hexdump import open_hexdump, open_socat
from sniffer.sources.logs import LOG_FORMATS, open_log
from sniffer.sources.pcap import open_pcap, open_pcapng
from sniffer.sources.raw import raw_chunks
from sniffer.sources.saleae import open_saleae
from sniffer.sources.sigrok import open_sigrok

__all__ = ["Capture", "CaptureError", "ReadOptions", "open_capture"]


def _head(path: Path) -> bytes:
    try:
        with path.open("rb") as handle:
            return handle.read(detect.HEAD_SIZE)
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise CaptureError(
            f"{path}: cannot be read ({reason}); check the path and its permissions"
        ) from None


def open_capture(path: str | Path, options: ReadOptions | None = None) -> Capture:
    """Open a capture file of any supported format, recognised from its content."""
    options = options or ReadOptions()
    path = Path(path)
    if not path.exists():
        raise CaptureError(f"{path}: no such file; give the path of a capture to replay")
    if path.is_dir():
        raise CaptureError(f"{path}: is a folder; give the path of a capture file")
    try:
        options.line(None)
    except ValueError as exc:
        raise CaptureError(f"{path}: {exc}") from None
    head = _head(path)
    if not head:
        raise CaptureError(
            f"{path}: the file is empty; expected a capture (pcapng, pcap, sigrok .sr, "
            "hex dump or raw bytes)"
        )
    kind = detect.sniff(head)
    if kind == detect.PCAPNG:
        return open_pcapng(path, options)
    if kind == detect.PCAP:
        return open_pcap(path, options, head)
    if kind == detect.SIGROK:
        return open_sigrok(path, options)
    if kind == detect.SOCAT:
        return open_socat(path, options)
    if kind == detect.HEXDUMP:
        return open_hexdump(path, options)
    if kind == detect.SALEAE:
        return open_saleae(path, options)
    if kind in LOG_FORMATS:
        return open_log(path, options, kind)
    line = options.line(None)
    info = SourceInfo(path=str(path), format="raw", line=line, stamps=Stamp.NONE)
    return Capture(info=info, _chunks=raw_chunks(path, line))

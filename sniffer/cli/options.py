"""Provides the options several commands share (line settings, dictionaries, output) and
their reading into the core's types; user mistakes become `UsageError`."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from dissectors.dictionary.bus import parse_unit_binding
from sniffer.errors import UsageError
from sniffer.meaning.annotate import Binding, load_bindings
from sniffer.model import LineSettings
from sniffer.outputs.listing import FORMATS
from sniffer.outputs.parallel import MAX_AUTO, MIN_ROWS, parse_jobs
from sniffer.sources import ReadOptions

if TYPE_CHECKING:
    SubParsers = argparse._SubParsersAction[argparse.ArgumentParser]
else:
    SubParsers = Any

Command = Callable[[argparse.Namespace, TextIO, TextIO], int]
"""A command: (parsed arguments, stdout, stderr) -> exit status."""


def add_line_options(p: argparse.ArgumentParser) -> None:
    """The line settings every command takes (a file's own settings are the default)."""
    g = p.add_argument_group("line settings (default: what the capture recorded, else 19200 8E1)")
    g.add_argument("-b", "--baud", type=int, metavar="N", help="baud rate (-b as in mbpoll)")
    g.add_argument("--bytesize", type=int, choices=(7, 8), help="data bits")
    g.add_argument(
        "-P", "--parity", type=str.upper, choices=("N", "E", "O"), help="parity (-P as in mbpoll)"
    )
    g.add_argument("--stopbits", type=int, choices=(1, 2), help="stop bits")
    g.add_argument(
        "--mode", choices=("rtu", "ascii", "auto"), help="framing (default auto: from the traffic)"
    )
    g.add_argument(
        "--timeout",
        type=float,
        metavar="S",
        help="response timeout in seconds (default: 0.2 s plus a longest frame's time; "
        "3 s for Modbus TCP)",
    )


def add_network_options(p: argparse.ArgumentParser) -> None:
    """`--carrier` and `--port` for network captures (commands that read files; `live`
    has its own `--port`, the serial port)."""
    n = p.add_argument_group("network captures (pcap/pcapng of Ethernet, Wi-Fi, loopback)")
    n.add_argument(
        "--carrier",
        choices=("tcp", "rtu-over-tcp", "rtu-over-udp"),
        help="what every connection carries: Modbus TCP (MBAP header) or raw RTU frames "
        "in TCP or UDP (default: told from the content of each connection)",
    )
    n.add_argument(
        "--port",
        type=int,
        metavar="N",
        help="read only traffic to or from port N, and take the side on N for the server "
        "(e.g. --port 4001 for a serial server's RTU over TCP)",
    )


def add_index_option(p: argparse.ArgumentParser) -> None:
    """`--no-index`: read the capture itself, not its sidecar index (see docs/performance.md)."""
    p.add_argument(
        "--no-index",
        action="store_true",
        help="read the capture itself even where a sidecar index of it (FILE.modscope-index) "
        "fits; a capture of 4 MB or more gets one once read (MODSCOPE_NO_INDEX=1 does the same)",
    )


def add_device_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("device dictionaries")
    g.add_argument("--bus", metavar="FILE", help="bus file binding slave addresses to models")
    g.add_argument(
        "--unit",
        action="append",
        default=[],
        metavar="ADDR=MODEL[:LABEL]",
        help="bind one address, e.g. --unit 3=rvs-dn or --unit '3=rvs-dn:Pump 1' "
        "(repeatable; wins over --bus)",
    )
    g.add_argument(
        "--dict",
        action="append",
        default=[],
        metavar="FILE",
        help="a dictionary of your own (repeatable)",
    )


def add_output_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("output")
    g.add_argument(
        "--format",
        choices=FORMATS,
        help="plain listing instead of the TUI: text, jsonl or csv (default when piped: text)",
    )
    g.add_argument("--time", choices=("rel", "abs"), default="rel", help="time column style")
    add_raw_csv_option(g)


def add_jobs_option(p: argparse._ActionsContainer) -> None:
    """`--jobs`: processes writing a listing or an export (see `sniffer.outputs.parallel`)."""
    p.add_argument(
        "--jobs",
        type=parse_jobs,
        default=None,
        metavar="N|auto",
        help="write the rows with N processes, each over a range of rows, joined into the "
        "same bytes in the same order (Linux; elsewhere one process). 1: one process. "
        f"Default auto: the CPUs this process may use, at most {MAX_AUTO}, for "
        f"{MIN_ROWS:,} rows or more, and one process when writing to a terminal",
    )


def add_raw_csv_option(g: argparse._ActionsContainer) -> None:
    """`--raw-csv`: CSV text cells without the leading ' that stops spreadsheets running
    them as formulas (see `sniffer.text.csv_cell`)."""
    g.add_argument(
        "--raw-csv",
        action="store_true",
        help="CSV: write text starting with = + - @ as it is, without the leading ' that "
        "keeps a spreadsheet from running it as a formula (for programs, not spreadsheets)",
    )


def read_options(args: argparse.Namespace) -> ReadOptions:
    """The line options as the capture readers take them; UsageError when they cannot
    make a line (a baud rate of 0), so the reader never sees them."""
    options = ReadOptions(
        baud=args.baud,
        bytesize=args.bytesize,
        parity=args.parity,
        stopbits=args.stopbits,
        mode=args.mode,
        probes=tuple(getattr(args, "probe", None) or ()),
        invert=bool(getattr(args, "invert", False)),
        carrier=getattr(args, "carrier", None),
        port=getattr(args, "port", None),
    )
    port = options.port
    if port is not None and not 0 < port < 65536:
        raise UsageError(f"--port must be a TCP or UDP port, 1 to 65535, not {port}")
    line_of(options)
    timeout = getattr(args, "timeout", None)
    if timeout is not None and not timeout > 0:
        raise UsageError(f"--timeout must be a positive number of seconds, not {timeout:g}")
    return options


def line_of(options: ReadOptions, from_file: LineSettings | None = None) -> LineSettings:
    """The line the options describe (over a file's own settings); UsageError if invalid."""
    try:
        return options.line(from_file)
    except ValueError as exc:
        raise UsageError(f"line settings: {exc}") from None


def line_warnings(options: ReadOptions, from_file: LineSettings | None, path: str) -> list[str]:
    """The flags win over what a capture recorded; say so where they contradict it."""
    if from_file is None:
        return []
    given = {
        "--baud": (options.baud, from_file.baud),
        "--bytesize": (options.bytesize, from_file.bytesize),
        "--parity": (options.parity, from_file.parity),
        "--stopbits": (options.stopbits, from_file.stopbits),
    }
    clash = [f"{flag} {mine}" for flag, (mine, its) in given.items() if mine not in (None, its)]
    if not clash:
        return []
    return [
        f"{path}: recorded at {from_file.describe()}; read with {', '.join(clash)} as the "
        "command line says (drop the flags to use the recorded settings)"
    ]


def bindings_for(args: argparse.Namespace, default_bus: Path | None = None) -> dict[int, Binding]:
    """Bindings from --bus and --unit (which win over the bus file); two --unit options
    for one address are a mistake, not a choice of the last."""
    seen: dict[int, str] = {}
    for text in args.unit:
        try:
            address = parse_unit_binding(text).address
        except ValueError:
            continue  # load_bindings says what is wrong with it
        if address in seen:
            raise UsageError(
                f"--unit {seen[address]!r} and --unit {text!r} both bind address {address}; "
                "keep one"
            )
        seen[address] = text
    bus = args.bus or (str(default_bus) if default_bus and default_bus.exists() else None)
    return load_bindings(bus, args.unit, args.dict)


READ_EPILOG = """\
exit status:
  0  the whole capture was read
  1  it was read with warnings (a truncated file, a damaged record): the rows
     before and after the damage are there, the warnings say where
  2  nothing usable was read, or a user error (one line says what to fix)
"""

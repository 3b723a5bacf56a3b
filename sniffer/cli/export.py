"""Provides `modscope export`: a capture written out for Wireshark (pcapng) or as
CSV/JSONL tables of frames, transactions or register values."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import BinaryIO, TextIO

from sniffer.cli.filtering import add_filter_options, query_of
from sniffer.cli.heap import settle
from sniffer.cli.options import (
    READ_EPILOG,
    SubParsers,
    add_device_options,
    add_index_option,
    add_jobs_option,
    add_line_options,
    add_network_options,
    add_raw_csv_option,
    bindings_for,
    line_warnings,
    read_options,
)
from sniffer.cli.progress import Progress
from sniffer.cli.replaying import (
    PartWriter,
    each_segment,
    first_pass,
    lister_of,
    stdin_copy,
    write_streamed,
)
from sniffer.cli.verdicts import finish_read
from sniffer.errors import UsageError
from sniffer.meaning.describe import Describer
from sniffer.meaning.query import Query
from sniffer.model import Stamp
from sniffer.outputs.export import (
    EXPORT_FORMATS,
    EXTENSIONS,
    PCAP_STYLES,
    REGISTER_COLUMNS,
    TRANSACTION_COLUMNS,
    WHATS,
    Moves,
    PcapExporter,
    exported_timing,
    register_records,
    transaction_records,
    write_table,
)
from sniffer.outputs.parallel import workers_for, write_binary
from sniffer.outputs.parquet import ParquetError, ParquetTable, require_pyarrow
from sniffer.session.session import Session, open_session
from sniffer.session.streamed import Learnt
from sniffer.sources import Capture
from sniffer.text import plain

EXPORT_EXAMPLES = """\
examples:
  modscope export bus.pcapng -o frames.pcapng          for Wireshark, decoded as it opens
  modscope export bus.pcapng -o raw.pcapng --as rtu    the RTU bytes as on the line
  modscope export bus.pcapng -o frames.jsonl           one JSON object per frame
  modscope export bus.pcapng -o regs.csv --what registers

"""


def output_format(path: str, fmt: str | None) -> str:
    """The export format: --format if given, else from the output's extension."""
    if fmt is not None:
        return fmt
    if path == "-":
        raise UsageError("writing to standard output needs --format (text, jsonl, csv, pcapng)")
    found = EXTENSIONS.get(Path(path).suffix.lower())
    if found is None:
        raise UsageError(
            f"{path}: cannot tell the format from the name; give --format "
            f"({', '.join(EXPORT_FORMATS)}) or end the name in "
            ".pcapng, .parquet, .csv, .jsonl or .txt"
        )
    return found


def cmd_export(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    if args.file == "-":  # as replay -: the bytes kept in a file, read from its content
        output_format(args.output, args.format)  # a usage error before stdin is read
        with stdin_copy() as path:
            return _export(args, out, err, path, "standard input")
    return _export(args, out, err, Path(args.file), None)


def _export(
    args: argparse.Namespace, out: TextIO, err: TextIO, source: Path, given: str | None
) -> int:
    fmt = output_format(args.output, args.format)
    what = args.what
    if args.style != "modbus-tcp" and fmt != "pcapng":
        raise UsageError(f"--as {args.style} is for a pcapng export; drop it or write .pcapng")
    if fmt == "pcapng" and what != "frames":
        raise UsageError(f"a pcapng export holds frames; --what {what} needs csv or jsonl")
    if fmt == "text" and what != "frames":
        raise UsageError(f"--what {what} is a table: write it as csv or jsonl")
    if fmt == "parquet":  # said before the capture is read, not after
        if args.output == "-":
            raise UsageError("a Parquet table goes to a file: give -o NAME.parquet")
        try:
            require_pyarrow()
        except ParquetError as exc:
            raise UsageError(str(exc)) from None
    if given is None and args.output != "-" and Path(args.output).resolve() == source.resolve():
        raise UsageError(f"{args.output}: is the capture being read; choose another output")
    query = query_of(args, err)
    bindings = bindings_for(args)
    options = read_options(args)

    def anew(index: bool) -> tuple[Session, Capture]:
        return open_session(source, options, bindings=bindings, timeout=args.timeout, index=index)

    session, capture = anew(not args.no_index)
    told = line_warnings(options, capture.info.recorded_line, given or str(source))
    progress = Progress(err, given or source.name, None if given else source)
    settle()
    # the capture is written a segment at a time, as replay lists it
    # (`sniffer.session.streamed`)
    moves = [Moves(session.line)]  # (pcapng: the first pass's, for its interface block)

    def moved(s: Session) -> None:
        if not s.base:  # a first segment: of a pass learnt again too (`first_pass`)
            moves[0] = Moves(s.line)
        moves[0].add(s.store)

    also = moved if fmt == "pcapng" else None
    session, capture, learnt = first_pass(
        session, capture, progress.reading, anew, not args.no_index, also
    )
    progress.done()
    session.warnings.extend(capture.warnings)
    for note in [*capture.info.notes, *session.notes]:
        err.write(f"modscope: note: {plain(note)}\n")
    for w in [*told, *session.warnings]:
        err.write(f"modscope: warning: {plain(w)}\n")
    status = finish_read(capture, session, err)
    # what the times are worth over the whole capture (pcapng: its interface block)
    timing = exported_timing(session.store, session.line, moves[0].moved)
    n = _streamed(
        args, out, given or source.name, fmt, learnt, anew(learnt.indexed), query, progress, timing
    )
    progress.done()
    if fmt == "pcapng":
        err.write(f"{plain(args.output)}: {n} packets {_carried(args.style)}\n")
    elif args.output != "-":
        err.write(f"{plain(args.output)}: {n} {what} ({fmt})\n")
    return status  # a truncated capture exits 1 here too: the output holds what was read


def _records_writer(what: str, fmt: str, raw: bool) -> PartWriter:
    """The part writer of a table of transactions or registers, as CSV or JSONL."""
    maker = transaction_records if what == "transactions" else register_records
    columns = TRANSACTION_COLUMNS if what == "transactions" else REGISTER_COLUMNS

    def write(
        stream: TextIO, part: Iterable[int], header: bool, describer: Describer, base: int
    ) -> int:
        records = maker(describer, part, base)
        return write_table(stream, fmt, columns, records, raw_csv=raw, header=header)

    return write


def _text_writer(args: argparse.Namespace, fmt: str, origin: float | None) -> PartWriter:
    if args.what == "frames":
        return lister_of(args, fmt, origin)
    return _records_writer(args.what, fmt, bool(args.raw_csv))


def _streamed(
    args: argparse.Namespace,
    out: TextIO,
    name: str,
    fmt: str,
    learnt: Learnt,
    second: tuple[Session, Capture],
    query: Query | None,
    progress: Progress,
    timing: tuple[Stamp, float],
) -> int:
    """The export of one capture a segment at a time, in memory flat in its size:
    `learnt` from the first pass, `second` a new session on the capture, which hands on
    each segment's rows as it drops them (`each_segment`), `timing` what the first pass
    found the times worth (`exported_timing`: a pcapng's interface block). The bytes are
    those of the export of one store of every row. Returns how many rows, records or
    packets were written."""
    shown = progress.share if args.output != "-" else None  # (not over a listing on a tty)
    if fmt == "pcapng":
        session = second[0]
        binary = sys.stdout.buffer if args.output == "-" else _open_binary(args.output)
        try:
            exporter = PcapExporter(
                binary,
                session.describer,  # (not read: `timing` is given; each segment's from then)
                session.line,
                name=name,
                style=args.style,
                timing=timing,
            )
            return _packets_streamed(exporter, args, learnt, second, query, shown)
        finally:
            if args.output != "-":
                binary.close()
    if fmt == "parquet":
        try:
            with ParquetTable(args.output, args.what) as table:

                def take(rows: Sequence[int], describer: Describer, base: int) -> None:
                    table.add(describer, rows, base)

                each_segment(args, learnt, second, query, take, shown)
                return table.close()
        except ParquetError as exc:
            raise UsageError(str(exc)) from None
    text = out if args.output == "-" else _open_text(args.output)
    try:
        writer = _text_writer(args, fmt, learnt.origin)
        return write_streamed(text, args, learnt, second, query, writer, shown)
    finally:
        if text is not out:
            text.close()


def _carried(style: str) -> str:
    """What a pcapng export's packets carry, as its last line says."""
    if style == "modbus-tcp":
        return "(link type 252, Modbus/TCP, decoded by Wireshark as is)"
    return "(link type 252, Modbus RTU byte for byte)"


def _packets_streamed(
    exporter: PcapExporter,
    args: argparse.Namespace,
    learnt: Learnt,
    second: tuple[Session, Capture],
    query: Query | None,
    shown: Callable[[int, int], None] | None = None,
) -> int:
    """The pcapng export of one capture a segment at a time, in memory flat in
    its size, as `write_streamed` lists it: `exporter` has written the section and
    interface blocks (what the times are worth over the whole capture, from the first
    pass: `Moves`), `learnt` is the first pass's, `second` a new session on the capture,
    which writes each segment's packets as it drops it (`segments`), `--jobs` processes
    sharing each segment's rows. The bytes are those of the export of one store of
    every row: the transaction ids are the rows' numbers in the whole capture
    (`PcapExporter.base`), the rows described as after every row. Returns how many
    packets were written."""
    count = 0

    def take(rows: Sequence[int], describer: Describer, base: int) -> None:
        nonlocal count
        exporter.describer, exporter.base = describer, base

        def packets(stream: BinaryIO, part: Sequence[int], first: bool) -> int:
            if first:
                return exporter.write(part)
            worker = PcapExporter(
                stream, describer, exporter.line, name="", style=exporter.style, header=False
            )
            worker.base = base
            return worker.write(part)

        stream = exporter.stream
        count += write_binary(stream, rows, workers_for(args.jobs, len(rows), stream), packets)

    each_segment(args, learnt, second, query, take, shown)
    return count


def _open_binary(path: str) -> BinaryIO:
    try:
        return open(path, "wb")
    except OSError as exc:
        raise UsageError(
            f"{path}: cannot be written ({exc.strerror or exc}); choose a folder you can write to"
        ) from None


def _open_text(path: str) -> TextIO:
    try:
        return open(path, "w", encoding="utf-8", newline="")
    except OSError as exc:
        raise UsageError(
            f"{path}: cannot be written ({exc.strerror or exc}); choose a folder you can write to"
        ) from None


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "export",
        help="write a capture's frames for Wireshark, or frames/transactions/registers as "
        "CSV or JSONL",
        description=(
            "Frame, pair and decode a capture, then write it out: as pcapng that Wireshark "
            "opens decoded with no configuration (every request a query, every answer a "
            "response, paired by transaction id with the time between them; the RTU or "
            "ASCII bytes, the CRC or LRC verdict and every problem in the packet "
            "comment; CRC errors flagged), or as CSV/JSONL tables of frames, "
            "transactions or register values. The format follows the output's extension "
            "(.pcapng, .csv, .jsonl, .txt) unless --format says."
        ),
        epilog=EXPORT_EXAMPLES + READ_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("file", help="capture file (any format replay reads), - for standard input")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output file, or -")
    p.add_argument(
        "--what",
        choices=WHATS,
        default="frames",
        help="frames (default), transactions (request + answer per row) or registers",
    )
    p.add_argument("--format", choices=EXPORT_FORMATS, help="default: from OUT's extension")
    p.add_argument(
        "--as",
        dest="style",
        choices=PCAP_STYLES,
        default="modbus-tcp",
        help="pcapng: each frame's PDU for Wireshark's Modbus/TCP dissector (modbus-tcp, "
        "the default: every function code classified and paired) or the RTU frame byte "
        "for byte for its RTU dissector (rtu)",
    )
    p.add_argument("--time", choices=("rel", "abs"), default="rel", help="text time column")
    add_raw_csv_option(p)
    add_jobs_option(p)
    add_line_options(p)
    add_network_options(p)
    add_index_option(p)
    g = p.add_argument_group("logic analyser captures (.sr)")
    g.add_argument("--probe", action="append", metavar="NAME|N", help="as for replay")
    g.add_argument("--invert", action="store_true", help="idle-low levels")
    add_device_options(p)
    add_filter_options(p)
    p.set_defaults(func=cmd_export)

"""Provides the CSV import: a plain register list to a device dictionary.

Rows become the data a TOML dictionary holds and are checked by the same builder, so
errors name the file and row line too.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

from .build import FORMAT, Builder
from .device import DeviceDictionary
from .errors import DictionaryError, nearest, raise_all
from .limits import MAX_DIGITS, check_size
from .reader import Source
from .textfile import read_text
from .tomlpos import LineMap

CSV_REQUIRED = ("table", "address", "name")
CSV_COLUMNS = (
    *CSV_REQUIRED,
    "type",
    "unit",
    "scale",
    "offset",
    "word_order",
    "access",
    "description",
    "length",
    "bit",
    "width",
    "byte",
    "min",
    "max",
    "default",
    "enum",
    "precision",
)
_CSV_INTEGERS = ("length", "bit", "width", "precision")
_CSV_NUMBERS = ("scale", "offset", "min", "max")


def _csv_number(text: str, decimal_comma: bool = False) -> int | float | None:
    text = text.strip()
    if len(text) > MAX_DIGITS:
        # a hex integer this long converts, but Python refuses to print it in decimal,
        # and no register address or value needs a thousand digits
        return None
    if decimal_comma and re.fullmatch(r"[+-]?[0-9]+,[0-9]+", text):
        text = text.replace(",", ".")
    try:
        return (
            int(text, 0) if re.fullmatch(r"[+-]?(0[xX][0-9a-fA-F]+|[0-9]+)", text) else float(text)
        )
    except ValueError:
        return None


def _csv_enum(path: str, line: int, text: str) -> dict[str, str]:
    names: dict[str, str] = {}
    for part in re.split(r"[;|]", text):
        if not part.strip():
            continue
        key, eq, name = part.partition("=")
        if not eq or not key.strip() or not name.strip():
            raise DictionaryError(
                path,
                line,
                f"enum part '{part.strip()}' is not NUMBER=NAME",
                'write the enum cell as "0=Stop; 1=Run"',
            )
        names[key.strip()] = name.strip()
    return names


MAX_COLUMN_PROBLEMS = 20  # unknown or repeated header columns told one by one; then counted


def _cells(name: str, line: int, text: str, dialect: type[csv.Dialect] | csv.Dialect) -> list[str]:
    """The cells of one line; a DictionaryError naming the line when the csv module
    refuses it (a cell over its field size limit, 131,072 characters; a NUL)."""
    try:
        return next(csv.reader([text], dialect), [])
    except csv.Error as exc:
        raise DictionaryError(
            name, line, f"the line cannot be read as CSV ({exc})", "shorten or fix the line"
        ) from None


def _csv_row(
    name: str, header: list[str], line: int, row_text: str, dialect: type[csv.Dialect] | csv.Dialect
) -> dict[str, object] | None:
    """One register row as the entry a TOML dictionary would hold (None: an empty row)."""
    decimal_comma = dialect.delimiter != ","
    cells = _cells(name, line, row_text, dialect)
    if not any(cell.strip() for cell in cells):
        return None
    if len(cells) > len(header):
        raise DictionaryError(
            name,
            line,
            f"{len(cells)} cells for {len(header)} columns",
            "quote cells that hold the delimiter",
        )
    entry: dict[str, object] = {}
    for column, cell in zip(header, cells, strict=False):
        cell = cell.strip()
        if not cell:
            continue
        if column == "address":
            number = _csv_number(cell)
            if not isinstance(number, int):
                raise DictionaryError(
                    name,
                    line,
                    f"address '{cell}' is not an integer",
                    "write the PDU address, e.g. 12 or 0x0C",
                )
            entry["pdu"] = number
        elif column in _CSV_INTEGERS or column in _CSV_NUMBERS:
            number = _csv_number(cell, decimal_comma)
            if number is None or (column in _CSV_INTEGERS and not isinstance(number, int)):
                wanted = "an integer" if column in _CSV_INTEGERS else "a number"
                raise DictionaryError(
                    name,
                    line,
                    f"{column} '{cell}' is not {wanted}",
                    f"write {column} as {wanted}",
                )
            entry[column] = number
        elif column == "enum":
            entry["enum"] = _csv_enum(name, line, cell)
        elif column == "default":
            number = _csv_number(cell, decimal_comma)
            entry["default"] = cell if number is None else number
        else:
            entry[column] = cell
    return entry


def import_csv(path: str | Path) -> DeviceDictionary:
    """A dictionary from a CSV register list (columns in docs/dictionaries.md).

    The model is the file name; `address` is the PDU address as on the wire.
    """
    name = str(path)
    text = read_text(Path(path))
    check_size(name, text)
    rows = [
        (number, line)
        for number, line in enumerate(text.splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not rows:
        raise DictionaryError(
            name, None, "the CSV file is empty", "add a header row: table,address,name"
        )
    header_line, header_text = rows[0]
    try:  # (the sniffer reads a header of real length: a few hundred characters)
        dialect: type[csv.Dialect] | csv.Dialect = csv.Sniffer().sniff(
            header_text[:4096], delimiters=",;\t"
        )
    except csv.Error:
        dialect = csv.excel
    header = [cell.strip().lower() for cell in _cells(name, header_line, header_text, dialect)]
    problems: list[DictionaryError] = []
    seen: set[str] = set()
    more = 0  # header problems past MAX_COLUMN_PROBLEMS
    for column in header:
        if len(problems) >= MAX_COLUMN_PROBLEMS and (column in seen or column not in CSV_COLUMNS):
            more += 1
        elif column in seen:
            problems.append(
                DictionaryError(
                    name, header_line, f"the header has '{column}' twice", "keep one of the columns"
                )
            )
        elif column not in CSV_COLUMNS:
            close = nearest(column[:64], CSV_COLUMNS)
            fix = f"rename it '{close}'" if close else f"use columns from {', '.join(CSV_COLUMNS)}"
            problems.append(
                DictionaryError(name, header_line, f"unknown CSV column '{column[:64]}'", fix)
            )
        seen.add(column)
    if more:
        problems.append(
            DictionaryError(
                name,
                header_line,
                f"{more:,} more unknown or repeated columns",
                f"use columns from {', '.join(CSV_COLUMNS)}",
            )
        )
    for column in CSV_REQUIRED:
        if column not in header:
            problems.append(
                DictionaryError(
                    name,
                    header_line,
                    f"the header has no '{column}' column",
                    "the header needs table,address,name",
                )
            )
    raise_all(problems)  # the rows cannot be read without a sound header
    entries: list[dict[str, object]] = []
    lines = LineMap({(): 1, ("device",): header_line})
    for line, row_text in rows[1:]:
        try:
            entry = _csv_row(name, header, line, row_text, dialect)
        except DictionaryError as error:
            problems.append(error)
            continue
        if entry is not None:
            lines.set(("entry", len(entries)), line)
            entries.append(entry)
    model = re.sub(r"[^A-Za-z0-9._+-]+", "-", Path(path).stem).strip("-") or "csv"
    data: dict[str, object] = {
        "format": FORMAT,
        "device": {
            "model": model,
            "name": Path(path).stem,
            "manual": f"CSV register list {Path(path).name}",
        },
        "entry": entries,
    }
    built: DeviceDictionary | None = None
    try:
        built = Builder(Source(name, lines)).build(data)
    except DictionaryError as error:
        problems.append(error)
    raise_all(problems)
    assert built is not None
    return built

"""Provides the limits every dictionary reader enforces before and while it parses text.

A dictionary, bus or Home Assistant file is small: a few hundred entries, nested a few
levels. Files far outside that are damage or an attack, and must be refused fast with a
DictionaryError naming the file, the line and the limit, never by running out of memory,
time or Python's recursion depth:

- size: at most `MAX_BYTES` characters of text (CSV register lists too);
- nesting: at most `MAX_DEPTH` levels of arrays, tables and mappings (tomllib and PyYAML
  build nested values by recursion and would end in a RecursionError);
- YAML aliases: the document with every alias expanded may hold at most `MAX_NODES`
  values (a "billion laughs" file of a few hundred bytes expands to billions) and at
  most `MAX_EXPANDED` characters of text (one long string named a hundred times costs
  a hundred times its length to everything that reads the entries);
- numbers: at most `MAX_DIGITS` digits (Python refuses to convert an integer of more
  than 4300 digits with a ValueError that names no file).

`load_toml` replaces `tomllib.loads`; `check_yaml` runs before `yaml.load`. Both check
the text with a scanner that does not recurse, so the check itself cannot overflow.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Iterator
from typing import Any

from .errors import DictionaryError

MAX_BYTES = 4 << 20  # 4 MiB; the largest real dictionary is about 100 kB
MAX_DEPTH = 64  # real files nest 4-8 levels
MAX_NODES = 200_000  # values after alias expansion; 1,000 HA sensors are about 20,000
# characters of keys and strings after alias expansion: 4 x MAX_BYTES, as no file under
# the size limit reaches it without aliases, and aliases in real files repeat small
# blocks (a hub's settings), adding kilobytes
MAX_EXPANDED = 4 * MAX_BYTES
MAX_DIGITS = 1000  # Python's int() refuses more than 4300

# The parts of TOML text that matter for nesting: strings and comments (skipped whole,
# so brackets inside them do not count), brackets, and runs of digits.
_TOML_TOKENS = re.compile(
    r'"""[\s\S]*?"""'
    r"|'''[\s\S]*?'''"
    r'|"(?:\\.|[^"\\\n])*"'
    r"|'[^'\n]*'"
    r"|#[^\n]*"
    r"|[\[\]{}]"
    r"|[0-9][0-9_]{" + str(MAX_DIGITS) + r",}"
)
_LONG_NUMBER = re.compile(r"[-+]?[0-9][0-9_]{" + str(MAX_DIGITS) + r",}")


def _line(text: str, pos: int) -> int:
    return text.count("\n", 0, pos) + 1


def check_size(path: str, text: str) -> None:
    """Refuse text over MAX_BYTES characters, naming the file."""
    if len(text) > MAX_BYTES:
        raise DictionaryError(
            path,
            None,
            f"the file is {len(text):,} characters long, over the limit of {MAX_BYTES:,}",
            "a dictionary describes one device model: split the file, or check that this is "
            "the file you meant",
        )


def _too_deep(path: str, line: int | None) -> DictionaryError:
    return DictionaryError(
        path,
        line,
        f"values nested more than {MAX_DEPTH} levels deep",
        "a dictionary nests tables and arrays a few levels at most; check the brackets "
        "(or the indentation) from this line",
    )


def _too_long(path: str, line: int | None) -> DictionaryError:
    return DictionaryError(
        path,
        line,
        f"a number with more than {MAX_DIGITS} digits",
        "write the register reference or value as the manual prints it",
    )


def _depth(value: object) -> int:
    """How deeply `value` nests lists and dicts, found without recursion; stops counting
    once past the limit."""
    deepest = 0
    stack: list[tuple[object, int]] = [(value, 1)]
    while stack:
        item, level = stack.pop()
        if level > deepest:
            deepest = level
            if deepest > MAX_DEPTH:
                break
        if isinstance(item, dict):
            stack.extend((v, level + 1) for v in item.values())
        elif isinstance(item, list):
            stack.extend((v, level + 1) for v in item)
    return deepest


def _dotted_line(text: str) -> int | None:
    """The first line whose table header plus dotted key go past the depth limit (a guess
    good enough to point at: quoted keys with dots count too)."""
    header = 0
    for number, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if line.startswith("["):
            header = line.strip("[] \t").count(".") + 1
            depth = header
        else:
            key = line.partition("=")[0]
            depth = header + key.count(".") + 1
        if depth > MAX_DEPTH:
            return number
    return None


def check_toml(path: str, text: str) -> None:
    """Refuse TOML text over the size, bracket nesting or digit limits (module doc)."""
    check_size(path, text)
    depth = 0
    for match in _TOML_TOKENS.finditer(text):
        token = match.group()
        first = token[0]
        if first in "[{":
            depth += 1
            if depth > MAX_DEPTH:
                raise _too_deep(path, _line(text, match.start()))
        elif first in "]}":
            depth = max(depth - 1, 0)
        elif first.isdigit():
            raise _too_long(path, _line(text, match.start()))


def load_toml(path: str, text: str) -> dict[str, Any]:
    """`tomllib.loads` within the limits. A syntax error is left as tomllib's
    TOMLDecodeError for the caller to explain; every other failure is a DictionaryError."""
    check_toml(path, text)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        raise
    except RecursionError:
        raise _too_deep(path, None) from None
    except ValueError:  # an integer Python refuses to convert
        found = _LONG_NUMBER.search(text)
        raise _too_long(path, _line(text, found.start()) if found else None) from None
    if _depth(data) > MAX_DEPTH:
        raise _too_deep(path, _dotted_line(text))
    return data


def check_yaml(path: str, text: str) -> None:
    """Refuse YAML text over the size, nesting, alias expansion or digit limits.

    Walks PyYAML's event stream (its parser keeps an explicit stack, no recursion) and
    counts the values and characters each anchor stands for, so an alias costs what it
    expands to. libyaml's parser goes first where PyYAML has it (50 times faster on a
    long scalar); it stops at its own nesting limit of 1,000 with a syntax error, so on
    any syntax error the Python parser walks the file again, to name the deep line. A
    syntax error there stops the check quietly: the real load reports it with its line."""
    import yaml

    check_size(path, text)
    fast = getattr(yaml, "CSafeLoader", None)
    for parser in (fast, yaml.SafeLoader) if fast is not None else (yaml.SafeLoader,):
        try:
            _check_yaml_events(path, yaml.parse(text, Loader=parser))
            return
        except yaml.YAMLError:
            continue


def _check_yaml_events(path: str, events: Iterator[Any]) -> None:
    """The limits of `check_yaml` over one parser's events."""
    import yaml

    sizes: dict[str, tuple[int, int]] = {}  # anchor -> (values, characters)
    # one open collection: [anchor, values inside it so far, characters inside it so far]
    open_: list[tuple[str | None, int, int]] = []
    total = 0
    chars = 0

    def add(count: int, length: int, line: int) -> None:
        nonlocal total, chars
        total += count
        chars += length
        if total > MAX_NODES:
            raise DictionaryError(
                path,
                line,
                f"the YAML expands to more than {MAX_NODES:,} values once its aliases "
                "(*name) are followed",
                "write the values out, or use fewer nested aliases; a Home Assistant "
                "configuration needs a few thousand values",
            )
        if chars > MAX_EXPANDED:
            raise DictionaryError(
                path,
                line,
                f"the YAML expands to more than {MAX_EXPANDED:,} characters once its "
                "aliases (*name) are followed",
                "name a long value with an alias once or twice, not over and over, or "
                "shorten it; a Home Assistant configuration is a few hundred kilobytes",
            )
        if open_:
            anchor, inside, inside_chars = open_[-1]
            open_[-1] = (anchor, inside + count, inside_chars + length)

    for event in events:
        line = event.start_mark.line + 1 if event.start_mark is not None else 0
        if isinstance(event, yaml.CollectionStartEvent):
            if len(open_) >= MAX_DEPTH:
                raise _too_deep(path, line)
            open_.append((event.anchor, 0, 0))
        elif isinstance(event, yaml.CollectionEndEvent) and open_:
            anchor, inside, inside_chars = open_.pop()
            size = inside + 1
            if anchor is not None:
                sizes[anchor] = (size, inside_chars)
            # counted once already as they arrived; re-add as a whole
            total -= inside
            chars -= inside_chars
            add(size, inside_chars, line)
        elif isinstance(event, yaml.ScalarEvent):
            value = event.value
            long_number = len(value) > MAX_DIGITS and _LONG_NUMBER.fullmatch(value)
            if not event.style and long_number:  # plain: None (Python), "" (libyaml)
                raise _too_long(path, line)
            if event.anchor is not None:
                sizes[event.anchor] = (1, len(value))
            add(1, len(value), line)
        elif isinstance(event, yaml.AliasEvent):
            if any(anchor == event.anchor for anchor, _, _ in open_):
                raise DictionaryError(
                    path,
                    line,
                    f"the alias *{event.anchor} is inside the value it names, a loop",
                    "an alias may only repeat a value that is complete before it",
                )
            add(*sizes.get(event.anchor or "", (1, 0)), line)

"""Provides line numbers for TOML keys, which tomllib does not report.

`scan_toml` walks text that tomllib has already accepted and records, for every key
path, the line where it is written: `("entry", 3, "unit")` is the `unit =` line of the
fourth `[[entry]]`, `("entry", 3)` its header, `("entry", 3, "enum", "0x10")` a key of an
inline table, `("function", 0, "response", 1)` the second element of an array. Lines are
1-based. Scanning is best effort: on anything unexpected it stops and keeps what it has.
"""

from __future__ import annotations

import bisect
import contextlib
from collections.abc import Mapping

KeyPath = tuple[str | int, ...]

_BARE = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-")
_ESCAPES = {"b": "\b", "t": "\t", "n": "\n", "f": "\f", "r": "\r", '"': '"', "\\": "\\"}


class LineMap:
    """Key path -> line, answering for a path with its nearest recorded ancestor."""

    def __init__(self, lines: Mapping[KeyPath, int] | None = None) -> None:
        self._lines: dict[KeyPath, int] = dict(lines or {})

    def set(self, path: KeyPath, line: int) -> None:
        self._lines[path] = line

    def exact(self, path: KeyPath) -> int | None:
        return self._lines.get(path)

    def line(self, path: KeyPath) -> int | None:
        """The line of `path`, or of the closest enclosing key or table that has one."""
        for end in range(len(path), 0, -1):
            found = self._lines.get(path[:end])
            if found is not None:
                return found
        return self._lines.get(())


class _Scanner:
    def __init__(self, text: str) -> None:
        self.text = text
        self.pos = 0
        self.end = len(text)
        self.newlines = [i for i, char in enumerate(text) if char == "\n"]
        self.lines = LineMap()
        self.arrays: dict[KeyPath, int] = {}  # arrays of tables: path -> tables so far
        self.table: KeyPath = ()

    def line_at(self, pos: int) -> int:
        return bisect.bisect_left(self.newlines, pos) + 1

    def peek(self, count: int = 1) -> str:
        return self.text[self.pos : self.pos + count]

    def skip_blank(self, newlines: bool) -> None:
        stops = " \t\r\n" if newlines else " \t\r"
        while self.pos < self.end:
            char = self.text[self.pos]
            if char in stops:
                self.pos += 1
            elif char == "#":
                while self.pos < self.end and self.text[self.pos] != "\n":
                    self.pos += 1
            else:
                return

    def run(self) -> None:
        while True:
            self.skip_blank(newlines=True)
            if self.pos >= self.end:
                return
            before = self.pos
            if self.peek() == "[":
                self.header()
            else:
                self.keyval(self.table)
            if self.pos <= before:  # never loop on text we do not understand
                self.pos = before + 1

    def header(self) -> None:
        line = self.line_at(self.pos)
        is_array = self.peek(2) == "[["
        self.pos += 2 if is_array else 1
        parts = self.key()
        self.skip_blank(newlines=False)
        self.pos += 2 if is_array else 1
        if is_array:
            parent = self.resolve(parts[:-1])
            key = (*parent, parts[-1])
            index = self.arrays.get(key, 0)
            self.arrays[key] = index + 1
            if self.lines.exact(key) is None:
                self.lines.set(key, line)
            self.table = (*key, index)
            self.lines.set(self.table, line)
        else:
            self.table = self.resolve(parts)
            if self.lines.exact(self.table) is None:
                self.lines.set(self.table, line)

    def resolve(self, parts: list[str]) -> KeyPath:
        """A header's dotted key as a concrete path, indexing into arrays of tables."""
        path: list[str | int] = []
        for part in parts:
            path.append(part)
            count = self.arrays.get(tuple(path))
            if count:
                path.append(count - 1)
        return tuple(path)

    def key(self) -> list[str]:
        parts: list[str] = []
        while True:
            self.skip_blank(newlines=False)
            char = self.peek()
            if char == '"':
                parts.append(self.basic_string())
            elif char == "'":
                parts.append(self.literal_string())
            else:
                start = self.pos
                while self.pos < self.end and self.text[self.pos] in _BARE:
                    self.pos += 1
                parts.append(self.text[start : self.pos])
            self.skip_blank(newlines=False)
            if self.peek() != ".":
                return parts
            self.pos += 1

    def keyval(self, base: KeyPath) -> None:
        line = self.line_at(self.pos)
        path = base
        for part in self.key():
            path = (*path, part)
            if self.lines.exact(path) is None:
                self.lines.set(path, line)
        self.skip_blank(newlines=False)
        if self.peek() == "=":
            self.pos += 1
        self.skip_blank(newlines=False)
        self.value(path)

    def value(self, path: KeyPath) -> None:
        if self.peek(3) in ('"""', "'''"):
            self.multiline_string(self.peek(3))
        elif self.peek() == '"':
            self.basic_string()
        elif self.peek() == "'":
            self.literal_string()
        elif self.peek() == "[":
            self.array(path)
        elif self.peek() == "{":
            self.inline_table(path)
        else:
            while self.pos < self.end and self.text[self.pos] not in ",]}\n#":
                self.pos += 1

    def array(self, path: KeyPath) -> None:
        self.pos += 1
        index = 0
        while self.pos < self.end:
            self.skip_blank(newlines=True)
            if self.peek() == "]":
                self.pos += 1
                return
            before = self.pos
            self.lines.set((*path, index), self.line_at(self.pos))
            self.value((*path, index))
            self.skip_blank(newlines=True)
            if self.peek() == ",":
                self.pos += 1
                index += 1
            elif self.pos == before:
                self.pos += 1

    def inline_table(self, path: KeyPath) -> None:
        self.pos += 1
        while self.pos < self.end:
            self.skip_blank(newlines=True)
            if self.peek() == "}":
                self.pos += 1
                return
            before = self.pos
            self.keyval(path)
            self.skip_blank(newlines=True)
            if self.peek() == "," or self.pos == before:
                self.pos += 1

    def basic_string(self) -> str:
        self.pos += 1
        out: list[str] = []
        while self.pos < self.end:
            char = self.text[self.pos]
            if char == '"':
                self.pos += 1
                break
            if char == "\\":
                code = self.text[self.pos + 1 : self.pos + 2]
                if code in ("u", "U"):
                    digits = 4 if code == "u" else 8
                    hex_text = self.text[self.pos + 2 : self.pos + 2 + digits]
                    out.append(chr(int(hex_text, 16)))
                    self.pos += 2 + digits
                    continue
                out.append(_ESCAPES.get(code, code))
                self.pos += 2
                continue
            out.append(char)
            self.pos += 1
        return "".join(out)

    def literal_string(self) -> str:
        start = self.pos + 1
        close = self.text.find("'", start)
        close = self.end if close < 0 else close
        self.pos = close + 1
        return self.text[start:close]

    def multiline_string(self, quote: str) -> None:
        self.pos += 3
        while self.pos < self.end:
            if quote == '"""' and self.text[self.pos] == "\\":
                self.pos += 2
                continue
            if self.text.startswith(quote, self.pos):
                run = 0
                while self.text[self.pos + run : self.pos + run + 1] == quote[0] and run < 5:
                    run += 1
                self.pos += run
                return
            self.pos += 1


def scan_toml(text: str) -> LineMap:
    """Line numbers of every key, table header and array element in TOML `text`."""
    scanner = _Scanner(text)
    with contextlib.suppress(ValueError, IndexError):  # odd escapes: keep what we have
        scanner.run()
    return scanner.lines

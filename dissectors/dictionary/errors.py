"""Provides DictionaryError: one problem in a dictionary or bus file, with its line and fix."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class DictionaryError(Exception):
    """A dictionary, bus or import file that cannot be used as written.

    `str(error)` reads `path:line: message. Fix: fix` (`path: ...` when the line is
    unknown). When a file has several problems the first is raised and the others ride
    along in `more`, in line order.
    """

    path: str
    line: int | None
    message: str
    fix: str
    more: tuple[DictionaryError, ...]

    def __init__(self, path: str, line: int | None, message: str, fix: str) -> None:
        super().__init__(path, line, message, fix)
        self.path = path
        self.line = line
        self.message = message
        self.fix = fix
        self.more = ()

    def __str__(self) -> str:
        where = self.path if self.line is None else f"{self.path}:{self.line}"
        return f"{where}: {self.message}. Fix: {self.fix}"

    @property
    def all(self) -> tuple[DictionaryError, ...]:
        """This error and every further one found in the same file."""
        return (self, *self.more)


def raise_all(errors: Iterable[DictionaryError]) -> None:
    """Raise the first of `errors` in line order with the others in its `more`; nothing
    when there are none. Errors that carry their own `more` are flattened."""
    flat = [each for error in errors for each in error.all]
    if not flat:
        return
    ordered = sorted(flat, key=lambda e: (e.line is None, e.line or 0))
    first = ordered[0]
    first.more = tuple(ordered[1:])
    raise first


def nearest(word: str, known: Iterable[str]) -> str | None:
    """The known word closest to `word`, if any is close enough to be a likely typo."""
    choices = list(known)
    lowered = {c.lower(): c for c in choices}
    if word.lower() in lowered:
        return lowered[word.lower()]
    found = difflib.get_close_matches(word, choices, n=1, cutoff=0.6)
    return found[0] if found else None


def choose_fix(word: str, known: Iterable[str], what: str = "one of") -> str:
    """A fix for an unknown word: the nearest known word, or the whole list."""
    choices = list(known)
    close = nearest(word, choices)
    listed = ", ".join(choices)
    if close is not None:
        return f"write '{close}' instead of '{word}'"
    return f"use {what}: {listed}"

"""Provides the filter language of the TUI's frame list and the CLI's --filter:
`unit:3 fc:3 status:timeout reg:"Trip" t:10-20 text`, `unit:3 or unit:4`,
`not (fc:3 or status:ok)`.

A term is `key:value` (`key==value` and `key=value` say the same, `key!=value` the
opposite) or a word of free text. Column terms (`unit`, `fc`, `kind`, `status`, `t`) are
decided from the store's arrays; `reg:` and words need the row's details. Terms next to
each other must all hold, except that values of one key given in several such terms
(`unit:1 unit:2`) are alternatives, as a list (`unit:1,2`) is. `and`, `or`, `not` and
parentheses combine terms, `not` binding tightest and `or` loosest. A `-` before a
`unit`, `fc`, `kind` or `status` term leaves out what it names (`-fc:3`). Double quotes
keep spaces, parentheses and the words `and`, `or`, `not` inside a value or a word.

What cannot be read is refused with a `QueryError` whose message starts with the part
not understood and says what to write instead: a filter never quietly means something
else than it says.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from decimal import Decimal
from typing import TypeAlias, TypeVar

from sniffer.vocab import Kind

KEYS = ("unit", "fc", "kind", "status", "reg", "t")
NEGATABLE = ("unit", "fc", "kind", "status")  # the keys a `-` may stand before
EXAMPLES = {
    "unit": "unit:3",
    "fc": "fc:3",
    "kind": "kind:request",
    "status": "status:timeout",
    "reg": 'reg:"Under Voltage"',
    "t": "t:10-20",
}
LIMITS = {"unit": (0, 255), "fc": (1, 127)}

KIND_WORDS: dict[str, int] = {
    "request": Kind.REQUEST,
    "req": Kind.REQUEST,
    "response": Kind.RESPONSE,
    "resp": Kind.RESPONSE,
    "answer": Kind.RESPONSE,
    "exception": Kind.EXCEPTION,
    "exc": Kind.EXCEPTION,
    "noise": Kind.NOISE,
    "event": Kind.EVENT,
    "unknown": Kind.UNKNOWN,
}
KIND_NAMES: dict[int, str] = {
    Kind.REQUEST: "request",
    Kind.RESPONSE: "response",
    Kind.EXCEPTION: "exception",
    Kind.NOISE: "noise",
    Kind.EVENT: "event",
    Kind.UNKNOWN: "unknown",
}

STATUS_WORDS: dict[str, str] = {
    "ok": "ok",
    "exception": "exception",
    "exc": "exception",
    "timeout": "timeout",
    "t/o": "timeout",
    "orphan": "orphan",
    "broadcast": "broadcast",
    "open": "open",
    "check": "check",
    "crc": "check",
    "lrc": "check",
    "bad": "check",
    "noise": "noise",
    "event": "event",
    "problem": "problem",
    "problems": "problem",
    "error": "problem",
}

_TIME_SUFFIX = {"ms": 0.001, "s": 1.0, "m": 60.0, "min": 60.0, "h": 3600.0}
# a term's head: a `-`, and a key with its comparison
_HEAD = re.compile(r"(-?)(?:([A-Za-z]+)(==|!=|<=|>=|=|<|>|:))?")
_BARE = re.compile(r"[^\s()]*")  # an unquoted value or word: up to a space or parenthesis
_REST = re.compile(r"\S*")
_OPERATORS = ("and", "or", "not")
_SYMBOLS = {"||": "or", "|": "or", "&&": "and", "&": "and"}
_T = TypeVar("_T")
_COMPARISONS = ("==", "!=", "<=", ">=", "=", "<", ">")


# a word that looks like the list's unit or function column (`u3`, `fc16`: not text)
_COLUMN_LOOK = re.compile(r"(u|fc)0*([0-9]{1,3})")


class QueryError(ValueError):
    """A filter that cannot be read; the message says what to write instead."""


@dataclass(frozen=True, slots=True)
class TimePoint:
    """Seconds from the capture's first row, or (clock) seconds after local midnight."""

    seconds: float
    clock: bool = False


@dataclass(frozen=True, slots=True)
class TimeSpan:
    start: TimePoint | None
    end: TimePoint | None


# -- the query's tree ----------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Column:
    """`unit:`, `fc:` or `kind:`: the row's column holds one of `values` (for `unit` and
    `fc`, only frames have them: noise and events never match)."""

    key: str
    values: frozenset[int]


@dataclass(frozen=True, slots=True)
class StatusTerm:
    """`status:`: what became of the row's transaction, by the names of STATUS_WORDS'
    values (`check`, `noise`, `event`, `problem` read flags and kinds too)."""

    names: frozenset[str]


@dataclass(frozen=True, slots=True)
class Time:
    """`t:`: the row starts inside the span (its end excluded)."""

    span: TimeSpan


@dataclass(frozen=True, slots=True)
class Register:
    """`reg:`: a register whose name holds one of `parts` (lower case) is read or
    written (only units with a dictionary, or recognised as SunSpec, name them)."""

    parts: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class Text:
    """A word: it appears (in any case) in the row's text (see select.row_words)."""

    word: str


@dataclass(frozen=True, slots=True)
class Not:
    part: Node


@dataclass(frozen=True, slots=True)
class And:
    """Every part holds; no parts: every row."""

    parts: tuple[Node, ...]


@dataclass(frozen=True, slots=True)
class Or:
    """One part at least holds; no parts: no row."""

    parts: tuple[Node, ...]


Node: TypeAlias = Column | StatusTerm | Time | Register | Text | Not | And | Or
EVERYTHING = And(())


def needs_detail(node: Node) -> bool:
    """Whether deciding `node` needs rows dissected (register names, free text)."""
    if isinstance(node, Register | Text):
        return True
    if isinstance(node, Not):
        return needs_detail(node.part)
    if isinstance(node, And | Or):
        return any(needs_detail(p) for p in node.parts)
    return False


def _atoms(node: Node) -> list[Node]:
    if isinstance(node, Not):
        return _atoms(node.part)
    if isinstance(node, And | Or):
        return [a for p in node.parts for a in _atoms(p)]
    return [node]


def conjunction(parts: list[Node] | tuple[Node, ...]) -> Node:
    """Every one of `parts` (nested conjunctions flattened; one part is itself)."""
    flat: list[Node] = []
    for p in parts:
        flat.extend(p.parts if isinstance(p, And) else (p,))
    return flat[0] if len(flat) == 1 else And(tuple(flat))


def disjunction(parts: list[Node] | tuple[Node, ...]) -> Node:
    """One of `parts` at least (nested disjunctions flattened; one part is itself)."""
    flat: list[Node] = []
    for p in parts:
        flat.extend(p.parts if isinstance(p, Or) else (p,))
    return flat[0] if len(flat) == 1 else Or(tuple(flat))


@dataclass(frozen=True, slots=True)
class Query:
    """A parsed filter: `tree` is what it means (the matcher reads only that).

    The other properties sum up the terms of the tree's top-level conjunction by key (for
    a query without `or`, `not` or parentheses: the whole query), as the flat language of
    terms had them; empty sets mean no condition on that column there. They are exact
    for that flat language only: with `and` between two terms of one key (`unit:1 and
    unit:2`, `reg:a and reg:b`) they are a summary, and only `tree` says what matches.
    """

    text: str = ""
    tree: Node = EVERYTHING

    @property
    def top(self) -> tuple[Node, ...]:
        """The parts every match must satisfy."""
        return self.tree.parts if isinstance(self.tree, And) else (self.tree,)

    def _top_atoms(self, negated: bool) -> list[Node]:
        """The top-level terms, or (negated) the terms top-level `not`s stand before."""
        if negated:
            return [n.part for n in self.top if isinstance(n, Not)]
        return [n for n in self.top if not isinstance(n, Not)]

    def _values(self, key: str, negated: bool) -> frozenset[int]:
        sets = [
            a.values for a in self._top_atoms(negated) if isinstance(a, Column) and a.key == key
        ]
        return _combine(sets, negated)

    def _names(self, negated: bool) -> frozenset[str]:
        return _combine(
            [a.names for a in self._top_atoms(negated) if isinstance(a, StatusTerm)], negated
        )

    @property
    def units(self) -> frozenset[int]:
        return self._values("unit", False)

    @property
    def not_units(self) -> frozenset[int]:
        return self._values("unit", True)

    @property
    def functions(self) -> frozenset[int]:
        return self._values("fc", False)

    @property
    def not_functions(self) -> frozenset[int]:
        return self._values("fc", True)

    @property
    def kinds(self) -> frozenset[int]:
        return self._values("kind", False)

    @property
    def not_kinds(self) -> frozenset[int]:
        return self._values("kind", True)

    @property
    def statuses(self) -> frozenset[str]:
        return self._names(False)

    @property
    def not_statuses(self) -> frozenset[str]:
        return self._names(True)

    @property
    def registers(self) -> tuple[str, ...]:
        """Lower-case parts of register names, any may match."""
        return tuple(p for n in self.top if isinstance(n, Register) for p in n.parts)

    @property
    def words(self) -> tuple[str, ...]:
        """Lower-case words, all must appear in the row's text."""
        return tuple(n.word for n in self.top if isinstance(n, Text))

    def hints(self) -> list[str]:
        """What to say of words that look like a column as the rows show it (`u3`,
        `fc16`): they are searched for as text, where the unit and function columns are
        not, so they may match nothing; the term that selects the column is named."""
        said = []
        for atom in _atoms(self.tree):
            if not isinstance(atom, Text) or not (found := _COLUMN_LOOK.fullmatch(atom.word)):
                continue
            key, value = "unit" if found[1] == "u" else "fc", int(found[2])
            try:
                parse_query(f"{key}:{value}")
            except QueryError:
                continue  # no such unit or function to point to
            said.append(
                f"'{atom.word}' is looked for as text, which the {key} column is not; "
                f"for {key} {value} write {key}:{value}"
            )
        return said

    @property
    def time(self) -> TimeSpan | None:
        """A span every match starts in (the first top-level `t:`), to bound scans."""
        return next((n.span for n in self.top if isinstance(n, Time)), None)

    @property
    def needs_detail(self) -> bool:
        """Whether rows must be dissected to decide (register names, free text)."""
        return needs_detail(self.tree)

    @property
    def has_columns(self) -> bool:
        return any(isinstance(a, Column | StatusTerm) for a in _atoms(self.tree))

    @property
    def empty(self) -> bool:
        """No condition at all: every row matches."""
        return self.tree == EVERYTHING


def _combine(sets: list[frozenset[_T]], negated: bool) -> frozenset[_T]:
    """The values top-level terms of one key allow: each one must hold (intersection);
    negated, each is left out (union)."""
    if not sets:
        return frozenset()
    return frozenset().union(*sets) if negated else frozenset.intersection(*sets)


def _numbers(key: str, value: str, low: int, high: int) -> set[int]:
    out: set[int] = set()
    for part in value.split(","):
        part = part.strip()
        if not part:
            raise QueryError(f"{key}:{value}: an empty value between commas; write e.g. {key}:1,2")
        a, sep, b = part.partition("-")
        try:
            first = int(a, 0)
            last = int(b, 0) if sep else first
        except ValueError:
            raise QueryError(
                f"{key}:{value}: {part!r} is not a number; write e.g. {key}:3, {key}:1,2 "
                f"or {key}:1-5"
            ) from None
        if not (low <= first <= high and low <= last <= high) or last < first:
            raise QueryError(f"{key}:{value}: values go from {low} to {high}")
        out.update(range(first, last + 1))
    if not out:
        raise QueryError(f"{key}: needs a value, e.g. {key}:3")
    return out


def _words(key: str, value: str, table: dict[str, int] | dict[str, str]) -> list[str]:
    out = []
    for part in value.lower().split(","):
        if not part:
            raise QueryError(
                f"{key}:{value}: an empty value between commas; write e.g. {EXAMPLES[key]}"
            )
        if part not in table:
            names = ", ".join(sorted({str(k) for k in table}))
            raise QueryError(f"{key}:{part} is not known; use one of {names}")
        out.append(part)
    return out


def parse_time_point(text: str) -> TimePoint:
    """`12.5`, `500ms`, `2m`, or a clock time `14:03:07.25` (local time of the capture)."""
    text = text.strip()
    if ":" in text:
        parts = text.split(":")
        if len(parts) > 3:
            raise QueryError(f"{text!r}: write a clock time as hh:mm or hh:mm:ss.fff")
        try:
            numbers = [float(p) for p in parts]
        except ValueError:
            raise QueryError(f"{text!r}: write a clock time as hh:mm or hh:mm:ss.fff") from None
        while len(numbers) < 3:
            numbers.append(0.0)
        h, m, s = numbers
        if not (0 <= h < 24 and 0 <= m < 60 and 0 <= s < 60) or h != int(h) or m != int(m):
            raise QueryError(
                f"{text!r} is not a clock time: hours go from 0 to 23, minutes and seconds "
                "from 0 to 59 (14:03:07.25)"
            )
        return TimePoint(h * 3600 + m * 60 + s, clock=True)
    match = re.fullmatch(r"([0-9]*\.?[0-9]+)\s*(ms|s|min|m|h)?", text)
    if match is None:
        raise QueryError(
            f"{text!r} is not a time; write seconds from the start (12.5, 500ms, 2m) "
            "or a clock time (14:03:07)"
        )
    return TimePoint(float(match.group(1)) * _TIME_SUFFIX[match.group(2) or "s"])


def parse_time_span(value: str) -> TimeSpan:
    """`10-20`, `10-` (from 10 on), `-20` (up to 20), `14:00-14:05`."""
    if value == "-":
        raise QueryError("t:-: give a start, an end or both, e.g. t:10-20, t:10- or t:-20")
    if value.startswith("-"):
        return TimeSpan(None, parse_time_point(value[1:]))
    if value.endswith("-"):
        return TimeSpan(parse_time_point(value[:-1]), None)
    a, sep, b = value.partition("-")
    if not sep:
        start = parse_time_point(a)
        return TimeSpan(start, TimePoint(start.seconds + 1.0, start.clock))
    start, end = parse_time_point(a), parse_time_point(b)
    if start.clock != end.clock:
        raise QueryError(
            f"t:{value}: both ends are seconds from the start (t:10-20) or both clock "
            "times (t:14:03-14:05)"
        )
    if end.seconds < start.seconds:
        raise QueryError(
            f"t:{value}: the end comes before the start; write the earlier time first (t:{b}-{a})"
        )
    return TimeSpan(start, end)


# -- reading a query ------------------------------------------------------------------------


def _atom(key: str, value: str) -> Node:
    """The term `key:value` (key known, value not empty)."""
    if key in LIMITS:
        low, high = LIMITS[key]
        return Column(key, frozenset(_numbers(key, value, low, high)))
    if key == "kind":
        return Column(key, frozenset(KIND_WORDS[w] for w in _words(key, value, KIND_WORDS)))
    if key == "status":
        return StatusTerm(frozenset(STATUS_WORDS[w] for w in _words(key, value, STATUS_WORDS)))
    if key == "reg":
        return Register((value.lower(),))
    try:
        return Time(parse_time_span(value))
    except QueryError as exc:
        said = str(exc)
        raise QueryError(said if said.startswith("t:") else f"t:{value}: {said}") from None


def _range_hint(key: str, op: str, value: str) -> str:
    """What to write instead of `key<value` and the like: a range."""
    if key in LIMITS:
        low, high = LIMITS[key]
        try:
            v = int(value, 0)
        except ValueError:
            return f"a range, e.g. {key}:{low}-{high}"
        first, last = {
            ">": (v + 1, high),
            ">=": (v, high),
            "<": (low, v - 1),
            "<=": (low, v),
        }[op]
        if low <= first <= last <= high:
            return f"a range: {key}:{first}-{last}"
        return f"a range between {low} and {high}, e.g. {key}:{low}-{high}"
    if key == "t":
        return f"a span: t:{value}-" if op.startswith(">") else f"a span: t:-{value}"
    return f"the values: {EXAMPLES[key]} ({key} values are not in an order)"


def _comparison(part: str, key: str, op: str, value: str) -> str:
    """What to say of a comparison written apart (`unit == 3`) or with < or >."""
    if op in ("==", "=", "!="):
        return f"{part}: write the key, the comparison and the value together: {key}{op}{value}"
    return f"{part}: < and > do not compare here; write {_range_hint(key, op, value)}"


@dataclass(frozen=True, slots=True)
class _Token:
    what: str  # "term", "(", ")", "and", "or", "not"
    start: int
    end: int
    node: Node = EVERYTHING  # a term's meaning
    key: str = ""  # a plain term's key: merged with the same key's terms next to it


def _rest(text: str, pos: int) -> int:
    """Where the text that starts at `pos` ends (the next space)."""
    match = _REST.match(text, pos)
    return match.end() if match is not None else pos


def _lex(text: str) -> list[_Token]:
    out: list[_Token] = []
    pos, n = 0, len(text)
    while True:
        while pos < n and text[pos].isspace():
            pos += 1
        if pos >= n:
            return out
        if text[pos] == "(":
            out.append(_Token("(", pos, pos + 1))
            pos += 1
        elif text[pos] == ")":
            end = pos + 1
            if end < n and not (text[end].isspace() or text[end] in "()"):
                raise QueryError(
                    f"{text[pos : _rest(text, end)]}: text right after a ); leave a space after it"
                )
            out.append(_Token(")", pos, end))
            pos = end
        else:
            token = _term(text, pos, out)
            out.append(token)
            pos = token.end


def _term(text: str, pos: int, before: list[_Token]) -> _Token:
    """The term, word or operator that starts at `pos` (not a space or a parenthesis)."""
    n = len(text)
    head = _HEAD.match(text, pos)
    assert head is not None  # every part of the pattern may be empty
    neg, key, op = head.group(1) == "-", head.group(2), head.group(3) or ""
    at = head.end()
    quoted = at < n and text[at] == '"'
    if quoted:
        close = text.find('"', at + 1)
        if close < 0:
            raise QueryError(
                f"{text[pos:].rstrip()}: the quote is not closed; end the text with "
                '" (e.g. reg:"Under Voltage")'
            )
        value, end = text[at + 1 : close], close + 1
        if end < n and not (text[end].isspace() or text[end] == ")"):
            raise QueryError(
                f"{text[pos : _rest(text, end)]}: text right after a closing quote; "
                "leave a space after it"
            )
        if not value.strip():
            raise QueryError(f"{text[pos:end]}: empty quotes; put the text between them")
    else:
        bare = _BARE.match(text, at)
        assert bare is not None
        value, end = bare.group(), bare.end()
        if '"' in value:
            raise QueryError(
                f"{text[pos:end]}: a quote inside a term; put quotes around the whole value "
                'or text (reg:"Under Voltage", "two words")'
            )
        if end < n and text[end] == "(":
            if neg and not key and not value:
                raise QueryError(
                    f"{text[pos : end + 1]}: a - leaves out one term; write not (...) to "
                    "leave out a group"
                )
            raise QueryError(
                f"{text[pos : _rest(text, end)]}: a ( right after text; leave a space before "
                'it, or put text with a parenthesis in quotes ("a (b)")'
            )
    term = text[pos:end]
    if key is None or (op == ":" and not value and not quoted and key.lower() not in KEYS):
        # a word (one that ends with a colon included: "Pump:")
        word = value if key is None else key + ":"
        if neg:
            if not word:
                raise QueryError("-: write the term to leave out right after it, e.g. -fc:3")
            raise QueryError(
                f"{term}: only unit, fc, kind and status terms can be negated with a -; "
                f'write not {term[1:]} to leave out rows with that text, or "{term}" to find it'
            )
        if not quoted:
            _not_an_operator(text, word, pos, end, before)
            if word.lower() in _OPERATORS:
                return _Token(word.lower(), pos, end)
        return _Token("term", pos, end, Text(word.lower()))
    key = key.lower()
    if key not in KEYS:
        raise QueryError(
            f"{term}: unknown key {key!r}; keys are {', '.join(KEYS)} "
            f'(put text with a {op} in quotes: "{term}")'
        )
    if neg and key not in NEGATABLE:
        raise QueryError(
            f"{term}: only unit, fc, kind and status terms can be negated with a -; "
            f"write not {term[1:]}"
        )
    if not value and not quoted and op != ":":
        # `unit== 3`: the value is the next word
        nxt = _BARE.match(text, len(text) - len(text[end:].lstrip()))
        if nxt is not None and nxt.group():
            raise QueryError(_comparison(text[pos : nxt.end()], key, op, nxt.group()))
    if op in ("<", "<=", ">", ">="):
        raise QueryError(_comparison(term, key, op, value))
    if not value:
        raise QueryError(f"{key}: needs a value, e.g. {EXAMPLES[key]}")
    try:
        node = _atom(key, value)
    except QueryError as exc:
        said, typed = str(exc), term.lstrip("-")
        canonical = f"{key}:{value}"
        if typed != canonical and said.startswith(canonical):
            said = typed + said[len(canonical) :]  # name the term as it was typed
        raise QueryError(said) from None
    if neg or op == "!=":
        return _Token("term", pos, end, Not(node))
    return _Token("term", pos, end, node, key)


def _not_an_operator(text: str, word: str, pos: int, end: int, before: list[_Token]) -> None:
    """Refuse the spellings of operators and comparisons the language does not have."""
    if word in _SYMBOLS:
        said = _SYMBOLS[word]
        how = "between alternatives" if said == "or" else "(or just a space) between terms"
        example = "unit:3 or unit:4" if said == "or" else "unit:3 and fc:3"
        raise QueryError(f"{word}: write {said} {how}, e.g. {example}")
    op = next((c for c in _COMPARISONS if word.startswith(c)), None)
    if op is None:
        if word.startswith("!"):
            raise QueryError(
                f"{word}: write not before what to leave out, e.g. not {word[1:] or 'unit:3'}"
            )
        return
    # a comparison with spaces around it (`unit == 3`) or with no key
    start, key, value, stop = pos, "", word[len(op) :], end
    last = before[-1] if before else None
    if last is not None and isinstance(last.node, Text) and last.node.word in KEYS:
        start, key = last.start, last.node.word
    if not value:
        nxt = _BARE.match(text, len(text) - len(text[end:].lstrip()))
        if nxt is not None and nxt.group():
            value, stop = nxt.group(), nxt.end()
    raise QueryError(_comparison(text[start:stop], key or "unit", op, value or "3"))


class _Parser:
    """Reads the tokens: `not` binds tightest, then `and` (or terms side by side), then
    `or`; parentheses group."""

    def __init__(self, text: str, tokens: list[_Token]) -> None:
        self.text = text
        self.tokens = tokens
        self.k = 0

    def peek(self) -> _Token | None:
        return self.tokens[self.k] if self.k < len(self.tokens) else None

    def take(self) -> _Token:
        token = self.tokens[self.k]
        self.k += 1
        return token

    def query(self) -> Node:
        if not self.tokens:
            return EVERYTHING
        node = self.either()
        extra = self.peek()
        if extra is not None:  # only a ) stops an expression before the end
            self.unmatched(extra)
        return node

    def unmatched(self, close: _Token) -> None:
        start = self.tokens[self.k - 1].start if self.k else close.start
        raise QueryError(
            f"{self.text[start : close.end]}: a ) with no ( before it; remove it, or add a ( "
            "where the group starts"
        )

    def either(self) -> Node:
        parts = [self.every()]
        while (token := self.peek()) is not None and token.what == "or":
            self.take()
            self.operand_after(token)
            parts.append(self.every())
        return disjunction(parts)

    def every(self) -> Node:
        parts = [self.run()]
        while (token := self.peek()) is not None and token.what == "and":
            self.take()
            self.operand_after(token)
            parts.append(self.run())
        return conjunction(parts)

    def operand_after(self, op: _Token) -> None:
        nxt = self.peek()
        if nxt is not None and nxt.what in ("term", "(", "not"):
            return
        if nxt is None:
            start = self.tokens[self.k - 2].start if self.k >= 2 else op.start
            part = self.text[start : op.end]
        else:
            part = self.text[op.start : nxt.end]
        raise QueryError(f"{part}: {op.what} needs a term after it, e.g. unit:3 {op.what} unit:4")

    def run(self) -> Node:
        """Terms side by side: all must hold; a key's plain terms are alternatives."""
        items: list[tuple[Node, _Token]] = []
        while (token := self.peek()) is not None and token.what in ("term", "(", "not"):
            items.append(self.unary())
        if not items:
            token = self.peek()
            assert token is not None  # `or`, `and` or `)` where a term should start
            if token.what == ")":
                self.unmatched(token)
            nxt = self.tokens[self.k + 1] if self.k + 1 < len(self.tokens) else token
            raise QueryError(
                f"{self.text[token.start : nxt.end]}: {token.what} needs a term before it, "
                f"e.g. unit:3 {token.what} unit:4"
            )
        parts: list[Node] = []
        slots: dict[str, int] = {}  # a key -> where its plain terms are in parts
        for node, token in items:
            key = token.key
            if not key:
                parts.append(node)
                continue
            k = slots.get(key)
            if k is None:
                slots[key] = len(parts)
                parts.append(node)
                continue
            if key == "t":
                first = next(t for n, t in items if t.key == "t")
                raise QueryError(
                    f"{self.text[token.start : token.end]}: a second time span next to "
                    f"{self.text[first.start : first.end]}; keep one, or join them with or "
                    "(rows in either) or and (rows in both)"
                )
            parts[k] = _merge(parts[k], node)
        return conjunction(parts)

    def unary(self) -> tuple[Node, _Token]:
        token = self.take()
        if token.what == "not":
            nxt = self.peek()
            if nxt is None or nxt.what not in ("term", "(", "not"):
                part = self.text[token.start : nxt.end if nxt is not None else token.end]
                raise QueryError(f"{part}: not needs a term after it, e.g. not unit:3")
            node, _ = self.unary()
            return (node.part if isinstance(node, Not) else Not(node)), token
        if token.what == "(":
            nxt = self.peek()
            if nxt is not None and nxt.what == ")":
                raise QueryError(
                    f"{self.text[token.start : nxt.end]}: empty parentheses; put terms "
                    "between them, or leave them out"
                )
            if nxt is not None:
                node = self.either()
                if self.peek() is not None:  # the )
                    self.take()
                    return node, token
            raise QueryError(
                f"{self.text[token.start :].rstrip()}: a ( is not closed; add a ) where the "
                "group ends"
            )
        return token.node, token


def _merge(a: Node, b: Node) -> Node:
    """Two plain terms of one key side by side: either may hold."""
    if isinstance(a, Column) and isinstance(b, Column):
        return Column(a.key, a.values | b.values)
    if isinstance(a, StatusTerm) and isinstance(b, StatusTerm):
        return StatusTerm(a.names | b.names)
    if isinstance(a, Register) and isinstance(b, Register):
        return Register(a.parts + b.parts)
    raise AssertionError(f"{a} and {b} do not merge")  # pragma: no cover


def parse_query(text: str) -> Query:
    """Parse a filter; raises QueryError naming the part it could not read and saying
    what to write instead."""
    return Query(text, _Parser(text, _lex(text)).query())


# -- writing a query -----------------------------------------------------------------------


def _seconds(x: float) -> str:
    """A number of seconds as the language reads it back to the same float."""
    shown = repr(x)
    return format(Decimal(x), "f") if "e" in shown else shown


def _point(p: TimePoint | None) -> str:
    if p is None:
        return ""
    if not p.clock:
        return _seconds(p.seconds)
    hours = int(p.seconds // 3600)
    minutes = int((p.seconds - hours * 3600) // 60)
    return f"{hours}:{minutes:02d}:{_seconds(p.seconds - hours * 3600 - minutes * 60)}"


def show(node: Node) -> str:
    """`node` written in the filter language: `parse_query` reads it back to a tree that
    selects the same rows. (No word or register part holding a `"` can be written.)"""
    if isinstance(node, Column):
        if node.key == "kind":
            return "kind:" + ",".join(KIND_NAMES[v] for v in sorted(node.values))
        return f"{node.key}:" + ",".join(str(v) for v in sorted(node.values))
    if isinstance(node, StatusTerm):
        return "status:" + ",".join(sorted(node.names))
    if isinstance(node, Time):
        span = node.span
        if span.start is None and span.end is None:
            return "t:0-"  # every row starts at or after the first
        return f"t:{_point(span.start)}-{_point(span.end)}"
    if isinstance(node, Register):
        terms = [f'reg:"{p}"' for p in node.parts]
        return terms[0] if len(terms) == 1 else "(" + " or ".join(terms) + ")"
    if isinstance(node, Text):
        return f'"{node.word}"'
    if isinstance(node, Not):
        inner = show(node.part)
        return f"not ({inner})" if isinstance(node.part, And | Or) else f"not {inner}"
    if isinstance(node, And):
        return " and ".join(f"({show(p)})" if isinstance(p, Or) else show(p) for p in node.parts)
    if not node.parts:
        raise ValueError("a choice among nothing (it selects no row) cannot be written")
    return " or ".join(show(p) for p in node.parts)

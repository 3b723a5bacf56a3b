"""Provides the RTU framer's length search: which lengths a frame starting at a position of
the stream may have, and which of them its CRC confirms.

The function-code registry's length rules are compiled here once per channel: as rules by
code, which both framers test a frame's length against, and, for RTU, as the tables by
code that the framer's inline fast paths and the compiled core (`sniffer._core.rtu_scan`)
read. Where the fast paths cannot decide, `RtuLengths.candidates` tests every length the
rules, the open request's predicted answer and the exception envelope allow, in order of
preference, and `RtuLengths.silence_framed` frames what no rule knows by the silences
around it. The search only reads: the open request is the framer's, passed in, and so is
what it makes of the length found.
"""

from __future__ import annotations

from array import array
from collections.abc import Mapping
from typing import Protocol

from dissectors.checks import crc16
from dissectors.functions import (
    EXCEPTION_LENGTH,
    IMPOSSIBLE,
    NEED_MORE,
    AnswerRule,
    FunctionSpec,
    LengthRule,
    fixed,
)
from sniffer.model import Direction
from sniffer.vocab import Kind

MAX_RTU = 256
MIN_RTU = 4
FIXED = AnswerRule.FIXED
ECHO = AnswerRule.ECHO
WALKED = -3  # the answer's length needs the rule's walker
NO_ANSWER = -4  # the code has no answer rule
INF = float("inf")

# What an echoed answer repeats of its request, by code: the specification calls the
# normal answers to FC 5, 6, 21 and 22 echoes of their requests, and FC 8's answer
# repeats its sub-function (with the request's data for sub-function 0 only, each
# counter's value for the others). Their first bytes tell an echo from the master's
# next request where the wait cannot: a frame with the request's unit and code that
# comes after the response timeout, but not past it by more than the stamps'
# resolution, is its echo only if it repeats them (see `echo_key`). A vendor's code
# with an echoed answer is left to the wait alone (nothing says what its answer repeats).
ECHO_REPEATS = {5: 6, 6: 6, 21: 6, 22: 6, 8: 4}
NO_ECHO_KEY = -1
_KEY_BITS = 48


def echo_key(buf: bytes | bytearray, pos: int, fc: int) -> int:
    """What an echo of the request at `pos` (code `fc`) must repeat of it, as one number
    (`ECHO_REPEATS`: how many bytes, above the bytes' value); NO_ECHO_KEY where the code
    says nothing."""
    n = ECHO_REPEATS.get(fc, 0)
    if not n or pos + n > len(buf):
        return NO_ECHO_KEY
    return n << _KEY_BITS | int.from_bytes(buf[pos : pos + n], "big")


def not_its_echo(buf: bytes | bytearray, pos: int, end: int, key: int) -> bool:
    """Whether the frame at `pos` does not repeat what the echo `key` names (False
    while its bytes are not all there, below `end`, or `key` names nothing)."""
    if key < 0:
        return False
    n = key >> _KEY_BITS
    if pos + n > end:
        return False
    return int.from_bytes(buf[pos : pos + n], "big") != key & ((1 << _KEY_BITS) - 1)


# preference of a length rule's kind when it is not the answer the open request predicts
PREFERENCE = {int(Kind.REQUEST): 1, int(Kind.RESPONSE): 2, int(Kind.EXCEPTION): 2}

# A length rule and the kind of frame it describes (the fast paths use their own tables)
Rule = tuple[LengthRule, int]
_EXCEPTION_RULE: Rule = (fixed(EXCEPTION_LENGTH), int(Kind.EXCEPTION))


def compile_rules(
    direction: Direction, functions: Mapping[int, FunctionSpec]
) -> list[tuple[Rule, ...]]:
    """The length rules a frame of each code may follow on a channel of `direction`."""
    table: list[tuple[Rule, ...]] = [() for _ in range(256)]
    for code, spec in functions.items():
        rules: list[Rule] = []
        if spec.request_length is not None and direction != Direction.SLAVE:
            rules.append((spec.request_length, int(Kind.REQUEST)))
        if spec.response_length is not None and direction != Direction.MASTER:
            rules.append((spec.response_length, int(Kind.RESPONSE)))
        table[code] = tuple(rules)
    if direction != Direction.MASTER:
        for code in range(1, 128):
            table[code | 0x80] = (_EXCEPTION_RULE,)
    return table


class Silences(Protocol):
    """What the search needs of the framer's timeline: when a byte started, and where
    silence of at least t3.5 came before one."""

    def start_time(self, pos: int) -> float: ...

    def is_boundary(self, pos: int) -> bool: ...

    def next_boundary(self, pos: int) -> int | None: ...


class RtuLengths:
    """The length rules of one RTU channel, and the search the framer's slow path makes
    with them.

    `tables` spreads the registry's request lengths and answer rules over lists indexed
    by function code, for the framer's inline fast paths; `table_bytes` is the same, flat,
    for the compiled ones. A request length is kept only where it is a base plus at most
    one count byte; the others, and every answer no formula gives, are left to the rules.
    """

    def __init__(
        self,
        direction: Direction,
        functions: Mapping[int, FunctionSpec],
        rules: list[tuple[Rule, ...]],
        silences: Silences,
    ) -> None:
        self.rules = rules
        self.silences = silences
        # the exact answer length a request implies (none on a channel of requests only)
        self.answer: list[AnswerRule | None] = [None] * 256
        self.answer_pos = [NO_ANSWER] * 256
        answer_base = [0] * 256
        answer_item = [1] * 256
        answer_up = [0] * 256
        answer_byte = [1] * 256
        for code, spec in functions.items():
            rule = spec.answer
            if rule is None or direction == Direction.MASTER:
                continue
            self.answer[code] = rule
            self.answer_pos[code] = WALKED if rule.walker is not None else rule.quantity_pos
            answer_base[code] = rule.base
            answer_item[code] = rule.per_item
            answer_up[code] = rule.round_up
            answer_byte[code] = rule.per_byte
        # a request's length: base, plus the byte at count_pos if not 0
        request_base = [0] * 256
        request_count = [0] * 256
        for code, spec in functions.items():
            r = spec.request_length
            if r is None or direction == Direction.SLAVE or r.walker or r.count_size > 1:
                continue
            request_base[code] = r.base
            request_count[code] = r.count_pos if r.count_size else 0
        # in the order `sniffer._core.rtu_scan` reads them, 256 entries each
        self.tables = (
            request_base,
            request_count,
            self.answer_pos,
            answer_base,
            answer_item,
            answer_up,
            answer_byte,
        )
        self.table_bytes = array("q", [v for table in self.tables for v in table]).tobytes()
        self.rule_bytes = _rule_bytes(rules)

    def predict(self, buf: bytearray, pos: int, length: int, fc: int) -> int | None:
        """The length of the answer the request at `pos` asks for (None: no rule says)."""
        rule = self.answer[fc]
        return None if rule is None else rule.length(buf[pos : pos + length])

    def candidates(
        self,
        buf: bytearray,
        pos: int,
        end: int,
        unit: int,
        fc: int,
        final: bool,
        pending_unit: int,
        pending_fc: int,
        pending_len: int,
        deadline: float,
        band: float = 0.0,
        key: int = NO_ECHO_KEY,
    ) -> tuple[int, int, bool]:
        """Test every length the registry allows at `pos`, and the answer the open request
        (`pending_*`, awaited until `deadline` when it is echoed; from `band` before it
        only a frame that repeats `key`, see `ECHO_REPEATS`) predicts: (length, kind,
        waiting)."""
        waiting = False
        # (length, preference, kind): the answer the last request predicts is preferred
        # (0); any other frame is more likely a request (1) than an answer nobody asked
        # for (2)
        cands: list[tuple[int, int, int]] = []
        pending = unit == pending_unit and (fc & 0x7F) == pending_fc
        if pending and (fc & 0x80 or not self._expired(buf, pos, end, deadline, band, key)):
            if fc & 0x80:
                cands.append((EXCEPTION_LENGTH, 0, int(Kind.EXCEPTION)))
            else:
                # A counted answer whose byte count is not the one its request asked for
                # is still the answer (a slave's mistake, shown as a problem), unless a
                # request passes its check in the same bytes: a request followed by a 00
                # byte passes the CRC one byte longer, at the length an unanswered
                # request's answer would have.
                counted = self.answer_pos[fc] >= 0
                agrees = not counted or buf[pos + 2] == pending_len - 5
                cands.append((pending_len, 0 if agrees else 3, int(Kind.RESPONSE)))
        for rule, rkind in self.rules[fc]:
            length = rule.length(buf, pos, end)
            if length == IMPOSSIBLE:
                continue
            if length == NEED_MORE:
                waiting = waiting or not final
                continue
            if MIN_RTU <= length <= MAX_RTU:
                cands.append((length, PREFERENCE[rkind], rkind))
        if len(cands) > 1:
            cands.sort()
        for n, (length, prio, ckind) in enumerate(cands):
            if pos + length > end:
                return 0, 0, waiting or not final
            if crc16(buf[pos : pos + length]) == 0:
                if prio and n + 1 < len(cands):
                    # A frame followed by 0x00 bytes passes the CRC at every length up
                    # to the last zero, a frame whose CRC ends in 0x00 passes one byte
                    # short, and one in 65,536 requests has a prefix that passes as an
                    # answer nobody asked for: a longer candidate that also passes is
                    # told apart by preference, never by length.
                    return _preferred(buf, pos, end, cands[n + 1 :], length, prio, ckind, final)
                return length, ckind, False
        return 0, 0, waiting

    def _expired(
        self, buf: bytearray, pos: int, end: int, deadline: float, band: float, key: int
    ) -> bool:
        """Whether an echoed answer awaited until `deadline` can no longer start at `pos`
        (from `band` before it, a frame that does not repeat `key`)."""
        if deadline == INF:
            return False
        t0 = self.silences.start_time(pos)
        return t0 > deadline or (t0 > deadline - band and not_its_echo(buf, pos, end, key))

    def silence_framed(
        self, buf: bytearray, pos: int, end: int, fc: int, final: bool
    ) -> tuple[int, int, bool]:
        """A frame no length rule knows (user or unknown function codes), bounded by
        silence on both sides, with a right CRC: (length, kind, waiting)."""
        silences = self.silences
        if not silences.is_boundary(pos):
            return 0, 0, False
        nxt = silences.next_boundary(pos)
        if nxt is None:
            if not final:
                return 0, 0, end - pos <= MAX_RTU  # its end is not seen yet
            nxt = end
        length = nxt - pos
        if MIN_RTU <= length <= MAX_RTU and crc16(buf[pos : pos + length]) == 0:
            return length, int(Kind.EXCEPTION if fc & 0x80 else Kind.UNKNOWN), False
        return 0, 0, False


def _rule_bytes(rules: list[tuple[Rule, ...]]) -> bytes:
    """The length rules by code, flat, for the compiled copy of the search
    (`sniffer._core.rtu_search`): two slots a code of (kind, base, count_pos, count_size),
    int64; kind 0 where the code has no rule in the slot, -1 where the copy cannot follow
    the code's rules (a walker, or more rules than slots), so that it leaves the search
    at that code to `candidates`."""
    flat: list[int] = []
    for table in rules:
        slots = [(kind, rule.base, rule.count_pos, rule.count_size) for rule, kind in table]
        if len(slots) > 2 or any(rule.walker is not None for rule, _ in table):
            slots = [(-1, 0, 0, 0)]
        slots += [(0, 0, 0, 0)] * (2 - len(slots))
        flat.extend(v for slot in slots for v in slot)
    return array("q", flat).tobytes()


def _preferred(
    buf: bytearray,
    pos: int,
    end: int,
    longer: list[tuple[int, int, int]],
    length: int,
    prio: int,
    kind: int,
    final: bool,
) -> tuple[int, int, bool]:
    """Of a frame of `length` and the `longer` candidates of a kind preferred to its
    that pass the CRC too, the preferred one (waiting while their bytes are still to
    come). The framer's fast path takes a request whole when no answer is awaited, so
    the search must not take the answer-shaped prefix of one: which path frames a frame
    (whether the reads split it) must not change what it is (tests/framing/
    test_read_shapes.py). Found on a write of 46 registers whose first 8 bytes pass as
    the answer to it: byte count 0x5C, first data byte 0x9C."""
    best = (prio, length, kind)
    for length2, prio2, kind2 in longer:
        if prio2 >= best[0] or length2 == length:
            continue
        if pos + length2 > end:
            if not final:
                return 0, 0, True  # wait for the bytes that decide
            continue
        if crc16(buf[pos : pos + length2]) == 0:
            best = (prio2, length2, kind2)
    return best[1], best[2], False

"""The RTU length search on its own: the tables the fast paths index, and the lengths the
slow path finds at a position, given the open request and the silences around it."""

from __future__ import annotations

from array import array

from dissectors.checks import with_crc
from dissectors.functions import FUNCTIONS
from sniffer.framing.lengths import (
    ECHO,
    FIXED,
    INF,
    NO_ANSWER,
    RtuLengths,
    compile_rules,
)
from sniffer.model import Direction
from sniffer.vocab import Kind

READ_REQ = with_crc(bytes.fromhex("0103006b0003"))  # read 3 holding registers
READ_RESP = with_crc(bytes.fromhex("010306022b00000064"))
WRITE6 = with_crc(bytes.fromhex("010600010003"))  # its answer is the same bytes
UNKNOWN_FC = with_crc(bytes.fromhex("0141deadbeef"))  # a code no rule knows
CHAR = 0.001  # seconds a byte, for the fake timeline


class Silences:
    """A timeline of evenly spaced bytes with silences before the given offsets."""

    def __init__(self, *boundaries: int) -> None:
        self.boundaries = sorted(boundaries)

    def start_time(self, pos: int) -> float:
        return pos * CHAR

    def is_boundary(self, pos: int) -> bool:
        return pos in self.boundaries

    def next_boundary(self, pos: int) -> int | None:
        return next((b for b in self.boundaries if b > pos), None)


def lengths(direction: Direction = Direction.UNKNOWN, *boundaries: int) -> RtuLengths:
    rules = compile_rules(direction, FUNCTIONS)
    return RtuLengths(direction, FUNCTIONS, rules, Silences(*boundaries))


def search(
    found: RtuLengths, data: bytes, final: bool = True, pending: tuple[int, int, int] = (-1, -1, 0)
) -> tuple[int, int, bool]:
    buf = bytearray(data)
    return found.candidates(buf, 0, len(buf), buf[0], buf[1], final, *pending, INF)


def test_the_tables_are_flat_in_the_order_the_compiled_core_reads_them() -> None:
    found = lengths()
    assert len(found.tables) == 7 and all(len(t) == 256 for t in found.tables)
    flat = array("q")
    flat.frombytes(found.table_bytes)
    assert flat.tolist() == [v for t in found.tables for v in t]
    request_base, request_count, answer_pos, answer_base, *_ = found.tables
    assert (request_base[3], request_count[3]) == (8, 0)
    assert (request_base[16], request_count[16]) == (9, 6)  # plus its byte count
    assert (answer_pos[3], answer_base[3]) == (4, 5)  # 5 + 2 bytes per register
    assert (answer_pos[16], answer_base[16]) == (FIXED, 8)
    assert answer_pos[6] == ECHO
    assert request_base[43] == 0 and answer_pos[43] == NO_ANSWER  # walked, not tabled


def test_a_channel_of_one_direction_has_only_its_own_lengths() -> None:
    master, slave = lengths(Direction.MASTER), lengths(Direction.SLAVE)
    assert (
        set(master.answer_pos) == {NO_ANSWER}
        and master.predict(bytearray(READ_REQ), 0, 8, 3) is None
    )
    assert not any(slave.tables[0]) and slave.predict(bytearray(READ_REQ), 0, 8, 3) == 11
    assert search(master, READ_REQ) == (8, int(Kind.REQUEST), False)
    assert search(slave, READ_REQ) == (0, 0, False)
    assert search(slave, READ_RESP) == (11, int(Kind.RESPONSE), False)


def test_the_predicted_answer_is_preferred_to_a_request_of_the_same_bytes() -> None:
    found = lengths()
    assert search(found, WRITE6) == (8, int(Kind.REQUEST), False)
    assert search(found, WRITE6, pending=(1, 6, 8)) == (8, int(Kind.RESPONSE), False)
    assert search(found, WRITE6, pending=(2, 6, 8)) == (8, int(Kind.REQUEST), False)


def test_an_echoed_answer_is_awaited_only_until_its_deadline() -> None:
    found = lengths()
    buf = bytearray(b"\0" * 10 + WRITE6)  # starts at 10 * CHAR
    on_time = found.candidates(buf, 10, len(buf), 1, 6, True, 1, 6, 8, 10 * CHAR)
    late = found.candidates(buf, 10, len(buf), 1, 6, True, 1, 6, 8, 9 * CHAR)
    assert on_time == (8, int(Kind.RESPONSE), False)
    assert late == (8, int(Kind.REQUEST), False)


def test_a_frame_cut_short_is_waited_for_until_the_end() -> None:
    found = lengths()
    assert search(found, READ_REQ[:6], final=False) == (0, 0, True)
    assert search(found, READ_REQ[:6], final=True) == (0, 0, False)
    assert search(found, READ_REQ[:-1] + b"\xff") == (0, 0, False)  # a bad CRC: no frame


def test_a_frame_no_rule_knows_is_framed_by_the_silences_around_it() -> None:
    n = len(UNKNOWN_FC)
    buf = bytearray(UNKNOWN_FC + READ_REQ)
    assert search(lengths(), UNKNOWN_FC) == (0, 0, False)
    bounded = lengths(Direction.UNKNOWN, 0, n)
    assert bounded.silence_framed(buf, 0, len(buf), 0x41, False) == (n, int(Kind.UNKNOWN), False)
    unbounded = lengths(Direction.UNKNOWN, 1, n)  # no silence before it
    assert unbounded.silence_framed(buf, 0, len(buf), 0x41, True) == (0, 0, False)
    open_end = lengths(Direction.UNKNOWN, 0)  # its end not seen yet
    tail = bytearray(UNKNOWN_FC)
    assert open_end.silence_framed(tail, 0, n, 0x41, False) == (0, 0, True)
    assert open_end.silence_framed(tail, 0, n, 0x41, True) == (n, int(Kind.UNKNOWN), False)

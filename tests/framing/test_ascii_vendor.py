"""Vendor start characters in Modbus ASCII: ABL's eMH1 wallboxes answer a `:` request
with `>`, hex, LRC and CR LF. Such answers are frames (flagged as a vendor variant, an
info fact), framed, paired, timed and dissected exactly as `:` answers are; a `>` with
no frame after it is noise, as before.

The exchanges are written here byte by byte from ABL's interface description as evcc's
and node-modbus-serial's issues quote it: the master reads the status registers from
0x002E (FC 3) and sets the charging current at 0x0014 (FC 16)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dissectors.checks import lrc
from dissectors.dissect import dissect
from dissectors.envelope.ascii import VENDOR_STARTS, open_ascii
from dissectors.values import Role
from sniffer.framing.pairing import measure
from sniffer.framing.pipeline import Pipeline, frame_capture
from sniffer.framing.serial import looks_ascii
from sniffer.framing.store import FrameStore
from sniffer.model import Chunk, LineSettings
from sniffer.vocab import FLAG_MEANINGS, INFO, PROBLEM_MASK, Flag, Kind, Status

ABL = LineSettings(baud=38400, bytesize=8, parity="E", stopbits=1, mode="ascii")

# the wallbox's own frames, as its interface description lays them out
READ = b":0303002E0005C7\r\n"  # unit 3, FC 3, 5 registers from 0x002E; LRC C7
STATUS = b">03030A2EA1B20C025803E803E833\r\n"  # 10 data bytes; LRC 33
SET = b":0310001400010202587C\r\n"  # FC 16: 0x0258 into 0x0014; LRC 7C
SET_OK = b">031000140001D8\r\n"  # the write's answer; LRC D8
STATUS_BAD = b">03030A2EA1B20C025803E803E834\r\n"  # LRC 34: one off


def colon(frame: bytes) -> bytes:
    """The same frame opened by the standard ':'."""
    return b":" + frame[1:]


def test_the_frames_written_here_are_what_the_lrc_says() -> None:
    for frame in (READ, STATUS, SET, SET_OK):
        assert open_ascii(frame).check_ok, frame
        decoded = bytes.fromhex(frame[1:-2].decode())
        assert lrc(decoded[:-1]) == decoded[-1]
    assert not open_ascii(STATUS_BAD).check_ok
    assert open_ascii(STATUS).vendor == "ABL eMH1 wallboxes' answers"
    assert open_ascii(READ).vendor == ""


def rows(store: FrameStore) -> list[tuple[Kind, bytes, int, Status, int]]:
    store.sync()
    return [
        (
            Kind(store.kind[i]),
            store.raw(i),
            store.flags[i],
            Status(store.status[i]),
            store.partner[i],
        )
        for i in range(len(store))
    ]


def exchange(frames: list[tuple[float, bytes]], line: LineSettings = ABL) -> FrameStore:
    """Each frame one read, stamped at its end (`t` the end of the frame)."""
    return frame_capture([Chunk(raw, t_end=1_700_000_000 + t) for t, raw in frames], line)


ABL_EXCHANGE = [
    (0.000, READ),
    (0.030, STATUS),
    (1.000, SET),
    (1.025, SET_OK),
    (2.000, READ),
    (2.030, STATUS_BAD),
    (3.000, READ),
    (3.030, STATUS),
]

V, A = int(Flag.VENDOR_START), int(Flag.ASCII)


def test_abl_answers_are_frames_paired_with_their_requests() -> None:
    got = rows(exchange(ABL_EXCHANGE))
    assert got == [
        (Kind.REQUEST, READ, A, Status.OK, 1),
        (Kind.RESPONSE, STATUS, A | V, Status.OK, 0),
        (Kind.REQUEST, SET, A, Status.OK, 3),
        (Kind.RESPONSE, SET_OK, A | V, Status.OK, 2),
        (Kind.REQUEST, READ, A, Status.BAD_ANSWER, 5),
        # a wrong LRC is a frame with a bad check, not noise: the master drops it
        (Kind.RESPONSE, STATUS_BAD, A | V | int(Flag.CHECK_BAD), Status.BAD_ANSWER, 4),
        (Kind.REQUEST, READ, A, Status.OK, 7),
        (Kind.RESPONSE, STATUS, A | V, Status.OK, 6),
    ]


def test_pairing_latency_and_dissection_are_those_of_colon_answers() -> None:
    """The same exchange with every answer opened by ':': the same rows, statuses,
    partners, latencies and dissections; only the vendor fact differs."""
    vendor = exchange(ABL_EXCHANGE)
    standard = exchange([(t, colon(raw)) for t, raw in ABL_EXCHANGE])
    assert len(vendor) == len(standard) == len(ABL_EXCHANGE)
    for i in range(len(vendor)):
        a, b = vendor.view(i), standard.view(i)
        assert (a.kind, a.status, a.partner, a.unit, a.function) == (
            b.kind,
            b.status,
            b.partner,
            b.unit,
            b.function,
        )
        assert a.flags & ~V == b.flags
        assert (a.t, a.t_end) == (b.t, b.t_end)
        assert measure(vendor, i) == measure(standard, i)
        assert a.body() == b.body()
        role = Role.REQUEST if a.kind == Kind.REQUEST else Role.RESPONSE
        assert dissect(a.body(), role) == dissect(b.body(), role)
    assert measure(vendor, 1) is not None and measure(vendor, 1).seconds > 0  # type: ignore[union-attr]


def test_the_vendor_fact_is_info_with_a_sentence_a_tag_and_the_framing_stage() -> None:
    meaning = FLAG_MEANINGS[Flag.VENDOR_START]
    assert (meaning.kind, meaning.severity, meaning.tag, meaning.stage) == (
        "vendor-start",
        INFO,
        "vendor",
        "framing",
    )
    assert not Flag.VENDOR_START & PROBLEM_MASK  # a fact: it colours no row as a problem
    for start in VENDOR_STARTS:  # the sentence names every start the framer accepts
        assert f"'{chr(start)}'" in meaning.text


def one_burst(data: bytes) -> list[tuple[Kind, bytes, int, Status, int]]:
    return rows(frame_capture([Chunk(data, t_end=1.0)], ABL))


def test_a_gt_in_the_middle_of_noise_is_noise() -> None:
    noise = b"\x00\x13>\x7f\xfe>0103zz>>\r\n"
    got = one_burst(noise + READ + STATUS)
    assert got[0] == (Kind.NOISE, noise, A, Status.NONE, -1)
    assert [r[:3] for r in got[1:]] == [(Kind.REQUEST, READ, A), (Kind.RESPONSE, STATUS, A | V)]


def test_noise_right_before_a_vendor_frame_is_cut_off_it() -> None:
    got = one_burst(READ + b"\xff\xfe>\x01" + STATUS)
    assert [r[:3] for r in got] == [
        (Kind.REQUEST, READ, A),
        (Kind.NOISE, b"\xff\xfe>\x01", A),
        (Kind.RESPONSE, STATUS, A | V),
    ]
    assert got[2][3] == Status.OK


@pytest.mark.parametrize(
    ("tail", "flag"),
    [
        (b"\n", int(Flag.NO_CR)),  # LF alone ends it, as it ends a ':' frame
        (b"", int(Flag.UNTERMINATED)),  # the capture ends before CR LF
        (b"\r", int(Flag.UNTERMINATED)),
    ],
)
def test_vendor_frames_end_as_colon_frames_do(tail: bytes, flag: int) -> None:
    frame = STATUS[:-2] + tail
    got = one_burst(READ + frame)
    assert got[1][:3] == (Kind.RESPONSE, frame, A | V | flag)


def test_a_colon_aborts_a_vendor_frame() -> None:
    cut = STATUS[:19]  # the start and 18 digits
    got = one_burst(READ + cut + READ + STATUS)
    assert [r[1] for r in got] == [READ, cut, READ, STATUS]
    assert got[1][2] == A | V | int(Flag.ABORTED | Flag.CHECK_BAD)  # its LRC is cut off too
    standard = one_burst(READ + colon(cut) + READ + colon(STATUS))  # as with ":"
    assert [r[2] & ~V for r in got] == [r[2] for r in standard]


def test_a_gt_inside_an_open_colon_frame_does_not_abort_it() -> None:
    """The standard lets only ':' abort a frame: a '>' inside one is a wrong character."""
    glued = READ[:-2] + STATUS
    got = one_burst(glued)
    assert len(got) == 1 and got[0][2] & Flag.NON_HEX and not got[0][2] & V


@pytest.mark.parametrize(
    "junk",
    [
        b">0103\r\n",  # too short for unit, function code and LRC
        b">01030\r\n",  # an odd number of digits
        b">" + b"0" * 600 + b"\r\n",  # longer than any ASCII frame
        b">01030A2E\r\r\n",  # two CRs
        b">01030A2E ",  # a space
    ],
)
def test_a_gt_without_a_frame_after_it_is_noise(junk: bytes) -> None:
    got = one_burst(READ + junk)
    assert got[0][:2] == (Kind.REQUEST, READ)
    assert {r[0] for r in got[1:]} == {Kind.NOISE}
    assert b"".join(r[1] for r in got[1:]) == junk


def test_abl_answers_alone_are_told_to_be_ascii() -> None:
    """A port that hears only the wallbox (one wire per direction) sees `>` frames only."""
    assert looks_ascii(STATUS * 2)
    assert looks_ascii((READ + STATUS) * 2)
    assert not looks_ascii(b"\x01\x03\x02\x00\x01>\n" * 4)
    pipeline = Pipeline(LineSettings(mode="auto"))
    pipeline.feed(Chunk(STATUS + SET_OK + STATUS, t_end=1.0))
    pipeline.finish()
    assert pipeline.mode == "ascii"
    assert Kind.NOISE not in {Kind(k) for k in pipeline.store.kind}
    assert all(f & V for f in pipeline.store.flags)


def fed(data: bytes, cuts: list[int]) -> FrameStore:
    """`data` in reads cut after the given lengths, 10 ms apart."""
    chunks, at, k = [], 0, 0
    while at < len(data):
        n = cuts[k % len(cuts)]
        chunks.append(Chunk(data[at : at + n], t_end=1_700_000_000 + 0.01 * k))
        at, k = at + n, k + 1
    return frame_capture(chunks, ABL)


def frames(store: FrameStore) -> list[tuple[Kind, bytes, int]]:
    return [(k, raw, f) for k, raw, f, _s, _p in rows(store) if k != Kind.NOISE]


STREAM = b"".join(raw for _t, raw in ABL_EXCHANGE)


@settings(max_examples=150, deadline=None)
@given(
    st.lists(st.integers(1, 40), min_size=1, max_size=12),
    st.lists(st.sampled_from([b"\x00", b">", b"\xfe", b">01", b"\r\n", b"7F"]), max_size=4),
)
def test_cutting_the_reads_anywhere_gives_the_same_frames(
    cuts: list[int], junk: list[bytes]
) -> None:
    """Live reads end anywhere: a `>` whose frame is not all in yet waits for the next
    read. Every byte lands in one row, in order."""
    data = READ + b"".join(junk) + STATUS + SET + SET_OK
    whole = frames(frame_capture([Chunk(data, t_end=1.0)], ABL))
    store = fed(data, cuts)
    assert frames(store) == whole
    assert [r[1] for r in whole][-3:] == [STATUS, SET, SET_OK]
    store.sync()
    position = 0
    for i in range(len(store)):
        assert store.offset[i] == position
        position += store.length[i]
    assert position == len(data)


@settings(max_examples=100, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.integers(1, 247),
            st.integers(0, 0xFFFF),
            st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=8),
            st.booleans(),
        ),
        min_size=1,
        max_size=8,
    )
)
def test_any_reads_answered_with_gt_frame_as_with_colon(
    polls: list[tuple[int, int, list[int], bool]],
) -> None:
    """Property: answering with '>' instead of ':' changes nothing but the vendor fact
    (frames, kinds, statuses, partners), whatever is read and whether the LRC is right."""

    def frame(start: bytes, body: bytes, good: bool = True) -> bytes:
        check = lrc(body) if good else (lrc(body) + 1) & 0xFF
        return start + (body + bytes([check])).hex().upper().encode() + b"\r\n"

    def capture(answer_start: bytes) -> FrameStore:
        chunks = []
        for k, (unit, address, words, good) in enumerate(polls):
            ask = bytes([unit, 3, *address.to_bytes(2, "big"), 0, len(words)])
            data = b"".join(w.to_bytes(2, "big") for w in words)
            reply = bytes([unit, 3, len(data)]) + data
            chunks.append(Chunk(frame(b":", ask), t_end=1_700_000_000 + k))
            chunks.append(Chunk(frame(answer_start, reply, good), t_end=1_700_000_000.05 + k))
        return frame_capture(chunks, ABL)

    vendor, standard = rows(capture(b">")), rows(capture(b":"))
    assert len(vendor) == len(standard) == 2 * len(polls)
    for (k1, raw1, f1, s1, p1), (k2, raw2, f2, s2, p2) in zip(vendor, standard, strict=True):
        assert (k1, raw1[1:], s1, p1) == (k2, raw2[1:], s2, p2)
        assert f1 == f2 | (V if raw1[:1] == b">" else 0)


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.sampled_from([b">", b":", b"0", b"3", b"A", b"f", b"\r", b"\n", b"\x00"])),
    st.lists(st.integers(1, 9), min_size=1, max_size=5),
)
def test_any_mix_of_starts_digits_and_line_ends_frames_every_byte_once(
    pieces: list[bytes], cuts: list[int]
) -> None:
    """Property: however starts, hex digits and line ends are mixed and cut into reads,
    framing never fails, every byte lands in one row in order, and a row flagged as a
    vendor variant starts with a vendor's start and holds hex digits only."""
    data = b"".join(pieces)
    store = fed(data, cuts) if data else frame_capture([], ABL)
    store.sync()
    position = 0
    for i in range(len(store)):
        assert store.offset[i] == position
        position += store.length[i]
        raw = store.raw(i)
        if store.flags[i] & V:
            assert raw[0] in VENDOR_STARTS and store.kind[i] != Kind.NOISE
            digits = raw[1:].rstrip(b"\r\n")
            assert len(digits) >= 6 and len(digits) % 2 == 0
            assert all(c in b"0123456789ABCDEFabcdef" for c in digits)
    assert position == len(data)

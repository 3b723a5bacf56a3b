"""Fuzz: framers (RTU, ASCII, auto) over random and damaged streams cut into chunks any
way, then pairing, annotation with device dictionaries, and every listing."""

from __future__ import annotations

import csv
import io
import json
import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

from dissectors.checks import ascii_frame
from sniffer.meaning.annotate import load_bindings
from sniffer.model import Chunk, Direction, LineSettings
from sniffer.outputs.export import (
    REGISTER_COLUMNS,
    TRANSACTION_COLUMNS,
    register_records,
    transaction_records,
    write_table,
)
from sniffer.outputs.listing import Lister
from sniffer.session.session import Session
from sniffer.sources.synth import polling_frames
from sniffer.text import FORMULA_START
from tests.fuzz.harness import budget, bytes_by_channel, conserved, mutated, no_hang
from tests.support.seedvectors import load_examples, wire_bytes

pytestmark = [pytest.mark.fuzz, pytest.mark.slow]

LINES = {
    "rtu": LineSettings(baud=19200, parity="E", mode="rtu"),
    "ascii": LineSettings(baud=9600, bytesize=7, parity="E", mode="ascii"),
    "auto": LineSettings(baud=19200, parity="N", stopbits=2, mode="auto"),
}
# the shipped dictionaries bound to the units the synthetic master polls
BINDINGS = load_bindings(None, ["1=rvs-dn", "2=dcrl", "3=ved903b", "17=rvs-dn:=cmd"], [])


def _seeds() -> list[bytes]:
    frames = polling_frames(40, seed=3)
    rtu = b"".join(f.raw for f in frames)
    ascii_stream = b"".join(ascii_frame(f.raw[:-2]) for f in frames[:20])
    vectors = b"".join(wire_bytes(example) for example in load_examples())
    return [rtu, ascii_stream, vectors, rtu[:200] + ascii_stream[:200]]


SEEDS = _seeds()
streams = st.one_of(mutated(SEEDS), st.binary(max_size=400))


@st.composite
def chunked(draw: st.DrawFn, data: bytes) -> list[Chunk]:
    """`data` cut into reads, on one or two channels, timed anyhow: exact, bursts,
    all at once, or going backwards (print-time stamps)."""
    chunks: list[Chunk] = []
    pos = 0
    t = 1_750_000_000.0
    two = draw(st.booleans())
    while pos < len(data):
        size = draw(st.integers(1, 64))
        piece = data[pos : pos + size]
        t += draw(st.sampled_from([0.0, 1e-4, 0.002, 0.05, 1.5, -0.01]))
        channel = draw(st.integers(0, 1)) if two else 0
        direction = draw(st.sampled_from(list(Direction)))
        start = t - len(piece) * 1e-4 if draw(st.booleans()) else None
        chunks.append(Chunk(piece, t_end=t, t_start=start, channel=channel, direction=direction))
        if draw(st.integers(0, 9)) == 0:
            chunks.append(Chunk(b"", t_end=t, channel=channel, event="framing error", note="x"))
        pos += size
    return chunks


CONTROL = re.compile("[\x00-\x09\x0b\x0c\x0e-\x1f]")  # any C0 control but CR and LF


def _listings(session: Session) -> None:
    rows = range(len(session.store))
    describer = session.describer
    for fmt in ("text", "jsonl", "csv"):
        out = io.StringIO()
        Lister(out, fmt, describer).write(rows, flush=False)
        text = out.getvalue()
        assert CONTROL.search(text) is None, fmt
        if fmt == "jsonl":
            for line in text.splitlines():
                json.loads(line)
        if fmt == "csv":
            for row in list(csv.reader(io.StringIO(text)))[1:]:
                for cell in row:
                    if cell[:1] in FORMULA_START:
                        float(cell)  # only numbers may start with a sign
    for columns, records in (
        (TRANSACTION_COLUMNS, transaction_records(describer, rows)),
        (REGISTER_COLUMNS, register_records(describer, rows)),
    ):
        write_table(io.StringIO(), "csv", columns, records)
    session.stats.table({u: b.label for u, b in BINDINGS.items()})


@budget(600)
@given(st.data(), st.sampled_from(sorted(LINES)), st.booleans(), st.booleans())
def test_framing_pairing_and_listings_never_raise_and_conserve_bytes(
    data: st.DataObject, mode: str, exact: bool, bound: bool
) -> None:
    stream = data.draw(streams)
    chunks = data.draw(chunked(stream))
    # where a reader looks at the store while it fills (Session.ingest does it by the
    # clock, which a test cannot repeat): drawn, so a failure replays
    looks = data.draw(st.lists(st.booleans(), min_size=len(chunks), max_size=len(chunks)))
    with no_hang():
        session = Session(
            LINES[mode], exact_timing=exact, timeout=0.1, bindings=BINDINGS if bound else None
        )
        for chunk, look in zip(chunks, looks, strict=True):
            session.feed(chunk)
            if look:
                session.refresh()
        session.finish()
        conserved(session.store, bytes_by_channel(chunks))
        _listings(session)

"""An ABL eMH1 wallbox on Modbus ASCII, replayed: its `>` answers are frames, paired and
timed, and every listing (text, JSONL, CSV) and the Wireshark export say they are a vendor
variant. The capture is read from a text2pcap dump (direction labels and ISO times), the
same dump without labels and times (as `od` writes it), raw bytes (no time at all) and a
pcapng of reads (read-end stamps); `--mode auto` tells ASCII from the traffic each time."""

from __future__ import annotations

import csv
import io
import json
import re
from pathlib import Path

import pytest

from sniffer.cli import main
from sniffer.session.session import replay_file
from sniffer.sources import open_capture
from sniffer.sources.linktypes import EPB_FLAG_INBOUND, EPB_FLAG_OUTBOUND
from sniffer.sources.pcapng_writer import PcapngWriter
from sniffer.vocab import Flag, Kind, Status

CAPTURE = Path(__file__).parent.parent / "captures" / "ascii" / "abl_emh1_text2pcap.txt"
VENDOR = "vendor variant: '>' where Modbus ASCII has ':' (ABL eMH1 answers)"

READ = b":0303002E0005C7\r\n"
STATUS = b">03030A2EA1B20C025803E803E833\r\n"
SET = b":0310001400010202587C\r\n"
SET_OK = b">031000140001D8\r\n"
STATUS_BAD = b">03030A2EA1B20C025803E803E834\r\n"
GLITCH = b"\x00\xfe>\x13\x7f"
PACKETS = [READ, STATUS, SET, SET_OK, READ, STATUS_BAD, GLITCH, READ, STATUS]
# each packet's time in the dump, from 12:00:00
TIMES = [0.0, 0.031, 1.0, 1.024, 2.0, 2.031, 2.4, 3.0, 3.029]
LINE_ARGS = ["--baud", "38400", "--parity", "E"]

EXPECTED = [
    (Kind.REQUEST, Status.OK),
    (Kind.RESPONSE, Status.OK),
    (Kind.REQUEST, Status.OK),
    (Kind.RESPONSE, Status.OK),
    (Kind.REQUEST, Status.BAD_ANSWER),
    (Kind.RESPONSE, Status.BAD_ANSWER),
    (Kind.NOISE, Status.NONE),
    (Kind.REQUEST, Status.OK),
    (Kind.RESPONSE, Status.OK),
]


def od_dump(path: Path) -> Path:
    """The fixture without its direction and time lines: `od -Ax -tx1` output only."""
    kept = [
        line
        for line in CAPTURE.read_text(encoding="ascii").splitlines()
        if not line.startswith(("O ", "I "))
    ]
    path.write_text("\n".join(kept) + "\n", encoding="ascii")
    return path


def raw_bytes(path: Path) -> Path:
    path.write_bytes(b"".join(PACKETS))
    return path


def pcapng_reads(path: Path) -> Path:
    """One read per packet, stamped at its end, requests flagged outbound by the
    capturing master and the wallbox's answers inbound."""
    with path.open("wb") as f:
        writer = PcapngWriter(f)
        port = writer.add_interface(147, name="ttyUSB0")
        for t, data in zip(TIMES, PACKETS, strict=True):
            flags = EPB_FLAG_OUTBOUND if data[:1] == b":" else EPB_FLAG_INBOUND
            writer.write_packet(port, 1_714_564_800 + t, data, flags=flags)
    return path


SOURCES = {
    "text2pcap": lambda tmp: CAPTURE,
    "od": lambda tmp: od_dump(tmp / "abl_od.txt"),
    "raw": lambda tmp: raw_bytes(tmp / "abl.bin"),
    "pcapng": lambda tmp: pcapng_reads(tmp / "abl.pcapng"),
}


@pytest.mark.parametrize("source", list(SOURCES))
def test_every_source_frames_and_pairs_the_vendor_answers(source: str, tmp_path: Path) -> None:
    path = SOURCES[source](tmp_path)
    session = replay_file(path)  # the line's mode from the traffic
    store = session.store
    assert session.pipeline.mode == "ascii"
    assert [store.raw(i) for i in range(len(store))] == PACKETS
    assert [(Kind(store.kind[i]), Status(store.status[i])) for i in range(len(store))] == EXPECTED
    for i, data in enumerate(PACKETS):
        vendor = bool(store.flags[i] & Flag.VENDOR_START)
        assert vendor == (data[:1] == b">" and store.kind[i] != Kind.NOISE), i
    assert store.flags[5] & Flag.CHECK_BAD  # a bad LRC: a frame with a bad check
    assert [store.partner[i] for i in (1, 3, 5, 8)] == [0, 2, 4, 7]


def test_the_text_listing_says_vendor_variant_on_each_answer(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["replay", str(CAPTURE), "--format", "text", *LINE_ARGS]) == 0
    note, *rows = capsys.readouterr().out.splitlines()
    assert note.startswith("# timing: when each line was logged")
    assert len(rows) == len(PACKETS)
    for k, row in enumerate(rows):
        assert (VENDOR in row) == (k in (1, 3, 5, 8)), row
    assert "LRC 0x34 wrong, expected 0x33" in rows[5]
    # the latency of a '>' answer, as of any answer: 31 ms between the dump's times less
    # the answer's characters at 38400 8E1 (31 * 11 / 38400 s) is 22.1 ms; a hexdump's
    # times are print times to 1 ms, so that is at most 22.1 + 1 ms: a bound, rounded up
    assert re.search(r"<24ms\b", rows[1])
    assert "noise" in rows[6]


def test_jsonl_and_csv_list_the_vendor_fact_as_an_info_problem(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["replay", str(CAPTURE), "--format", "jsonl", *LINE_ARGS]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    answer = records[1]
    assert answer["kind"] == "response" and answer["transaction"]["status"] == "ok"
    assert answer["problems"] == [VENDOR]
    assert answer["problem_details"] == [
        {"kind": "vendor-start", "severity": "info", "text": VENDOR, "span": None}
    ]
    assert "problem_details" not in records[0]  # a ':' request: nothing to say
    bad = records[5]
    assert [p["kind"] for p in bad["problem_details"]] == ["check", "vendor-start"]
    assert main(["replay", str(CAPTURE), "--format", "csv", *LINE_ARGS]) == 0
    table = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    assert [row["problems"] == VENDOR for row in table] == [k in (1, 3, 8) for k in range(9)]


def test_the_wireshark_export_says_it_in_the_comment_and_reads_back(tmp_path: Path) -> None:
    out = tmp_path / "abl.pcapng"
    assert main(["export", str(CAPTURE), "-o", str(out), *LINE_ARGS]) == 0
    chunks = list(open_capture(out).chunks())
    assert [c.data for c in chunks] == PACKETS  # the line's bytes, '>' and all
    notes = [c.note or "" for c in chunks]
    assert notes[1].startswith('ASCII ">03030A2E') and notes[1].endswith(VENDOR)
    assert VENDOR not in notes[0]
    again = replay_file(out).store  # read back: the same frames, the same facts
    assert [again.raw(i) for i in range(len(again))] == PACKETS
    assert [again.flags[i] & Flag.VENDOR_START for i in range(len(again))] == [
        int(Flag.VENDOR_START) if k in (1, 3, 5, 8) else 0 for k in range(9)
    ]

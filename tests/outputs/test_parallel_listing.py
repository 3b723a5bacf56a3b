"""Listings and exports written by parallel workers (`--jobs`, `sniffer.outputs.parallel`) are the
serial output byte for byte, in every format, with relative and absolute times, over
ranges of uneven sizes and more workers than some captures have rows to spare; a
worker that fails makes the command fail; `| head -1` ends quietly."""

from __future__ import annotations

import os
import random
import signal
import struct
import subprocess
import sys
from collections.abc import Callable, Iterable, Iterator
from contextlib import redirect_stdout
from pathlib import Path

import pytest

from dissectors.checks import ascii_frame, with_crc
from sniffer.cli import main
from sniffer.meaning.describe import Describer
from sniffer.model import LineSettings
from sniffer.outputs import parallel
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE
from sniffer.sources.linktypes import LINKTYPE_RTAC_SERIAL
from sniffer.sources.pcapng_writer import PcapngWriter, describe_interface, rtac_record
from sniffer.sources.synth import polling_frames, stress_stream
from tests.support.core import KINDS, _frame
from tests.support.sunspec import device_image, discovery
from tests.support.sunspec import read as sunspec_read

LINE = LineSettings(baud=19200, bytesize=8, parity="E", stopbits=1, mode="rtu")
FAST = LineSettings(baud=115200, bytesize=8, parity="N", stopbits=1, mode="rtu")
ASCII = LineSettings(baud=9600, bytesize=7, parity="E", stopbits=1, mode="ascii")
T0 = 1_714_564_800.0
JOBS = ("1", "2", "7")  # serial, a pair, more workers than some ranges have rows to spare

Reads = list[tuple[float, bytes]]  # (time of the read's end, its bytes)


def _write(path: Path, line: LineSettings, *ports: Reads) -> Path:
    """A pcapng of link type 250 with one interface per port."""
    with path.open("wb") as out:
        writer = PcapngWriter(out)
        ifaces = [
            writer.add_interface(
                LINKTYPE_RTAC_SERIAL, name=f"ttyUSB{k}", description=describe_interface(line)
            )
            for k in range(len(ports))
        ]
        merged = sorted((t, k, data) for k, reads in enumerate(ports) for t, data in reads)
        for t, k, data in merged:
            packet = rtac_record(T0 + t - len(data) * line.char_time, data)
            writer.write_packet(ifaces[k], T0 + t, packet)
    return path


def _r(unit: int, fc: int, a: int, b: int) -> bytes:
    return with_crc(struct.pack(">BBHH", unit, fc, a, b))


def _answer(unit: int, fc: int, words: list[int]) -> bytes:
    data = b"".join(w.to_bytes(2, "big") for w in words)
    return with_crc(bytes([unit, fc, len(data)]) + data)


def _mixed(seed: int) -> Reads:
    """Frames one per read at 19200 8E1: random traffic of every kind (noise, CRC
    errors, exceptions, echoes, broadcasts, unknown codes, silent slaves) on units
    1, 2 and 7 that the demo's bus binds in part; parameter windows of unit 2 selected
    between reads; slow answers of unit 3; exceptions its requests explain or not; a
    SunSpec device (unit 7) found and polled."""
    rng = random.Random(seed)
    char = LINE.char_time
    out: Reads = []
    t = 0.0

    def send(frames: list[bytes], delay: float = 0.0) -> None:
        nonlocal t
        for k, frame in enumerate(frames):
            t += len(frame) * char + (delay if k else 0.0)
            out.append((t, frame))
            t += LINE.t35 * rng.uniform(1.05, 1.5)

    image = device_image()
    sunspec = [sunspec_read(image, s, c) for s, c in discovery(image, 40000)]
    sunspec += [sunspec_read(image, s, c) for s, c in [(40072, 50), (40124, 53)] * 4]
    for n in range(500):
        pick = rng.random()
        if pick < 0.55:
            send(_frame(rng, rng.choice(KINDS)))
        elif pick < 0.65:
            send([_r(2, 6, 0x5001, rng.choice((1, 30, 49)))] * 2)  # a window selects
            send([_r(2, 4, 0x5003, 2), _answer(2, 4, [0, rng.choice((250, 251))])])
        elif pick < 0.75:
            slow = rng.random() < 0.4
            send([_r(3, 3, 0, 2), _answer(3, 3, [5, 6])], 0.1 if slow else 0.0)
        elif pick < 0.8:
            refused = with_crc(bytes([3, 0x86, 3]))
            send([_r(3, 6, 0x0D, rng.choice((500, 700))), refused])
        elif sunspec and pick < 0.9:
            send(list(sunspec.pop(0)))
        else:
            t += 0.3 if n % 7 else 2.0  # a pause
    return out


def _stressed(seed: int, n: int) -> Reads:
    """A polling master at 115200 delivered in 16 ms bursts with stray bytes, zeros
    after frames and flipped bits."""
    frames = polling_frames(n, seed=seed, line=FAST, units=(1, 2, 3, 5, 9, 17))
    return [(c.t_end, c.data) for c in stress_stream(frames, seed=seed).chunks]


def _ascii(n: int) -> Reads:
    """Modbus ASCII polling at 9600 7E1, one frame per read, some LRCs wrong."""
    out: Reads = []
    t = 0.0
    for k, f in enumerate(polling_frames(n, seed=4, units=(1, 4, 9))):
        frame = bytearray(ascii_frame(f.raw[:-2]))
        if k % 53 == 7:
            frame[-3] ^= 0x01  # the LRC
        t = max(t, f.t * 8) + len(frame) * ASCII.char_time
        out.append((t, bytes(frame)))
        t += 0.005
    return out


@pytest.fixture(scope="module")
def captures(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[str]]:
    """Command-line arguments naming each capture and its settings."""
    folder = tmp_path_factory.mktemp("captures")
    bus = ["--bus", str(DEMO_BUS)]
    mixed = _write(folder / "mixed.pcapng", LINE, _mixed(11))
    ports = _write(folder / "ports.pcapng", FAST, _stressed(5, 1500), _stressed(6, 700))
    ascii_file = _write(folder / "ascii.pcapng", ASCII, _ascii(800))
    return {
        "demo": [str(DEMO_CAPTURE), *bus],
        "mixed": [str(mixed), *bus],
        "ports": [str(ports), *bus],
        "ascii": [str(ascii_file), "--mode", "ascii"],
    }


@pytest.fixture(autouse=True)
def few_rows_suffice(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(parallel.MIN_ROWS_ENV, "2")
    monkeypatch.setenv("MODSCOPE_NO_INDEX", "1")


@pytest.fixture
def forks(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """Counts the workers started (in this process; the workers leave with os._exit)."""
    started: list[int] = []
    real = os.fork

    def counting() -> int:
        pid = real()
        if pid:
            started.append(pid)
        return pid

    monkeypatch.setattr(os, "fork", counting)
    yield started


def _stdout(argv: list[str], path: Path, code: int = 0) -> bytes:
    with path.open("w", encoding="utf-8") as out, redirect_stdout(out):
        assert main(argv) == code
    return path.read_bytes()


CASES = [
    (name, fmt, time)
    for name in ("demo", "mixed", "ports", "ascii")
    for fmt in ("text", "jsonl", "csv")
    # (--time abs changes text only: JSONL and CSV refuse it, their times being numbers)
    for time in (("rel", "abs") if fmt == "text" else ("rel",))
]


@pytest.mark.parametrize(("name", "fmt", "time"), CASES)
def test_a_replay_listing_is_the_same_with_any_number_of_workers(
    captures: dict[str, list[str]],
    tmp_path: Path,
    forks: list[int],
    name: str,
    fmt: str,
    time: str,
) -> None:
    outputs = {}
    for jobs in JOBS:
        argv = ["replay", *captures[name], "--format", fmt, "--time", time, "--jobs", jobs]
        outputs[jobs] = _stdout(argv, tmp_path / f"out{jobs}")
    serial = outputs["1"]
    assert serial.count(b"\n") > 700
    for jobs in JOBS[1:]:
        assert outputs[jobs] == serial, jobs
    assert len(forks) == 1 + 6  # 1 and 7 - 1 workers for 2 and 7 jobs


def test_a_filtered_and_counted_listing_is_the_same(
    captures: dict[str, list[str]], tmp_path: Path, forks: list[int]
) -> None:
    for argv in (["--filter", "unit:3"], ["-c", "5"], ["--filter", "kind:exception", "-c", "9"]):
        base = ["replay", *captures["mixed"], "--format", "jsonl", *argv]
        serial = _stdout([*base, "--jobs", "1"], tmp_path / "a")
        assert serial
        for jobs in JOBS[1:]:
            assert _stdout([*base, "--jobs", jobs], tmp_path / "b") == serial
    assert forks


_OUTS: list[tuple[str, list[str]]] = [
    ("x.pcapng", []),
    ("x.pcapng", ["--as", "rtu"]),
    ("x.jsonl", []),
    ("x.csv", []),
    ("x.txt", ["--time", "abs"]),
    ("x.txt", []),
    ("x.csv", ["--what", "transactions"]),
    ("x.jsonl", ["--what", "transactions"]),
    ("x.csv", ["--what", "registers"]),
    ("x.jsonl", ["--what", "registers"]),
]
_NAMES = ("demo", "mixed", "ports", "ascii")
# each export on two captures, each capture in five exports (every pair took 100 s of the
# suite, for no more seams: the captures differ in their rows, not in how an export is cut)
EXPORTS = [
    (_NAMES[(k + shift) % len(_NAMES)], out, extra)
    for k, (out, extra) in enumerate(_OUTS)
    for shift in (0, 1)
]


@pytest.mark.parametrize(("name", "out", "extra"), EXPORTS)
def test_an_export_is_the_same_with_any_number_of_workers(
    captures: dict[str, list[str]],
    tmp_path: Path,
    forks: list[int],
    capsys: pytest.CaptureFixture[str],
    name: str,
    out: str,
    extra: list[str],
) -> None:
    written = {}
    for jobs in JOBS:
        target = tmp_path / f"{jobs}-{out}"
        assert main(["export", *captures[name], "-o", str(target), *extra, "--jobs", jobs]) == 0
        written[jobs] = target.read_bytes()
    said = capsys.readouterr().err.splitlines()
    assert len({line.split(": ", 1)[1] for line in said if "-x." in line}) == 1  # the counts
    for jobs in JOBS[1:]:
        assert written[jobs] == written["1"], jobs
    assert len(forks) == 1 + 6


def test_auto_stays_serial_on_a_small_listing(
    captures: dict[str, list[str]],
    tmp_path: Path,
    forks: list[int],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv(parallel.MIN_ROWS_ENV)
    argv = ["replay", *captures["demo"], "--format", "jsonl"]
    assert _stdout(argv, tmp_path / "auto") == _stdout([*argv, "--jobs", "1"], tmp_path / "one")
    assert _stdout([*argv, "--jobs", "4"], tmp_path / "four")  # below MIN_ROWS: serial too
    assert forks == []


def test_auto_uses_the_cpus_but_not_for_a_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    class Out:
        def __init__(self, tty: bool) -> None:
            self.tty = tty

        def isatty(self) -> bool:
            return self.tty

    monkeypatch.setattr(parallel, "cpus", lambda: 16)
    file, terminal = Out(False), Out(True)
    assert parallel.workers_for(None, 100, file) == parallel.MAX_AUTO  # type: ignore[arg-type]
    assert parallel.workers_for(None, 100, terminal) == 1  # type: ignore[arg-type]
    assert parallel.workers_for(3, 100, terminal) == 3  # type: ignore[arg-type]
    assert parallel.workers_for(7, 4, file) == 4  # type: ignore[arg-type]
    monkeypatch.setattr(parallel, "can_fork", lambda: False)
    assert parallel.workers_for(7, 100, file) == 1  # type: ignore[arg-type]


def test_ranges_are_contiguous_and_as_even_as_can_be() -> None:
    rows = list(range(10, 33))
    parts = parallel.split(rows, 7)
    assert [len(p) for p in parts] == [4, 4, 3, 3, 3, 3, 3]
    assert [r for p in parts for r in p] == rows
    assert [len(p) for p in parallel.split(rows[:3], 5)] == [1, 1, 1, 0, 0]


def _break_in_workers(monkeypatch: pytest.MonkeyPatch, act: Callable[[], None]) -> None:
    """`act` when a worker describes its range's last row (the parent never does)."""
    real = Describer.contents
    parent = os.getpid()

    def contents(
        self: Describer, rows: Iterable[int], values: bool = True, writes: bool = False
    ) -> Iterator[tuple[int, object]]:
        for i, found in real(self, rows, values, writes):
            if os.getpid() != parent and i == len(self.store) - 1:
                act()
            yield i, found

    monkeypatch.setattr(Describer, "contents", contents)


def _fail() -> None:
    raise ValueError("a worker broke")


@pytest.mark.parametrize("fmt", ["jsonl", "text"])
def test_a_failing_worker_fails_the_command(
    captures: dict[str, list[str]],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    fmt: str,
) -> None:
    _break_in_workers(monkeypatch, _fail)
    argv = ["replay", *captures["demo"], "--format", fmt, "--jobs", "3"]
    _stdout(argv, tmp_path / "out", code=70)
    err = capsys.readouterr().err
    assert "range 3 of 3" in err and "failed (exit status 70)" in err
    assert "ValueError: a worker broke" in err and "the output is incomplete" in err
    with pytest.raises(ChildProcessError):
        os.waitpid(-1, os.WNOHANG)  # every worker reaped


def test_a_worker_killed_fails_the_export(
    captures: dict[str, list[str]],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    _break_in_workers(monkeypatch, lambda: os.kill(os.getpid(), signal.SIGKILL))
    target = tmp_path / "x.pcapng"
    assert main(["export", *captures["demo"], "-o", str(target), "--jobs", "2"]) == 70
    err = capsys.readouterr().err
    assert "range 2 of 2" in err and "was killed by signal 9" in err
    assert "packets (link type 252" not in err


def test_head_ends_the_workers_quietly(captures: dict[str, list[str]], tmp_path: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).parent.parent.parent))
    argv = [sys.executable, "-m", "sniffer.cli", "replay", *captures["ports"], "--jobs", "3"]
    for fmt in ("jsonl", "text"):
        shell = " ".join(map(str, argv)) + f" --format {fmt} | head -1"
        done = subprocess.run(
            ["bash", "-o", "pipefail", "-c", shell],
            env=env,
            capture_output=True,
            timeout=120,
            check=False,
        )
        assert done.returncode == 0, done.stderr
        assert done.stdout.count(b"\n") == 1
        # nothing but what the capture's times are worth (said once, before the rows)
        said = [x for x in done.stderr.splitlines() if not x.startswith(b"modscope: note: timing:")]
        assert said == []

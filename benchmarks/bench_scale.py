"""Provides the scale benchmark: whole-process times of modscope and tshark on one recording.

Run: python benchmarks/bench_scale.py [--frames N] [--runs R] [--dir DIR]
     python benchmarks/bench_scale.py --mixes N [--mix-frames F] [--seed S]
     python benchmarks/bench_scale.py --mixes N --mix-listings F --only-export
     python benchmarks/bench_scale.py --mixes N --mix-listings F --only-listings [--jobs J]

With --mixes N it measures N buses instead of the project's one stream
(`benchmarks/mixes.py`: the project's stream, the bus of issue #29, then random buses the
benchmark was not tuned on), each as `modscope record` writes it and one frame per
packet, with tshark on the same frames, and prints each mix, then the worst and the
median mix of every figure (the worst is the one to judge by). With --only-export it
times, of each mix, only `export -o x.pcapng` and tshark's plain summary on the
--mix-listings frames (no index figures, no listings); with --only-listings, the
listings and the export of each mix against tshark's, without the index figures.

It writes (once; kept in DIR and reused while their frame count matches):
- `reads-N.pcapng`: N frames of a polling bus at 115200 8N1 as `modscope record` writes
  them (link type 250, one block per 16 ms read of a USB adapter), through the recorder;
- `frames-N.pcapng`: the same frames one per packet (link type 250, header time at the
  frame's first byte, packet time at its last), the shape tshark reads in linear time
  (its RTU reassembly over multi-frame reads is super-linear, which would flatter us);
- the same two shapes with 10 frames, to take start-up off both sides;
- `reads-L.pcapng` and `frames-L.pcapng` with L = --listing-frames (default 100k) for
  the full listings and the export, which run at thousands of rows a second.

Then it times each command as a whole process (median of --runs; the machine is shared
and noisy, so judge the ratios; a mix's listings, export and tshark's figures are timed
in rounds, each round running every command once, so that they share the machine's
drift, see `measure_interleaved`), with its peak resident memory, and prints per-frame
rates with start-up taken off: (frames - 10) / (time on N - time on 10); and the same in
CPU time (user + system of each process, from wait4), which the load of a shared machine
moves far less than the wall time (a process waiting for a CPU is not working).
tshark runs as `tshark -n -r F -d rtacser.data,mbrtu` (plain summary, `-T fields`,
`-T ek`) on the one-frame-per-packet file.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from benchmarks.common import LINE, Unflushed, usb_reads
from benchmarks.mixes import Mix, issue_mix, mixes, project_mix, random_mix, write_mix
from sniffer.live.port import PortSpec
from sniffer.live.recorder import Recorder
from sniffer.model import Chunk
from sniffer.sources.linktypes import LINKTYPE_RTAC_SERIAL, RTAC_DATA_RX_START
from sniffer.sources.pcapng_writer import (
    EPB_FLAG_INBOUND,
    PcapngWriter,
    describe_interface,
    rtac_record,
)
from sniffer.sources.synth import SynthFrame, polling_frames

START = 1768464000.0  # 2026-01-15 08:00:00 UTC, as the demo
SMALL = 10
TSHARK = ["tshark", "-n", "-d", "rtacser.data,mbrtu"]


def _frames(n: int) -> list[SynthFrame]:
    return polling_frames(n, line=LINE)


def write_reads(path: Path, frames: list[SynthFrame]) -> int:
    """The frames as `modscope record` writes a USB adapter's 16 ms reads; returns reads."""
    stream = Unflushed(path)
    recorder = Recorder(path, [PortSpec("/dev/ttyUSB0", LINE)], stream=stream)  # type: ignore[arg-type]
    reads = usb_reads(frames)
    for chunk in reads:
        recorder.write(Chunk(chunk.data, START + chunk.t_end))
    recorder.close(START + (reads[-1].t_end if reads else 0.0) + 0.1)
    stream.close()
    return len(reads)


def write_frames(path: Path, frames: list[SynthFrame]) -> None:
    """The same frames one per packet: RTAC header at the first byte, packet at the last."""
    stream = Unflushed(path)
    writer = PcapngWriter(stream)  # type: ignore[arg-type]
    iface = writer.add_interface(
        LINKTYPE_RTAC_SERIAL, name="/dev/ttyUSB0", description=describe_interface(LINE)
    )
    char = LINE.char_time
    for f in frames:
        t0 = START + f.t
        packet = rtac_record(t0, f.raw, event=RTAC_DATA_RX_START)
        writer.write_packet(iface, t0 + len(f.raw) * char, packet, flags=EPB_FLAG_INBOUND)
    stream.close()


def make_files(folder: Path, n: int) -> tuple[Path, Path]:
    """`reads-n.pcapng` and `frames-n.pcapng` in `folder`, written unless already there.

    They are written by a child process: Linux carries a process's peak RSS over fork
    and exec (`ru_maxrss`), so a benchmark that had built a million frames itself would
    report that peak for every command it timed afterwards."""
    folder.mkdir(parents=True, exist_ok=True)
    reads, one = folder / f"reads-{n}.pcapng", folder / f"frames-{n}.pcapng"
    if not (reads.exists() and one.exists()):
        subprocess.run(
            [sys.executable, __file__, "--write-files", str(n), "--dir", str(folder)],
            check=True,
        )
    return reads, one


def write_files(folder: Path, n: int) -> None:
    """Write the two files of `make_files` here (in the child process)."""
    folder.mkdir(parents=True, exist_ok=True)
    reads, one = folder / f"reads-{n}.pcapng", folder / f"frames-{n}.pcapng"
    t = time.perf_counter()
    frames = _frames(n)
    count = write_reads(reads, frames)
    write_frames(one, frames)
    size = sum(len(f.raw) for f in frames)
    print(
        f"wrote {n:,} frames ({size / 1e6:.1f} MB of bus bytes, {count:,} reads) to "
        f"{reads.name} and {one.name} in {time.perf_counter() - t:.1f} s",
        flush=True,
    )


@dataclass
class Run:
    seconds: float
    rss_mb: float
    cpu: float = 0.0  # median CPU seconds (user + system) of the process


COLD = {**os.environ, "MODSCOPE_NO_INDEX": "1"}  # no sidecar index read or written
WARM = {k: v for k, v in os.environ.items() if k != "MODSCOPE_NO_INDEX"}


Once = tuple[float, float, float]  # a run's wall time, CPU time and peak memory (MB)


def _once(argv: list[str], env: dict[str, str] | None) -> Once:
    """One run of `argv`: its wall time, CPU time (user + system, from wait4) and peak
    resident memory in MB."""
    t = time.perf_counter()
    with subprocess.Popen(
        argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env or COLD
    ) as proc:
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        assert proc.stderr is not None
        err = proc.stderr.read()
    wall = time.perf_counter() - t
    if proc.returncode not in (0, 1):
        raise SystemExit(f"{' '.join(argv)} failed ({proc.returncode}): {err[-2000:]!r}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def run(argv: list[str], runs: int, env: dict[str, str] | None = None) -> Run:
    """Median wall time, median CPU time and the largest peak RSS of `runs` runs of
    `argv`. The CPU time is the process's own (user + system, from wait4): on a machine
    shared with other work it moves far less than the wall time, which waits for a CPU."""
    done = [_once(argv, env) for _ in range(runs)]
    return _summed(done)


def _summed(done: list[tuple[float, float, float]]) -> Run:
    return Run(
        statistics.median(w for w, _, _ in done),
        max(m for _, _, m in done),
        statistics.median(c for _, c, _ in done),
    )


def modscope(*args: str) -> list[str]:
    return [sys.executable, "-m", "sniffer.cli", *args]


def machine() -> str:
    model = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (
        f"{os.cpu_count()} CPUs ({model}), Python {platform.python_version()}, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
    )


@dataclass
class Figure:
    label: str
    n: int
    big: Run
    small: Run

    @property
    def whole(self) -> float:
        return self.n / self.big.seconds

    @property
    def per_frame(self) -> float:
        """Frames a second with start-up taken off (time on n minus time on 10); NaN
        when the run on 10 frames took as long (a loaded machine): no figure then."""
        spent = self.big.seconds - self.small.seconds
        return (self.n - SMALL) / spent if spent > 0 else float("nan")

    @property
    def per_frame_cpu(self) -> float:
        """The same in CPU time (user + system): what the machine's load moves least."""
        return (self.n - SMALL) / max(self.big.cpu - self.small.cpu, 1e-6)


def measure(
    label: str,
    n: int,
    big: list[str],
    small: list[str],
    runs: int,
    env: dict[str, str] | None = None,
) -> Figure:
    fig = Figure(label, n, run(big, runs, env), run(small, runs, env))
    _shown(fig)
    return fig


def measure_interleaved(
    specs: list[tuple[str, list[str], list[str]]], n: int, runs: int, fresh: Path | None = None
) -> list[Figure]:
    """Several commands, each given as (label, argv on n frames, argv on SMALL frames),
    timed in `runs` rounds: a round runs every command once on each file, in turn, so
    that all meet the same load over the minutes the rounds take and their medians
    compare. Taken command after command, the medians of a shared machine whose speed
    drifted put modscope's runs and tshark's in different minutes: the same code's
    export of 200k frames measured 1.6x tshark in one run and 3.8x in the next
    (2026-12-07). `fresh`: a file removed before every run (an export's output), so
    that each run writes a new file, as an export usually does: the kernel writes a
    file's pages to disk later, in the background, but a file opened again and cut to
    nothing first waits for that (ext4 also starts writing a file cut and written again
    when it is closed), and interleaved runs would leave that writing to whichever
    command ran next."""
    done: list[tuple[list[Once], list[Once]]] = [([], []) for _ in specs]
    for _ in range(runs):
        for (_, big, small), (bigs, smalls) in zip(specs, done, strict=True):
            for argv, times in ((big, bigs), (small, smalls)):
                if fresh is not None:
                    fresh.unlink(missing_ok=True)
                times.append(_once(argv, None))
    figs = [
        Figure(label, n, _summed(bigs), _summed(smalls))
        for (label, _, _), (bigs, smalls) in zip(specs, done, strict=True)
    ]
    for fig in figs:
        _shown(fig)
    return figs


def _shown(fig: Figure) -> None:
    label = fig.label
    print(
        f"  {label:<44} {fig.big.seconds:8.2f} s {fig.whole:>11,.0f}/s whole "
        f"{fig.per_frame:>11,.0f}/s per frame  start {fig.small.seconds:.2f} s  "
        f"peak {fig.big.rss_mb:6.0f} MB  CPU {fig.per_frame_cpu:>11,.0f}/s per frame",
        flush=True,
    )


@dataclass
class Shape:
    """How fast one file reads per frame against another of the same frames, from
    alternated runs (a, b, a, b...): the median of each pair's ratio, start-up taken off
    both, in wall and in CPU time. A pair's two runs meet the same load, so their ratio
    moves far less than the ratio of two medians taken minutes apart."""

    wall: float
    cpu: float
    pairs: int


def measure_alternated(
    labels: tuple[str, str],
    n: int,
    bigs: tuple[list[str], list[str]],
    smalls: tuple[list[str], list[str]],
    pairs: int,
) -> tuple[Figure, Figure, Shape]:
    """Two commands on n frames, run in `pairs` alternated pairs (their start-up, the
    same commands on `SMALL` frames, the median of `pairs` runs each, run in the same
    rounds as the pairs): both figures, and how much faster per frame the first reads
    than the second (`Shape`). On 1M frames of a fast mix the work itself takes about
    as long as the start-up, so the start-ups must meet the same minutes as the pairs:
    measured in two blocks before them, they put issue29's shapes at 0.75 where 15
    alternated whole processes said 1.17 (2026-12-07)."""
    small: tuple[list[Once], ...] = ([], [])
    done: tuple[list[Once], ...] = ([], [])
    for _ in range(pairs):
        for k in (0, 1):
            done[k].append(_once(bigs[k], None))
        for k in (0, 1):
            small[k].append(_once(smalls[k], None))
    figs = [Figure(labels[k], n, _summed(done[k]), _summed(small[k])) for k in (0, 1)]
    for fig in figs:
        _shown(fig)
    start = [f.small for f in figs]
    wall = [
        (b[0] - start[1].seconds) / (a[0] - start[0].seconds)
        for a, b in zip(done[0], done[1], strict=True)
        if a[0] > start[0].seconds
    ]
    cpu = [
        (b[1] - start[1].cpu) / max(a[1] - start[0].cpu, 1e-6)
        for a, b in zip(done[0], done[1], strict=True)
    ]
    shape = Shape(statistics.median(wall) if wall else float("nan"), statistics.median(cpu), pairs)
    print(
        f"  => {labels[0]} / {labels[1]}, per frame, median of {pairs} alternated pairs: "
        f"{shape.wall:.2f} ({shape.cpu:.2f} in CPU time)",
        flush=True,
    )
    return figs[0], figs[1], shape


def compare(ours: Figure, theirs: Figure) -> None:
    print(
        f"  => {ours.label} / {theirs.label}: {ours.per_frame / theirs.per_frame:.1f}x per frame, "
        f"{ours.whole / theirs.whole:.1f}x whole process; memory {ours.big.rss_mb:.0f} MB vs "
        f"{theirs.big.rss_mb:.0f} MB",
        flush=True,
    )


INDEX_WINDOWED = """
import sys
from sniffer.cli.replay import REPLAY_WINDOW
from sniffer.session.session import open_session
session, capture = open_session(sys.argv[1], index=False)
session.stats.bound()
session.ingest(capture.chunks(), window=REPLAY_WINDOW)
"""

# the same for callgrind: `ingest` refreshes the statistics every 0.25 s of wall time,
# and under callgrind (tens of times slower, slower still on a loaded machine) those
# refreshes grow with the load: 100k frames of the project's stream, same code, counted
# 3,240 instructions a frame with them at load 30 and 2,333 without (2026-12-05).
# Without them the count does not depend on the load (each window's refresh stays).
#   valgrind --tool=callgrind python -c "$INDEX_COUNTED" FILE
INDEX_COUNTED = INDEX_WINDOWED.replace(
    "window=REPLAY_WINDOW)", 'window=REPLAY_WINDOW, every=float("inf"))'
)


@dataclass
class MixResult:
    mix: Mix
    frames: int
    reads: Figure | None  # None: not timed (--only-export, --only-listings)
    one: Figure | None
    tshark: Figure | None
    listings: dict[str, tuple[Figure, Figure | None]]
    shape: Shape | None = None  # reads as recorded against one frame per packet


def _ratio(ours: Figure | None, theirs: Figure | None) -> float:
    if ours is None or theirs is None:
        return float("nan")
    return ours.per_frame / theirs.per_frame


def _x(ratio: float) -> str:
    """A ratio as the tables print it: five wide, or a dash where there is none
    (`--no-tshark`)."""
    return "    -" if ratio != ratio else f"{ratio:5.1f}x"


def _cpu_ratio(ours: Figure, theirs: Figure | None) -> float:
    return ours.per_frame_cpu / theirs.per_frame_cpu if theirs is not None else float("nan")


def make_mix_files(folder: Path, mix: Mix, n: int) -> tuple[Path, Path]:
    """The mix's two files of n frames, written by a child process (see make_files)."""
    reads = folder / f"{mix.name}-reads-{n}.pcapng"
    one = folder / f"{mix.name}-frames-{n}.pcapng"
    if not (reads.exists() and one.exists()):
        subprocess.run(
            [
                sys.executable,
                __file__,
                "--write-mix",
                str(n),
                "--mix-name",
                mix.name,
                "--seed",
                str(mix.seed),
                "--dir",
                str(folder),
            ],
            check=True,
        )
        # written out before anything is timed: 5M frames of a mix are about 800 MB, and
        # runs that met the kernel writing them (the mixes written just before their
        # runs, 2026-12-07 16:33) took up to 1.7x as long as the same runs after
        os.sync()
    return reads, one


def mix_of(name: str, seed: int) -> Mix:
    """The mix a child process is asked to write, by its name."""
    if name == "project":
        return project_mix()
    if name == "issue29":
        return issue_mix()
    return random_mix(seed)


def measure_mix(
    mix: Mix,
    n: int,
    folder: Path,
    runs: int,
    tshark: int,
    listings: int,
    only_export: bool = False,
    only_listings: bool = False,
    jobs: str = "auto",
    pairs: int = 7,
) -> MixResult:
    """The mix's figures: modscope on n frames, tshark on its first `tshark` frames (0:
    none). tshark's rate per frame falls as a file grows (its Modbus request tracking),
    so a ratio to tshark on fewer frames than modscope read is, if anything, low.
    `only_export`: the export of the `listings` frames and tshark's plain summary of
    them, nothing else. `only_listings`: the listings and the export alone (no index
    figures), with `--jobs jobs`. The two shapes' index figures come from `pairs`
    alternated runs (`measure_alternated`)."""
    print(f"{mix.name}: {mix.describe()}", flush=True)
    reads10, one10 = make_mix_files(folder, mix, SMALL)
    ix = ix1 = ts = None
    shape = None
    if not (only_listings or only_export):
        ix, ix1, ts, shape = _index_figures(mix, n, folder, runs, tshark, reads10, one10, pairs)
    rows: dict[str, tuple[Figure, Figure | None]] = {}
    if listings:
        kinds = ("export",) if only_export else ("jsonl", "text", "export")
        rows = _listing_figures(mix, listings, folder, runs, tshark, reads10, one10, jobs, kinds)
    return MixResult(mix, n, ix, ix1, ts, rows, shape)


def _index_figures(
    mix: Mix,
    n: int,
    folder: Path,
    runs: int,
    tshark: int,
    reads10: Path,
    one10: Path,
    pairs: int,
) -> tuple[Figure, Figure, Figure | None, Shape]:
    """`replay --stats` of the mix's two shapes in `pairs` alternated pairs, and tshark's
    plain summary (median of `runs`)."""
    reads, one = make_mix_files(folder, mix, n)
    ix, ix1, shape = measure_alternated(
        ("replay --stats (reads as recorded)", "replay --stats (frame per packet)"),
        n,
        (modscope("replay", str(reads), "--stats"), modscope("replay", str(one), "--stats")),
        (modscope("replay", str(reads10), "--stats"), modscope("replay", str(one10), "--stats")),
        pairs,
    )
    ts = None
    if tshark:
        _, tone = make_mix_files(folder, mix, tshark) if tshark != n else (reads, one)
        ts = measure(
            f"tshark plain summary (frame per packet, {tshark:,})",
            tshark,
            [*TSHARK, "-r", str(tone)],
            [*TSHARK, "-r", str(one10)],
            runs,
        )
        print(
            f"  => {_ratio(ix, ts):.1f}x tshark (reads as recorded), "
            f"{_ratio(ix1, ts):.1f}x (frame per packet); in CPU time "
            f"{_cpu_ratio(ix, ts):.1f}x, {_cpu_ratio(ix1, ts):.1f}x",
            flush=True,
        )
    return ix, ix1, ts, shape


def _listing_figures(
    mix: Mix,
    listings: int,
    folder: Path,
    runs: int,
    tshark: int,
    reads10: Path,
    one10: Path,
    jobs: str,
    kinds: tuple[str, ...] = ("jsonl", "text", "export"),
) -> dict[str, tuple[Figure, Figure | None]]:
    """The JSONL and text listings and the export (those of `kinds`) of `listings` frames
    of the mix (as recorded), each with tshark's figure on the same frames one per packet."""
    rows: dict[str, tuple[Figure, Figure | None]] = {}
    lreads, lone = make_mix_files(folder, mix, listings)
    out = folder / "out.pcapng"
    specs: list[tuple[str, list[str], list[str]]] = []
    if tshark:
        specs.append(
            (
                "tshark plain summary (listing frames)",
                [*TSHARK, "-r", str(lone)],
                [*TSHARK, "-r", str(one10)],
            )
        )
        if "jsonl" in kinds:
            specs.append(
                (
                    "tshark -T ek",
                    [*TSHARK, "-T", "ek", "-r", str(lone)],
                    [*TSHARK, "-T", "ek", "-r", str(one10)],
                )
            )
    ours = [
        (label, argv)
        for label, argv in (
            ("jsonl", ("replay", "--format", "jsonl")),
            ("text", ("replay", "--format", "text")),
            ("export", ("export", "-o", str(out))),
        )
        if label in kinds
    ]
    for _, (verb, *rest) in ours:
        rest = [*rest, "--jobs", jobs]
        specs.append(
            (
                f"{verb} {' '.join(rest)}",
                modscope(verb, str(lreads), *rest),
                modscope(verb, str(reads10), *rest),
            )
        )
    figs = measure_interleaved(specs, listings, runs, fresh=out)
    plain = figs.pop(0) if tshark else None
    ek = figs.pop(0) if tshark and "jsonl" in kinds else None
    for (label, _), fig in zip(ours, figs, strict=True):
        peer = ek if label == "jsonl" else plain
        rows[label] = (fig, peer)
        if peer is not None:
            print(f"  => {label}: {_ratio(fig, peer):.1f}x tshark", flush=True)
    out.unlink(missing_ok=True)
    return rows


def summarize(results: list[MixResult]) -> None:
    """Each mix's ratios, then the worst and the median mix of each figure."""
    figures: list[tuple[str, list[tuple[float, float, str]]]] = []

    def add(label: str, pick: list[tuple[Figure, Figure | None, str]]) -> None:
        figures.append(
            (label, [(_ratio(ours, theirs), ours.per_frame, name) for ours, theirs, name in pick])
        )

    indexed = [(r, r.reads, r.one) for r in results if r.reads is not None and r.one is not None]
    if indexed:
        add("replay --stats, reads as recorded", [(x, r.tshark, r.mix.name) for r, x, _ in indexed])
        add("replay --stats, frame per packet", [(y, r.tshark, r.mix.name) for r, _, y in indexed])
    for key, label in (
        ("jsonl", "replay --format jsonl (vs -T ek)"),
        ("text", "replay --format text"),
        ("export", "export -o x.pcapng"),
    ):
        pick = [(*r.listings[key], r.mix.name) for r in results if key in r.listings]
        if pick:
            add(label, pick)
    print("\nper frame, start-up taken off; ratio = modscope / tshark on the same mix")
    if indexed:
        print(f"  {'mix':<14} {'reads/s':>11} {'x':>6} {'frames/s':>11} {'x':>6}  mix")
    for r, x, y in indexed:
        print(
            f"  {r.mix.name:<14} {x.per_frame:>11,.0f} {_x(_ratio(x, r.tshark))} "
            f"{y.per_frame:>11,.0f} {_x(_ratio(y, r.tshark))}  {r.mix.describe()}"
        )
    for key in ("jsonl", "text", "export"):
        for r in results:
            if key in r.listings:
                ours, theirs = r.listings[key]
                peer = "" if theirs is None else f" tshark {theirs.per_frame:>9,.0f}/s"
                print(
                    f"  {key:<6} {r.mix.name:<14} {ours.per_frame:>9,.0f}/s{peer} "
                    f"{_x(_ratio(ours, theirs))}"
                )
    print(f"\n  {'figure':<36} {'worst':>24} {'median':>24}")
    for label, values in figures:
        ordered = sorted(v for v in values if v[0] == v[0])  # (no NaN: no figure)
        if not ordered:
            continue
        worst = ordered[0]
        median = ordered[(len(ordered) - 1) // 2]
        print(
            f"  {label:<36} {_x(worst[0])} {worst[1]:>10,.0f}/s {worst[2]:<7} "
            f"{_x(median[0])} {median[1]:>10,.0f}/s {median[2]}"
        )
    if not indexed:
        return
    shapes = [(r.shape, r.mix.name) for r in results if r.shape is not None]
    wall = sorted((s.wall, name) for s, name in shapes if s.wall == s.wall)
    if shapes and not wall:  # (files so small that no run on them outlasted its start-up)
        print("  reads as recorded / frame per packet: no figure (the files are too small)")
    if wall:
        by_cpu = sorted((s.cpu, name) for s, name in shapes)
        print(
            f"  reads as recorded / frame per packet, per frame, the median of "
            f"{shapes[0][0].pairs} alternated pairs of each mix: worst {wall[0][0]:.2f} "
            f"({wall[0][1]}), median {wall[(len(wall) - 1) // 2][0]:.2f}; in CPU time worst "
            f"{by_cpu[0][0]:.2f} ({by_cpu[0][1]}), median "
            f"{by_cpu[(len(by_cpu) - 1) // 2][0]:.2f}"
        )
    print("\nthe same in CPU time (user + system of each process; the load moves it least)")
    for r, x, y in indexed:
        print(
            f"  {r.mix.name:<14} {x.per_frame_cpu:>11,.0f} "
            f"{_x(_cpu_ratio(x, r.tshark))} {y.per_frame_cpu:>11,.0f} "
            f"{_x(_cpu_ratio(y, r.tshark))}"
        )
    for label, pairs in (
        ("replay --stats, reads as recorded", [(x, r.tshark) for r, x, _ in indexed]),
        ("replay --stats, frame per packet", [(y, r.tshark) for r, _, y in indexed]),
    ):
        cpu = sorted(_cpu_ratio(ours, theirs) for ours, theirs in pairs)
        print(f"  {label:<36} worst {_x(cpu[0])} median {_x(cpu[(len(cpu) - 1) // 2])}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0] if __doc__ else "")
    parser.add_argument("--frames", type=int, default=1_000_000, help="frames for the index")
    parser.add_argument(
        "--listing-frames", type=int, default=100_000, help="frames for listings and export"
    )
    parser.add_argument("--runs", type=int, default=3, help="runs per figure (median)")
    parser.add_argument(
        "--pairs",
        type=int,
        default=7,
        help="with --mixes: alternated pairs of runs of the two shapes' index (median)",
    )
    parser.add_argument("--dir", type=Path, default=Path("/tmp/modscope-bench"))
    parser.add_argument("--no-tshark", action="store_true", help="time modscope only")
    parser.add_argument("--only-index", action="store_true", help="skip listings and export")
    parser.add_argument(
        "--only-export",
        action="store_true",
        help="with --mixes and --mix-listings: time only the export (and tshark's plain summary)",
    )
    parser.add_argument(
        "--mixes", type=int, metavar="N", help="measure N bus mixes (benchmarks/mixes.py)"
    )
    parser.add_argument("--mix-frames", type=int, default=2_000_000, help="frames per mix")
    parser.add_argument(
        "--mix-listings",
        type=int,
        default=0,
        metavar="F",
        help="also the listings and export of each mix, on F frames",
    )
    parser.add_argument(
        "--tshark-frames",
        type=int,
        default=200_000,
        help="frames of each mix tshark reads (its rate per frame falls as files grow)",
    )
    parser.add_argument(
        "--only-listings",
        action="store_true",
        help="with --mixes and --mix-listings: the listings and the export alone",
    )
    parser.add_argument(
        "--jobs", default="auto", help="--jobs of the mixes' listings and export (auto)"
    )
    parser.add_argument("--seed", type=int, default=29, help="seed of the random mixes")
    parser.add_argument("--write-files", type=int, metavar="N", help=argparse.SUPPRESS)
    parser.add_argument("--write-mix", type=int, metavar="N", help=argparse.SUPPRESS)
    parser.add_argument("--mix-name", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.write_files is not None:
        write_files(args.dir, args.write_files)
        return
    if args.write_mix is not None:
        write_mix(args.dir, mix_of(args.mix_name, args.seed), args.write_mix)
        return
    if args.only_export and not (args.mixes is not None and args.mix_listings):
        parser.error("--only-export needs --mixes N and --mix-listings F")
    if args.mixes is not None:
        print(f"machine: {machine()}; load average {os.getloadavg()[0]:.2f}")
        if args.only_export:
            print(
                f"{args.mixes} mixes, the export of {args.mix_listings:,} frames and tshark's "
                f"plain summary of the same frames, median of {args.runs}"
            )
        elif args.only_listings:
            print(
                f"{args.mixes} mixes, listings of {args.mix_listings:,} frames, "
                f"median of {args.runs}"
            )
        else:
            print(
                f"{args.mixes} mixes of {args.mix_frames:,} frames (tshark: the first "
                f"{args.tshark_frames:,}), median of {args.runs}"
            )
        results = [
            measure_mix(
                mix,
                args.mix_frames,
                args.dir,
                args.runs,
                0 if args.no_tshark else args.tshark_frames,
                args.mix_listings,
                args.only_export,
                args.only_listings,
                args.jobs,
                args.pairs,
            )
            for mix in mixes(args.mixes, args.seed)
        ]
        summarize(results)
        print(f"load average at the end {os.getloadavg()[0]:.2f}")
        return
    print(f"machine: {machine()}")
    n, ln, runs = args.frames, args.listing_frames, args.runs
    reads, one = make_files(args.dir, n)
    reads10, one10 = make_files(args.dir, SMALL)
    tshark = not args.no_tshark
    out = args.dir / "out.pcapng"

    print(f"index: {n:,} frames, median of {runs}")
    ix = measure(
        "modscope replay --stats (16 ms reads)",
        n,
        modscope("replay", str(reads), "--stats"),
        modscope("replay", str(reads10), "--stats"),
        runs,
    )
    ix1 = measure(
        "modscope replay --stats (frame per packet)",
        n,
        modscope("replay", str(one), "--stats"),
        modscope("replay", str(one10), "--stats"),
        runs,
    )
    # the index as `replay --stats` builds it: a window of rows, the rest dropped once
    # counted (sniffer.cli.replay.REPLAY_WINDOW); and every row kept (the TUI, listings)
    only = measure(
        "modscope index only (16 ms reads)",
        n,
        [sys.executable, "-c", INDEX_WINDOWED, str(reads)],
        [sys.executable, "-c", INDEX_WINDOWED, str(reads10)],
        runs,
    )
    index_whole = (
        "import sys; from sniffer.session.session import replay_file; replay_file(sys.argv[1])"
    )
    measure(
        "modscope index only, every row kept",
        n,
        [sys.executable, "-c", index_whole, str(reads)],
        [sys.executable, "-c", index_whole, str(reads10)],
        runs,
    )
    # reopening: the first run writes the sidecar index, the others read it
    for path in (reads, reads10):
        run(modscope("replay", str(path), "-c", "1"), 1, WARM)
    measure(
        "modscope replay --stats, sidecar index",
        n,
        modscope("replay", str(reads), "--stats"),
        modscope("replay", str(reads10), "--stats"),
        runs,
        WARM,
    )
    first = run(modscope("replay", str(reads), "-c", "40", "--format", "text"), runs, WARM)
    print(f"  {'first 40 rows, sidecar index (whole process)':<44} {first.seconds:8.2f} s")
    if tshark:
        ts = measure(
            "tshark plain summary (frame per packet)",
            n,
            [*TSHARK, "-r", str(one)],
            [*TSHARK, "-r", str(one10)],
            runs,
        )
        compare(ix, ts)
        compare(ix1, ts)
        compare(only, ts)
    if args.only_index:
        return

    lreads, lone = make_files(args.dir, ln)
    print(f"listings and export: {ln:,} frames, median of {runs}")
    # listings and the export use --jobs auto: one worker a CPU (here 2) from 20k rows
    jsonl = measure(
        "modscope replay --format jsonl",
        ln,
        modscope("replay", str(lreads), "--format", "jsonl"),
        modscope("replay", str(reads10), "--format", "jsonl"),
        runs,
    )
    measure(
        "modscope replay --format jsonl --jobs 1",
        ln,
        modscope("replay", str(lreads), "--format", "jsonl", "--jobs", "1"),
        modscope("replay", str(reads10), "--format", "jsonl", "--jobs", "1"),
        runs,
    )
    text = measure(
        "modscope replay --format text",
        ln,
        modscope("replay", str(lreads), "--format", "text"),
        modscope("replay", str(reads10), "--format", "text"),
        runs,
    )
    export = measure(
        "modscope export -o x.pcapng",
        ln,
        modscope("export", str(lreads), "-o", str(out)),
        modscope("export", str(reads10), "-o", str(out)),
        runs,
    )
    if tshark:
        plain = measure(
            "tshark plain summary (frame per packet)",
            ln,
            [*TSHARK, "-r", str(lone)],
            [*TSHARK, "-r", str(one10)],
            runs,
        )
        fields = [*TSHARK, "-T", "fields", "-e", "frame.number", "-e", "modbus.func_code"]
        measure(
            "tshark -T fields (frame per packet)",
            ln,
            [*fields, "-r", str(lone)],
            [*fields, "-r", str(one10)],
            runs,
        )
        ek = measure(
            "tshark -T ek (frame per packet)",
            ln,
            [*TSHARK, "-T", "ek", "-r", str(lone)],
            [*TSHARK, "-T", "ek", "-r", str(one10)],
            runs,
        )
        compare(jsonl, ek)
        compare(text, plain)
        compare(export, plain)
    out.unlink(missing_ok=True)


if __name__ == "__main__":
    main()

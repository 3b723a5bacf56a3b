"""Provides the live benchmark: modscope listening to a 921600 baud polling stream on a pty.

Run: python benchmarks/bench_live.py [--seconds S] [--baud N] [--per-frame] [--only live]

A writer thread plays a realistic polling stream (sniffer.sources.synth) into one end of a
pseudo-terminal at the line's own pace: every millisecond it writes the bytes whose last
bit would be on the wire by then, as a USB adapter with a 1 ms latency timer delivers
them (--per-frame: one write per frame, the worst case for the reader). modscope runs
as a separate process on the other end, once as `record` (capture and recording) and
once as `live --format jsonl --write` (capture, recording, framing, pairing, dissection
and the JSONL stream). Figures:

- CPU: modscope's user+system time over wall time while the stream runs (from
  /proc/PID/stat, so start-up does not count), as a share of one core;
- latency: from the moment the writer wrote a frame's last byte to the moment its JSONL
  line arrived on modscope's stdout (median, 99th percentile, worst);
- frames written and listed, bytes lost (must be 0);
- memory: modscope's resident set (VmRSS, sampled every second from /proc/PID/status)
  after warm-up (`--warmup` seconds into the stream), at the end, and the growth per
  frame listed between the two (`--rss-log FILE` keeps every sample).

The writer plays one cycle of synthetic frames (about two minutes of the line) over and
over, so an hour's run does not hold an hour of frames in this process.
"""

from __future__ import annotations

import argparse
import bisect
import gc
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import tty
from array import array
from collections import deque
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from sniffer.model import LineSettings
from sniffer.sources.synth import polling_frames

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# modscope from this tree (not whatever the venv's `modscope` script imports)
MODSCOPE = [sys.executable, "-m", "sniffer.cli"]
TICK = os.sysconf("SC_CLK_TCK")


LATENCY_TARGET = 0.050  # issue 11: every frame listed within 50 ms of its last byte
CYCLE_SECONDS = 120.0  # the writer's cycle of frames, played again and again


def child_env() -> dict[str, str]:
    """The environment modscope runs in: this tree first on its path."""
    paths = (ROOT, os.environ.get("PYTHONPATH", ""))
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in paths if p)}


def rss_mb(pid: int) -> float:
    """Resident memory of a process now, in MiB (Linux)."""
    for text in Path(f"/proc/{pid}/status").read_text().splitlines():
        if text.startswith("VmRSS:"):
            return int(text.split()[1]) / 1024
    return 0.0


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far (Linux)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


class Writer(threading.Thread):
    """Plays frames into the pty master at wire pace; remembers when each frame ended."""

    def __init__(
        self, fd: int, line: LineSettings, seconds: float, per_frame: bool, dense: bool
    ) -> None:
        super().__init__(daemon=True)
        self.fd = fd
        self.per_frame = per_frame
        cycle = min(seconds, CYCLE_SECONDS)
        n = int(cycle * line.baud / line.char_bits / 20) + 1000  # more than enough
        self.frames = polling_frames(n, line=line)
        char = line.char_time
        if dense:
            # back to back: 3.5 character times of silence and no more (the spec's fixed
            # 1.75 ms above 19200 baud would leave the line mostly idle)
            self.ends = []
            t = 0.0
            for f in self.frames:
                t += len(f.raw) * char
                self.ends.append(t)
                t += 3.5 * char
            self.period = t
        else:
            self.ends = [f.t + len(f.raw) * char for f in self.frames]
            self.period = self.ends[-1] + 3.5 * char
        self.seconds = seconds
        # every frame written, in order, with when: the listing comes in the same order
        self.sent: deque[tuple[bytes, float]] = deque()
        self.count = 0
        self.bytes = 0
        self.stop = threading.Event()

    def run(self) -> None:
        start = time.monotonic()
        k = 0  # next frame of the cycle
        base = 0.0  # the start of the current cycle, in stream seconds
        frames, ends, count = self.frames, self.ends, len(self.frames)
        while not self.stop.is_set():
            now = time.monotonic() - start
            if now >= self.seconds:
                break
            if self.per_frame:
                wait = base + ends[k] - now
                if wait > 0:
                    time.sleep(wait)
                due = k + 1
            else:
                due = k
                while due < count and base + ends[due] <= now:
                    due += 1
                if due == k:
                    time.sleep(0.001)
                    continue
            data = b"".join(f.raw for f in frames[k:due])
            written = time.monotonic()  # noted before writing: modscope may list it at once
            for f in frames[k:due]:
                self.sent.append((f.raw, written))
            view = memoryview(data)
            while view:
                view = view[os.write(self.fd, view) :]
            self.count += due - k
            self.bytes += len(data)
            k = due
            if k == count:  # the cycle again, after it
                k = 0
                base += self.period


LOOK_AHEAD = 64  # frames written the listing may have skipped (framed as noise)


def _match(sent: deque[tuple[bytes, float]], raw: bytes) -> float | None:
    """When the frame listed as `raw` was written: the next frame written if it is that,
    else one of the few after it (those before it were not listed as frames: dropped).
    Matched in order, not by content alone: a bus repeats its frames, and one frame
    missed would otherwise pair every later copy of it with the copy before."""
    for k in range(min(LOOK_AHEAD, len(sent))):
        if sent[k][0] == raw:
            for _ in range(k):
                sent.popleft()
            return sent.popleft()[1]
    return None


class Sampler(threading.Thread):
    """VmRSS of a process every second, with how many frames were listed by then."""

    def __init__(self, pid: int, listed: list[int]) -> None:
        super().__init__(daemon=True)
        self.pid = pid
        self.listed = listed  # one counter, shared with the listing reader
        self.samples: list[tuple[float, float, int]] = []  # (seconds, MB, frames listed)
        self.stop = threading.Event()

    def run(self) -> None:
        start = time.monotonic()
        while not self.stop.wait(1.0):
            try:
                mb = rss_mb(self.pid)
            except OSError:
                return
            self.samples.append((time.monotonic() - start, mb, self.listed[0]))

    def at(self, seconds: float) -> tuple[float, float, int] | None:
        """The first sample at or after `seconds`."""
        return next((x for x in self.samples if x[0] >= seconds), None)


def run(mode: str, args: argparse.Namespace, line: LineSettings, tmp: Path) -> None:
    master, slave = os.openpty()
    tty.setraw(slave)
    port = os.ttyname(slave)
    rec = tmp / f"{mode}.pcapng"
    line_args = ["--baud", str(line.baud), "--parity", "N", "--stopbits", "1", "--mode", "rtu"]
    if mode == "record":
        cmd = [*MODSCOPE, "record", port, *line_args, "-w", str(rec)]
    else:
        cmd = [*MODSCOPE, "live", port, *line_args, "--format", "jsonl", "-w", str(rec)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=child_env())
    assert proc.stderr is not None and proc.stdout is not None
    while True:
        text = proc.stderr.readline().decode()
        if not text:
            raise SystemExit(f"modscope did not start: {proc.communicate()[1].decode()}")
        if "listening on" in text or "modscope: recording" in text:
            break
    writer = Writer(master, line, args.seconds, args.per_frame, not args.polling_gaps)
    # the cycle's frames are long-lived: keep this process's garbage collector from
    # walking them while the listing is read (its pauses would count as latency)
    gc.collect()
    gc.freeze()
    latencies = array("d")
    # the worst latency of each minute of the stream, so that a spike can be set beside
    # what else the machine was doing then
    minute_worst: dict[int, float] = {}
    began = time.monotonic()
    listed = [0]  # frames listed (each frame is listed once; updates are not counted)
    unmatched = [0]  # frames listed that match none of the next frames written
    noise = 0
    updates = 0
    bad: list[bytes] = []

    def read_listing() -> None:
        nonlocal noise, updates
        assert proc.stdout is not None
        for raw_line in proc.stdout:
            arrived = time.monotonic()
            try:
                rec_ = json.loads(raw_line)
            except ValueError:  # counted and shown: a listing line must be whole JSON
                bad.append(raw_line)
                continue
            if "update" in rec_:  # a request listed while open, settled since
                updates += 1
                continue
            if rec_["kind"] == "noise":
                noise += 1
            if rec_["kind"] in ("noise", "event"):
                continue
            listed[0] += 1
            written = _match(writer.sent, bytes.fromhex(rec_["raw"]))
            if written is None:
                unmatched[0] += 1
            else:
                latencies.append(arrived - written)
                minute = int((arrived - began) // 60)
                if arrived - written > minute_worst.get(minute, 0.0):
                    minute_worst[minute] = arrived - written

    reader = threading.Thread(target=read_listing, daemon=True)
    reader.start()
    sampler = Sampler(proc.pid, listed)
    sampler.start()
    writer.start()
    time.sleep(1.0)  # warm up, then measure
    cpu0, wall0 = cpu_seconds(proc.pid), time.monotonic()
    writer.join()
    cpu1, wall1 = cpu_seconds(proc.pid), time.monotonic()
    sampler.stop.set()
    time.sleep(0.5)
    proc.send_signal(2)
    _, err = proc.communicate(timeout=60)
    reader.join(5)
    os.close(master)
    os.close(slave)
    share = (cpu1 - cpu0) / (wall1 - wall0)
    rate = writer.bytes / args.seconds
    print(
        f"{mode:<7} {writer.count:,} frames, {writer.bytes / 1e3:,.0f} kB in {args.seconds:.0f} s "
        f"({rate / 1e3:.1f} kB/s, {100 * rate / (line.baud / line.char_bits):.0f}% of the line)"
    )
    print(
        f"        CPU {100 * share:.1f}% of one core; recording {rec.stat().st_size / 1e6:.1f} MB"
    )
    lost = [x for x in err.decode().splitlines() if "data lost" in x]
    print(f"        losses reported: {len(lost)}" + (f" ({lost[0]})" if lost else ""))
    samples = sampler.samples
    if samples:
        warm = sampler.at(args.warmup) or samples[-1]
        last = samples[-1]
        peak = max(mb for _, mb, _ in samples)
        grown = last[1] - warm[1]
        frames = last[2] - warm[2]
        per = ""
        if frames > 0 and mode == "live":
            per = f", {grown * 2**20 / frames:+.1f} B per frame listed"
        print(
            f"        RSS {warm[1]:.1f} MiB at {warm[0]:.0f} s (warm), {last[1]:.1f} MiB at "
            f"{last[0]:.0f} s (end), peak {peak:.1f} MiB: {grown:+.1f} MiB{per}"
        )
        half = sampler.at(last[0] / 2)
        if half is not None and last[2] > half[2] and mode == "live":
            print(
                f"        second half: {half[1]:.1f} -> {last[1]:.1f} MiB, "
                f"{(last[1] - half[1]) * 2**20 / (last[2] - half[2]):+.1f} B per frame listed"
            )
        if args.rss_log:
            with open(f"{args.rss_log}.{mode}", "w") as log:
                log.writelines(f"{t:.0f} {mb:.1f} {n}\n" for t, mb, n in samples)
    if mode == "live":
        print(
            f"        frames listed {listed[0]:,} of {writer.count:,} written, noise {noise}, "
            f"updates {updates:,}, unmatched {unmatched[0]:,}"
        )
        if bad:
            print(f"        {len(bad)} lines not JSON, the first: {bad[0][:300]!r}")
        if latencies:
            ordered = sorted(latencies)
            p99 = ordered[min(len(ordered) - 1, int(0.99 * len(ordered)))]
            print(
                f"        latency last byte -> JSONL line: median "
                f"{1000 * statistics.median(ordered):.1f} ms, p99 {1000 * p99:.1f} ms, "
                f"max {1000 * ordered[-1]:.1f} ms"
            )
            over = len(ordered) - bisect.bisect_right(ordered, LATENCY_TARGET)
            p999 = ordered[min(len(ordered) - 1, int(0.999 * len(ordered)))]
            spikes = [
                f"{m}: {1000 * w:.0f} ms" for m, w in sorted(minute_worst.items())
                if w > LATENCY_TARGET
            ]  # fmt: skip
            print(
                f"        p99.9 {1000 * p999:.1f} ms; over {1000 * LATENCY_TARGET:.0f} ms: "
                f"{over:,} frames ({100 * over / len(ordered):.4f}%)"
                + (f", worst by minute of the stream {', '.join(spikes)}" if spikes else "")
            )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=10.0, help="length of each run")
    parser.add_argument("--baud", type=int, default=921600)
    parser.add_argument("--per-frame", action="store_true", help="one write per frame")
    parser.add_argument(
        "--polling-gaps",
        action="store_true",
        help="the synthetic master's own gaps (t3.5 = 1.75 ms above 19200 baud and more), "
        "not back-to-back frames",
    )
    parser.add_argument("--only", choices=("record", "live"), help="run one mode")
    parser.add_argument(
        "--warmup",
        type=float,
        default=30.0,
        help="seconds into the stream at which RSS counts as warmed up (default 30)",
    )
    parser.add_argument("--rss-log", metavar="FILE", help="every RSS sample, to FILE.MODE")
    args = parser.parse_args()
    line = LineSettings(baud=args.baud, bytesize=8, parity="N", stopbits=1, mode="rtu")
    style = "one write per frame" if args.per_frame else "1 ms delivery"
    style += ", polling gaps" if args.polling_gaps else ", back to back"
    print(f"{line.describe()}, {style}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.2f}")
    where = subprocess.run(
        [sys.executable, "-c", "import sniffer; print(sniffer.__file__)"],
        env=child_env(),
        capture_output=True,
        text=True,
    ).stdout.strip()
    print(f"modscope from {os.path.dirname(where)}")
    with tempfile.TemporaryDirectory() as tmp:
        for mode in ("record", "live"):
            if args.only in (None, mode):
                run(mode, args, line, Path(tmp))


if __name__ == "__main__":
    main()

"""Provides the live benchmark: modscope listening to a 921600 baud polling stream on a pty.

Run: python benchmarks/bench_live.py [--seconds S] [--baud N] [--per-frame]

A writer thread plays a realistic polling stream (sniffer.synth) into one end of a
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
- frames written and listed, bytes lost (must be 0).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import tty
from collections import defaultdict, deque
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from sniffer.model import LineSettings
from sniffer.synth import polling_frames

MODSCOPE = str(Path(sys.executable).with_name("modscope"))
TICK = os.sysconf("SC_CLK_TCK")


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
        n = int(seconds * line.baud / line.char_bits / 20) + 1000  # more than enough
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
        else:
            self.ends = [f.t + len(f.raw) * char for f in self.frames]
        self.seconds = seconds
        self.sent: dict[str, deque[float]] = defaultdict(deque)
        self.count = 0
        self.bytes = 0
        self.stop = threading.Event()

    def run(self) -> None:
        start = time.monotonic()
        k = 0
        frames, ends = self.frames, self.ends
        while not self.stop.is_set() and k < len(frames):
            now = time.monotonic() - start
            if now >= self.seconds:
                break
            if self.per_frame:
                wait = ends[k] - now
                if wait > 0:
                    time.sleep(wait)
                due = k + 1
            else:
                due = k
                while due < len(frames) and ends[due] <= now:
                    due += 1
                if due == k:
                    time.sleep(0.001)
                    continue
            data = b"".join(f.raw for f in frames[k:due])
            written = time.monotonic()  # noted before writing: modscope may list it at once
            for f in frames[k:due]:
                self.sent[f.raw.hex()].append(written)
            view = memoryview(data)
            while view:
                view = view[os.write(self.fd, view) :]
            self.count += due - k
            self.bytes += len(data)
            k = due


def run(mode: str, args: argparse.Namespace, line: LineSettings, tmp: Path) -> None:
    master, slave = os.openpty()
    tty.setraw(slave)
    port = os.ttyname(slave)
    rec = tmp / f"{mode}.pcapng"
    line_args = ["--baud", str(line.baud), "--parity", "N", "--stopbits", "1", "--mode", "rtu"]
    if mode == "record":
        cmd = [MODSCOPE, "record", port, *line_args, "-w", str(rec)]
    else:
        cmd = [MODSCOPE, "live", port, *line_args, "--format", "jsonl", "-w", str(rec)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stderr is not None and proc.stdout is not None
    while True:
        text = proc.stderr.readline().decode()
        if not text:
            raise SystemExit(f"modscope did not start: {proc.communicate()[1].decode()}")
        if "listening on" in text or "modscope: recording" in text:
            break
    writer = Writer(master, line, args.seconds, args.per_frame, not args.polling_gaps)
    latencies: list[float] = []
    listed: set[int] = set()
    noise = 0

    def read_listing() -> None:
        nonlocal noise
        assert proc.stdout is not None
        for raw_line in proc.stdout:
            arrived = time.monotonic()
            rec_ = json.loads(raw_line)
            if rec_["kind"] == "noise":
                noise += 1
            if rec_["kind"] in ("noise", "event") or rec_["index"] in listed:
                continue  # a request listed again when it timed out is counted once
            listed.add(rec_["index"])
            times = writer.sent.get(rec_["raw"])
            if times:
                latencies.append(arrived - times.popleft())

    reader = threading.Thread(target=read_listing, daemon=True)
    reader.start()
    writer.start()
    time.sleep(1.0)  # warm up, then measure
    cpu0, wall0 = cpu_seconds(proc.pid), time.monotonic()
    writer.join()
    cpu1, wall1 = cpu_seconds(proc.pid), time.monotonic()
    time.sleep(0.5)
    proc.send_signal(2)
    _, err = proc.communicate(timeout=30)
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
    if mode == "live":
        print(f"        frames listed {len(listed):,} of {writer.count:,} written, noise {noise}")
        if latencies:
            ordered = sorted(latencies)
            p99 = ordered[min(len(ordered) - 1, int(0.99 * len(ordered)))]
            print(
                f"        latency last byte -> JSONL line: median "
                f"{1000 * statistics.median(ordered):.1f} ms, p99 {1000 * p99:.1f} ms, "
                f"max {1000 * ordered[-1]:.1f} ms"
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
    args = parser.parse_args()
    line = LineSettings(baud=args.baud, bytesize=8, parity="N", stopbits=1, mode="rtu")
    style = "one write per frame" if args.per_frame else "1 ms delivery"
    style += ", polling gaps" if args.polling_gaps else ", back to back"
    print(f"{line.describe()}, {style}, {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory() as tmp:
        for mode in ("record", "live"):
            if args.only in (None, mode):
                run(mode, args, line, Path(tmp))


if __name__ == "__main__":
    main()

"""Provides the MQTT fleet benchmark: how many demo-rate buses one modscope process and one
Mosquitto carry on this machine.

Run: python benchmarks/bench_mqtt.py [--seconds S] [--buses 1,2,4,8,...]

For each N, one Python process runs N publishers at once, each a bus of its own (the
bundled demo with its three dictionaries, `modscope/bench<k>`, Home Assistant discovery
on), each fed the demo's reads at the recorded pace (what `replay --speed original`
does, and what a live port gives): about 28 reads and 26 frames a second per bus, the
first S seconds of the demo. A Mosquitto started on a free loopback port (no
persistence) takes them; `mosquitto_sub` in its own process subscribes to everything
(`modscope/#` and `homeassistant/#`, QoS 1) and counts what arrives, as a site's consumer would.

Per N: messages published and received, dropped by the publishers' buffers, how far the
slowest bus finished behind the demo's own clock, and the CPU time of each process over
the wall time (100 % = one core). A step "keeps up" when nothing was dropped, every
message arrived, and no bus ended more than a second behind.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from sniffer.meaning.annotate import load_bindings
from sniffer.model import Chunk
from sniffer.outputs.mqtt.publish import PublisherOptions, open_publisher, publish_replay
from sniffer.outputs.mqtt.target import parse_target
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, open_session

TICK = os.sysconf("SC_CLK_TCK")


def _cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


class Counter:
    """mosquitto_sub on everything under modscope/, counting lines in a thread."""

    def __init__(self, port: int) -> None:
        self.count = 0
        self.proc = subprocess.Popen(
            [
                "stdbuf",
                "-oL",
                "mosquitto_sub",
                "-p",
                str(port),
                "-q",
                "1",
                "-t",
                "modscope/#",
                "-t",
                "homeassistant/#",
                "-F",
                "%t",
            ],
            stdout=subprocess.PIPE,
        )
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for _line in self.proc.stdout:
            self.count += 1

    def stop(self) -> None:
        self.proc.terminate()
        self.proc.wait(5)


def run(n: int, seconds: float, port: int, mosquitto_pid: int) -> dict[str, float]:
    bindings = load_bindings(DEMO_BUS)
    counter = Counter(port)
    time.sleep(0.5)
    publishers = []
    feeds: list[list[Chunk]] = []
    for k in range(n):
        session, capture = open_session(DEMO_CAPTURE, bindings=bindings)
        chunks = list(capture.chunks())
        t0 = chunks[0].t_end
        feeds.append([c for c in chunks if c.t_end - t0 <= seconds])
        target = parse_target(f"mqtt://127.0.0.1:{port}/modscope/bench{k}")
        options = PublisherOptions(bus=f"bench{k}", ha_prefix="homeassistant", block=False)
        publishers.append((session, open_publisher(target, session, bindings, options)))
    behind: list[float] = [0.0] * n
    use0 = resource.getrusage(resource.RUSAGE_SELF)
    broker0 = _cpu_seconds(mosquitto_pid)
    sub0 = _cpu_seconds(counter.proc.pid)
    wall0 = time.monotonic()

    def bus(k: int) -> None:
        session, pub = publishers[k]
        start = time.monotonic()
        publish_replay(session, feeds[k], pub, original_speed=True)
        span = feeds[k][-1].t_end - feeds[k][0].t_end
        behind[k] = time.monotonic() - start - span

    threads = [threading.Thread(target=bus, args=(k,)) for k in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    wall = time.monotonic() - wall0
    use1 = resource.getrusage(resource.RUSAGE_SELF)
    cpu = (use1.ru_utime - use0.ru_utime) + (use1.ru_stime - use0.ru_stime)
    broker = _cpu_seconds(mosquitto_pid) - broker0
    sub = _cpu_seconds(counter.proc.pid) - sub0
    offered = dropped = 0
    for _session, pub in publishers:
        pub.link.drain(10)
        offered += pub.link.counts.offered
        dropped += pub.link.counts.dropped
    for _session, pub in publishers:
        pub.link.close(5)
    time.sleep(1.0)
    received = counter.count
    counter.stop()
    return {
        "buses": n,
        "wall": wall,
        "published": offered - dropped,
        "received": received,
        "dropped": dropped,
        "behind": max(behind),
        "modscope_cpu": cpu / wall * 100,
        "mosquitto_cpu": broker / wall * 100,
        "sub_cpu": sub / wall * 100,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="demo seconds per step")
    parser.add_argument("--buses", default="1,2,4,8,16,24,32,48,64,72,80,96,128")
    args = parser.parse_args()
    if shutil.which("mosquitto") is None:
        raise SystemExit("needs mosquitto and mosquitto_sub (apt-get install mosquitto)")
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
    )
    print(
        f"{'buses':>5} {'published':>10} {'received':>9} {'dropped':>8} {'behind s':>9} "
        f"{'modscope %':>10} {'mosquitto %':>11} {'sub %':>6}"
    )
    with tempfile.TemporaryDirectory() as folder:
        port = _free_port()
        conf = Path(folder, "mosquitto.conf")
        conf.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\n")
        broker = subprocess.Popen(
            ["mosquitto", "-c", str(conf)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        try:
            time.sleep(0.5)
            for n in (int(x) for x in args.buses.split(",")):
                r = run(n, args.seconds, port, broker.pid)
                ok = r["dropped"] == 0 and r["received"] >= r["published"] and r["behind"] < 1
                print(
                    f"{n:>5} {r['published']:>10,.0f} {r['received']:>9,.0f} "
                    f"{r['dropped']:>8,.0f} {r['behind']:>9.2f} {r['modscope_cpu']:>9.0f}% "
                    f"{r['mosquitto_cpu']:>10.0f}% {r['sub_cpu']:>5.0f}%"
                    + ("" if ok else "  falls behind"),
                    flush=True,
                )
                if not ok:
                    break
        finally:
            broker.terminate()
            broker.wait(5)


if __name__ == "__main__":
    main()

"""Provides the sidecar index benchmark: its size as a share of the capture, and the
CPU time of writing and reading it, per shape of capture.

Run: python benchmarks/bench_index.py [--frames N] [--runs R] [--dir DIR] [--base TREE]
     [--mixes project,issue29,mix163457879]

For each mix (`benchmarks/mixes.py`: the project's stream, the bus of issue #29, a
random bus) it takes both shapes `bench_scale.py` writes (16 ms reads as `modscope
record` writes them, and one frame per packet), then, as whole processes:
- `replay --stats` with no sidecar to read, so that it writes one (the write), and
  again, from that sidecar (the read);
- the size of the sidecar, as a share of the capture, and per part (columns, bytes,
  statistics; `--parts`).
It prints the median CPU time (user + system, of the child) of R runs of each, and with
`--base TREE` (a checkout of modscope before the change, its compiled core built) the
same from that tree, runs alternated, and the ratio. `MODSCOPE_NO_INDEX=1` runs give
the cost with no sidecar at all. tshark reads these captures in `bench_scale.py`; its
figure on the same file is printed with `--tshark` (its RTU summary of the one frame a
packet shape).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.bench_scale import TSHARK, machine  # noqa: E402

SCALE = ROOT / "benchmarks" / "bench_scale.py"


def files(folder: Path, mix: str, n: int, seed: int) -> tuple[Path, Path]:
    """The two shapes of `mix` (written by bench_scale.py once, kept in `folder`)."""
    if mix == "project":
        reads, one = folder / f"reads-{n}.pcapng", folder / f"frames-{n}.pcapng"
        argv = ["--write-files", str(n)]
    else:
        reads = folder / f"{mix}-reads-{n}.pcapng"
        one = folder / f"{mix}-frames-{n}.pcapng"
        seed = int(mix[3:]) if mix.startswith("mix") else seed
        argv = ["--write-mix", str(n), "--mix-name", mix, "--seed", str(seed)]
    if not (reads.exists() and one.exists()):
        folder.mkdir(parents=True, exist_ok=True)
        subprocess.run([sys.executable, str(SCALE), *argv, "--dir", str(folder)], check=True)
    return reads, one


def cpu_of(argv: list[str], cwd: Path, env: dict[str, str]) -> float:
    """CPU seconds (user + system) of one run of `argv` as a child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(argv, cwd=cwd, env=env, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)  # fmt: skip
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def sidecar_of(capture: Path) -> Path:
    return capture.with_name(capture.name + ".modscope-index")


def parts_of(side: Path, tree: Path) -> dict[str, int] | None:
    """The sizes of a format-3 sidecar's parts (columns, bytes, statistics, header)."""
    code = (
        "import json, sys\n"
        "from sniffer.session import index\n"
        "data = open(sys.argv[1], 'rb').read()\n"
        "size = index._PREFIX.unpack_from(data, len(index.MAGIC))[0]\n"
        "start = len(index.MAGIC) + index._PREFIX.size\n"
        "h = json.loads(data[start:start + size])\n"
        "if h.get('format') != 3: print('null'); sys.exit()\n"
        "at = start + size\n"
        "out = dict.fromkeys(index.COLUMNS, 0); out['bytes'] = 0; out['tables'] = 0\n"
        "for count, pcs, crc, length in h['blocks']:\n"
        "    b = index.Packed(data[at:at + length], count, 0, len(pcs))\n"
        "    for name in index.COLUMNS: out[name] += b.columns[name][1]\n"
        "    out['bytes'] += sum(p[4] for listed in b.pieces for p in listed)\n"
        "    out['tables'] += b.columns[index.COLUMNS[0]][0]\n"
        "    at += length\n"
        "out['statistics'] = sum(h['tail']); out['header'] = start + size\n"
        "print(json.dumps(out))\n"
    )
    got = subprocess.run(
        [sys.executable, "-c", code, str(side)], cwd=tree, capture_output=True, text=True
    )
    return json.loads(got.stdout) if got.returncode == 0 else None


def measure(capture: Path, trees: dict[str, Path], runs: int, show_parts: bool) -> None:
    env = {k: v for k, v in os.environ.items() if k != "MODSCOPE_NO_INDEX"}
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # (compiled once, not at every run)
    env.setdefault("PYTHONPYCACHEPREFIX", str(capture.parent / "pycache"))
    argv = [sys.executable, "-m", "sniffer.cli", "replay", str(capture), "--stats"]
    side = sidecar_of(capture)
    times: dict[str, dict[str, list[float]]] = {
        name: {"none": [], "write": [], "read": []} for name in trees
    }
    sizes: dict[str, int] = {}
    for tree in trees.values():  # compile and warm up
        cpu_of(argv, tree, {**env, "MODSCOPE_NO_INDEX": "1"})
    for _ in range(runs):
        for name, tree in trees.items():  # alternated
            times[name]["none"].append(cpu_of(argv, tree, {**env, "MODSCOPE_NO_INDEX": "1"}))
            side.unlink(missing_ok=True)
            times[name]["write"].append(cpu_of(argv, tree, env))
            sizes[name] = side.stat().st_size
            times[name]["read"].append(cpu_of(argv, tree, env))
    capture_size = capture.stat().st_size
    print(f"{capture.name}: {capture_size / 1e6:.1f} MB")
    for name in trees:
        t = {k: statistics.median(v) for k, v in times[name].items()}
        print(
            f"  {name:<6} sidecar {sizes[name] / 1e6:6.2f} MB = "
            f"{100 * sizes[name] / capture_size:5.1f}% of the capture; CPU s (median of "
            f"{runs}): no sidecar {t['none']:.2f}, write {t['write']:.2f}, read {t['read']:.2f}",
            flush=True,
        )
    if len(trees) == 2:
        (a, ta), (b, tb) = ((k, {x: statistics.median(v) for x, v in times[k].items()})
                            for k in trees)  # fmt: skip
        print(
            f"  {b} / {a}: write {tb['write'] / ta['write']:.2f}, read "
            f"{tb['read'] / ta['read']:.2f}, size {sizes[b] / sizes[a]:.3f}"
        )
    if show_parts:
        side.unlink(missing_ok=True)
        last = list(trees.values())[-1]
        cpu_of(argv, last, env)
        parts = parts_of(side, last)
        if parts is not None:
            print(
                "  parts: "
                + ", ".join(f"{k} {100 * v / capture_size:.2f}%" for k, v in parts.items())
            )


def tshark_cpu(capture: Path, runs: int) -> float:
    """Median CPU seconds of tshark's plain summary of `capture`."""
    return statistics.median(
        cpu_of([*TSHARK, "-r", str(capture)], capture.parent, dict(os.environ)) for _ in range(runs)
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0] if __doc__ else "")
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--runs", type=int, default=3, help="runs per figure (median)")
    parser.add_argument("--dir", type=Path, default=Path("/tmp/modscope-bench"))
    parser.add_argument("--base", type=Path, help="a tree of modscope to compare with")
    parser.add_argument("--mixes", default="project,issue29,mix163457879")
    parser.add_argument("--seed", type=int, default=29)
    parser.add_argument("--parts", action="store_true", help="the sidecar's size per part")
    parser.add_argument("--tshark", type=int, default=0, metavar="R",
                        help="tshark's CPU on each file, median of R runs")  # fmt: skip
    args = parser.parse_args()
    print(f"machine: {machine()}; load average {os.getloadavg()[0]:.2f}")
    trees = {"new": ROOT} if args.base is None else {"base": args.base, "new": ROOT}
    started = time.perf_counter()
    for mix in args.mixes.split(","):
        for capture in files(args.dir, mix, args.frames, args.seed):
            measure(capture, trees, args.runs, args.parts)
            if args.tshark:
                print(f"  tshark -r (plain summary): {tshark_cpu(capture, args.tshark):.2f} CPU s")
    print(
        f"load average at the end {os.getloadavg()[0]:.2f} ({time.perf_counter() - started:.0f} s)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

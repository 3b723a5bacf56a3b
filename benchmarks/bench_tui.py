"""Provides the TUI benchmark: first screen, full index, jump and page on a large capture.

    python benchmarks/bench_tui.py --frames 1000000

Writes a synthetic polling capture (pcapng, link type 147, one packet per frame) in a
child process, then opens it in the app headless at 120x36 and prints: time to the
first screen (target < 1 s), time to the full index (wall and CPU), the time of a jump to the middle
and of a page down (target < 50 ms each: the widget's work, and the round trip through
the app's event loop), the worst key typed while indexing (target < 100 ms), a column
filter and a transaction view over every row, the ladder opened at the middle, and the
peak memory of the process (ru_maxrss).

Then it opens the capture again, from the sidecar index the first open wrote (a sidecar
left from before is deleted first), and prints the time to the first screen of that
reopening (target < 0.5 s, whatever the size of the capture) and to all its rows.
"""

from __future__ import annotations

import argparse
import asyncio
import io
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from sniffer.model import LineSettings  # noqa: E402
from sniffer.session.session import open_session  # noqa: E402
from sniffer.sources.linktypes import describe_interface  # noqa: E402
from sniffer.sources.pcapng_writer import LINKTYPE_USER0, PcapngWriter  # noqa: E402
from sniffer.sources.synth import clean_chunks, polling_frames  # noqa: E402

LINE = LineSettings(baud=115200, parity="N", stopbits=1, mode="rtu")
EPOCH = 1_700_000_000.0


def make_capture(path: Path, frames: int) -> None:
    """A pcapng file of `frames` synthetic frames, one packet each (time = end of frame)."""
    buf = io.BytesIO()
    writer = PcapngWriter(buf)
    iface = writer.add_interface(
        LINKTYPE_USER0, name="synthetic", description=describe_interface(LINE)
    )
    for chunk in clean_chunks(polling_frames(frames, line=LINE), LINE):
        writer.write_packet(iface, EPOCH + chunk.t_end, chunk.data)
    path.write_bytes(buf.getvalue())


async def measure_reopen(path: Path) -> dict[str, float]:
    """First screen and every row of a capture opened again, from its sidecar index."""
    from sniffer.tui.app import ModscopeApp

    out: dict[str, float] = {}
    start = time.perf_counter()
    cpu = time.process_time()
    session, capture = open_session(path)
    app = ModscopeApp(session, capture, blink=False)
    async with app.run_test(size=(120, 36)):
        frames = app.frames
        while frames.first_drawn is None:
            await asyncio.sleep(0.002)
        out["reopen: first screen s"] = frames.first_drawn - start
        out["reopen: rows at first screen"] = frames.count
        while not app.indexed.is_set():
            await asyncio.sleep(0.01)
        out["reopen: every row s"] = time.perf_counter() - start
        out["reopen: every row CPU s"] = time.process_time() - cpu
        out["reopen: rows"] = app.model.published
        if session.indexed_from is None:
            raise SystemExit("the capture was indexed again, not read from its sidecar")
    return out


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


async def measure(path: Path) -> dict[str, float]:
    from textual.widgets import Input

    from sniffer.tui.app import ModscopeApp
    from sniffer.tui.screens.ladder import LadderScreen

    out: dict[str, float] = {}
    start = time.perf_counter()
    cpu = time.process_time()
    session, capture = open_session(path)
    app = ModscopeApp(session, capture, blink=False)
    async with app.run_test(size=(120, 36)) as pilot:
        frames = app.frames
        while frames.first_drawn is None:
            await asyncio.sleep(0.002)
        out["first screen s"] = frames.first_drawn - start
        out["rows at first screen"] = frames.count
        # keys typed while the capture is still being indexed (target < 100 ms each)
        frames.focus()
        waits = []
        for key in ("j", "j", "pagedown", "k", "end", "home"):
            if app.indexed.is_set():
                break
            t = time.perf_counter()
            app.simulate_key(key)
            while frames.drawn_at < t:
                await asyncio.sleep(0.0005)
            waits.append(frames.drawn_at - t)
        if waits:
            out["key while indexing ms (worst)"] = max(waits) * 1000
        while not app.indexed.is_set():
            await asyncio.sleep(0.01)
        out["full index s"] = time.perf_counter() - start
        # both threads' CPU time: on a shared machine the wall time above says more about
        # the other processes than about this one
        out["full index CPU s"] = time.process_time() - cpu
        out["peak RSS MB, indexed"] = peak_mb()
        await pilot.pause()
        out["rows"] = app.model.published
        height = frames.page_height

        def draw() -> None:
            for y in range(height):
                frames.render_line(y)

        t = time.perf_counter()
        frames.go_to(frames.count // 2)
        draw()
        out["jump to middle ms (widget)"] = (time.perf_counter() - t) * 1000
        t = time.perf_counter()
        frames.action_page(1)
        draw()
        out["page down ms (widget)"] = (time.perf_counter() - t) * 1000

        async def key_to_screen(key: str) -> float:
            """Seconds from a key press to the frame list drawn anew (through the event
            loop, as a keystroke from the terminal)."""
            t = time.perf_counter()
            app.simulate_key(key)
            while frames.drawn_at < t:
                await asyncio.sleep(0.0005)
            return frames.drawn_at - t

        frames.focus()
        await pilot.pause()
        t = time.perf_counter()
        reader = app.model.reader
        middle = reader.t[0] + (reader.t[app.model.published - 1] - reader.t[0]) / 2
        frames.go_to(app.model.view.at_time(reader, middle))
        while frames.drawn_at < t:
            await asyncio.sleep(0.0005)
        out["go to middle time ms (call to screen)"] = (frames.drawn_at - t) * 1000
        out["page down ms (key to screen)"] = await key_to_screen("pagedown") * 1000
        out["end ms (key to screen)"] = await key_to_screen("end") * 1000
        out["home ms (key to screen)"] = await key_to_screen("home") * 1000
        for name, key in (("only problems", "exclamation_mark"), ("transactions", "t")):
            t = time.perf_counter()
            await pilot.press(key)
            job = app.model.job
            while job is None or not job.caught_up:
                await pilot.pause(0.01)
                job = app.model.job
            out[f"{name} view s"] = time.perf_counter() - t
            out[f"{name} rows"] = len(app.model.view)
            await pilot.press(key)
        # free text dissects every candidate row: report the rate, not the (long) total
        filter_input = app.main.query_one("#filter", Input)
        filter_input.value = "illegal"
        filter_input.focus()
        t = time.perf_counter()
        await pilot.press("enter")
        job = app.model.job
        while job is None or (not job.caught_up and time.perf_counter() - t < 3.0):
            await asyncio.sleep(0.01)
            job = app.model.job
        out["free text filter rows/s"] = job.checked / (time.perf_counter() - t)
        await pilot.press("escape")
        filter_input.value = ""
        await pilot.press("slash", "enter")
        await pilot.pause()
        # the ladder at the middle: only the lines on screen are built
        frames.go_to(frames.count // 2)
        await pilot.pause()
        t = time.perf_counter()
        await pilot.press("l")
        screen = app.screen
        assert isinstance(screen, LadderScreen)
        screen.view.render()
        out["ladder at middle ms (key and draw)"] = (time.perf_counter() - t) * 1000
        t = time.perf_counter()
        screen.view.page(1)
        screen.view.render()
        out["ladder page down ms (draw)"] = (time.perf_counter() - t) * 1000
        await pilot.press("escape")
        # the rows the TUI holds (paged: the columns kept in memory and the cache)
        out["store MB"] = app.model.reader.memory_bytes() / 1e6
    out["peak RSS MB"] = peak_mb()
    return out


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--frames", type=int, default=1_000_000, help="frames in the capture")
    parser.add_argument("--file", type=Path, help="use (or keep) the capture at this path")
    parser.add_argument("--make", type=Path, help=argparse.SUPPRESS)  # child: write and exit
    args = parser.parse_args()
    if args.make is not None:
        make_capture(args.make, args.frames)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        path = args.file or Path(tmp) / f"bench-{args.frames}.pcapng"
        if not path.exists():
            t = time.perf_counter()
            subprocess.run(
                [sys.executable, __file__, "--make", str(path), "--frames", str(args.frames)],
                check=True,
            )
            size = path.stat().st_size / 1e6
            print(f"wrote {path.name}: {size:.1f} MB in {time.perf_counter() - t:.1f} s")
        from sniffer.session import index

        for old in index.sidecars(path):
            old.unlink(missing_ok=True)  # the first open indexes (and writes the sidecar)
        figures = asyncio.run(measure(path))
        figures.update(asyncio.run(measure_reopen(path)))
    width = max(len(k) for k in figures)
    for name, value in figures.items():
        whole = name.endswith(("rows", "rows/s", "first screen"))
        shown = f"{value:,.0f}" if whole else f"{value:,.3f}"
        print(f"{name:<{width}}  {shown}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

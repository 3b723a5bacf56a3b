"""Every cell the TUI draws is readable: rendered screens are read cell by cell (foreground
and background as the terminal gets them) and each visible character must have a
contrast of at least 4.5:1 (WCAG AA for text; box drawing, sparklines and scrollbars
are held to the same), in both themes, after `T` switches between them, at 80x24 and
200x50. A cell left in the terminal's default colour fails too: its contrast is unknown.
"""

from __future__ import annotations

import pytest
from rich.style import Style

from sniffer.meaning.annotate import load_bindings
from sniffer.session.session import DEMO_BUS, DEMO_CAPTURE, Session, replay_file
from sniffer.tui.app import ModscopeApp
from sniffer.tui.theme import contrast
from tests.support.tui import ready

pytestmark = [
    pytest.mark.asyncio,
    pytest.mark.skipif(not DEMO_CAPTURE.exists(), reason="the demo capture is missing"),
]
_SESSION: list[Session] = []

# the screens people read at 2 a.m.: the list and each pane, the full details, the help,
# the ladder, the register plot and table, a refused filter, a prompt, only problems
STATES: dict[str, list[str]] = {
    "main": [],
    "details, field tree": ["enter", "down", "down"],
    "details on the whole screen": ["g", "#", "6", "0", "0", "enter", "D"],
    "units": ["u"],
    "register watch": ["w", "tab"],
    "register plot": ["w", "tab", "enter"],
    "register table": ["w", "tab", "x", "down", "x", "R"],
    "ladder": ["l"],
    "help": ["question_mark"],
    "refused filter": [*"/unti:3", "enter"],
    "prompt": ["g"],
    "problems only": ["exclamation_mark", "down"],
}
WIDE = ("main", "register watch", "details on the whole screen")
# what `T` must draw again in the new colours (drawn once, not on every refresh)
AFTER_T = ("main", "details, field tree", "units", "register watch", "ladder")


def demo() -> Session:
    if not _SESSION:
        _SESSION.append(replay_file(DEMO_CAPTURE, bindings=load_bindings(DEMO_BUS)))
    return _SESSION[0]


def hex_of(colour: object) -> str | None:
    triplet = getattr(colour, "triplet", None)
    return triplet.hex if triplet is not None else None


def unreadable(app: ModscopeApp) -> list[str]:
    """Every run of visible characters on the screen whose contrast is below 4.5:1."""
    found = []
    for y, strip in enumerate(app.screen._compositor.render_strips()):
        for segment in strip:
            text, style = segment.text, segment.style or Style()
            if not text.strip():
                continue
            fg, bg = hex_of(style.color), hex_of(style.bgcolor)
            if style.reverse:
                fg, bg = bg, fg
            if fg is None or bg is None:
                found.append(f"line {y}: {text.strip()!r} in the terminal's default colour")
                continue
            ratio = contrast(fg, bg)
            if ratio < 4.5 or style.dim:
                found.append(f"line {y}: {text.strip()!r} {fg} on {bg} = {ratio:.2f}:1")
    return found


async def check(light: bool, keys: list[str], size: tuple[int, int]) -> list[str]:
    app = ModscopeApp(demo(), blink=False, light=light)
    async with app.run_test(size=size) as pilot:
        await ready(pilot, app)
        for key in keys:
            await pilot.press(key)
        app._tick()  # the watch and units panes fill on the app's tick (every 0.5 s)
        await pilot.pause(0.05)
        return unreadable(app)


@pytest.mark.parametrize("state", sorted(STATES))
@pytest.mark.parametrize("light", [False, True])
async def test_every_cell_is_readable_at_80x24(light: bool, state: str) -> None:
    assert (await check(light, STATES[state], (80, 24))) == []


@pytest.mark.parametrize("state", AFTER_T)
@pytest.mark.parametrize("light", [False, True])
async def test_every_cell_is_readable_after_t_switches_the_theme(light: bool, state: str) -> None:
    """Started in one theme, `T` pressed after the state is drawn: all of it redrawn."""
    assert (await check(light, [*STATES[state], "T"], (80, 24))) == []


@pytest.mark.parametrize("state", WIDE)
@pytest.mark.parametrize("light", [False, True])
async def test_every_cell_is_readable_at_200x50(light: bool, state: str) -> None:
    assert (await check(light, STATES[state], (200, 50))) == []

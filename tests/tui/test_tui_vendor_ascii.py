"""The TUI shows an ABL wallbox's `>` answers as answers, tagged `vendor` in the list and
with the vendor fact, in the info colour, among the detail pane's problems."""

from __future__ import annotations

import pytest

from sniffer.model import Chunk, LineSettings
from sniffer.session.session import Session
from sniffer.tui.app import ModscopeApp
from sniffer.tui.widgets.detail import DetailPane, FieldTree
from tests.support.tui import ready, screen_text

pytestmark = pytest.mark.asyncio
SIZE = (140, 36)
ABL = LineSettings(baud=38400, bytesize=8, parity="E", stopbits=1, mode="ascii")
READ = b":0303002E0005C7\r\n"
STATUS = b">03030A2EA1B20C025803E803E833\r\n"


def abl_session() -> Session:
    session = Session(ABL)
    for k, data in enumerate([READ, STATUS, READ, STATUS]):
        session.feed(Chunk(data, 1_700_000_000 + k // 2 + (0.03 if k % 2 else 0)))
    session.finish()
    return session


async def test_the_vendor_answer_is_tagged_and_its_fact_shown_in_the_details() -> None:
    app = ModscopeApp(abl_session())
    async with app.run_test(size=SIZE) as pilot:
        await ready(pilot, app)
        await pilot.press("down")  # row 1: the wallbox's answer
        await pilot.pause()
        pane = app.main.query_one("#detail", DetailPane)
        assert pane.detail is not None and pane.detail.view.index == 1
        tree = app.main.query_one("#fields", FieldTree)
        problems = next(n for n in tree.root.children if str(n.label).startswith("problems"))
        (leaf,) = problems.children
        assert (
            str(leaf.label) == "vendor variant: '>' where Modbus ASCII has ':' (ABL eMH1 answers)"
        )
        assert leaf.label.style == tree.style("info")  # type: ignore[union-attr]
        listed = [line.split() for line in screen_text(app).splitlines() if line[:4] == "   #"]
        rows = {words[0]: " ".join(words) for words in listed}
        assert "vendor 5 values" in rows["#1"] and "vendor" not in rows["#0"]

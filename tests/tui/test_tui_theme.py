"""Colours: one per meaning, each readable (WCAG contrast >= 4.5:1) on the list and on the
selected row, in both themes; and the stylesheet really uses them."""

from __future__ import annotations

import pytest

from sniffer.tui.app import ModscopeApp
from sniffer.tui.theme import BACKGROUNDS, MEANINGS, PALETTES, contrast
from tests.support.tui import hostile_session


def test_contrast_is_computed_as_wcag_defines_it() -> None:
    assert contrast("#000000", "#ffffff") == pytest.approx(21.0)
    assert contrast("#777777", "#ffffff") == pytest.approx(4.48, abs=0.01)
    assert contrast("#ffffff", "#ffffff") == pytest.approx(1.0)


@pytest.mark.parametrize("theme", sorted(PALETTES))
def test_every_meaning_is_legible_on_the_list_and_on_the_selected_row(theme: str) -> None:
    palette = PALETTES[theme]
    for meaning in MEANINGS:
        for bg in BACKGROUNDS:
            ratio = contrast(palette[meaning], palette[bg])
            assert ratio >= 4.5, f"{theme}: {meaning} on {bg} is {ratio:.2f}:1"


@pytest.mark.parametrize("theme", sorted(PALETTES))
def test_problems_of_different_kinds_have_different_colours(theme: str) -> None:
    palette = PALETTES[theme]
    problems = ("exception", "check", "timeout", "timing", "noise", "event")
    assert len({palette[m] for m in problems}) == len(problems)


@pytest.mark.asyncio
@pytest.mark.parametrize("light", [False, True])
async def test_the_frame_list_draws_with_the_theme_colours(light: bool) -> None:
    app = ModscopeApp(hostile_session(), light=light)
    palette = PALETTES["modscope-light" if light else "modscope-dark"]
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.pause()
        frames = app.frames
        for part, meaning in (("exception", "exception"), ("check", "check"), ("unit", "unit")):
            style = frames.get_component_rich_style(f"frame-list--{part}", partial=True)
            assert style.color is not None and style.color.triplet is not None
            assert style.color.triplet.hex == palette[meaning]
        cursor = frames.get_component_rich_style("frame-list--cursor", partial=True)
        assert cursor.bgcolor is not None and cursor.bgcolor.triplet is not None
        assert cursor.bgcolor.triplet.hex == palette["cursor"]

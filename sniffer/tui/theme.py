"""Provides the TUI's two themes: one colour per meaning (exception, bad check, timeout, slow or
other timing flag, noise, event), legible on the selected row.

Each colour is given as a Textual theme variable (`$row-exception`, ...) that the
stylesheet uses; every foreground keeps a contrast of at least 4.5:1 (WCAG AA) on the
list's background and on the selected row, focused or not (tests/tui/test_tui_theme.py
computes it). `modscope-dark` is the default; `modscope-light` is for bright rooms and
light terminals (the `T` key switches between them).
"""

from __future__ import annotations

from textual.theme import Theme

# the meanings the rows and panes colour, and the backgrounds they must be read on
MEANINGS = ("exception", "check", "timeout", "timing", "noise", "event", "unit", "text", "muted")
BACKGROUNDS = ("background", "cursor", "cursor-blur")

PALETTES: dict[str, dict[str, str]] = {
    "modscope-dark": {
        "exception": "#ff8080",  # the slave said no
        "check": "#ff8ae2",  # the bytes are damaged (CRC, LRC, non-hex)
        "timeout": "#ffab5e",  # no answer
        "timing": "#ecc94b",  # slow, late, quiet-time, retry, orphan: timing and pairing flags
        "noise": "#a8b3bf",
        "event": "#7cc4ff",  # port lost, data lost
        "unit": "#c9a7ff",
        "text": "#e8eef4",
        "muted": "#a8b3bf",
        "background": "#101418",
        "cursor": "#243b55",
        "cursor-blur": "#1c2630",
        "on-state": "#ffffff",  # the status bars' text, on their state's dark colour
    },
    "modscope-light": {
        "exception": "#b3261e",
        "check": "#a01c78",
        "timeout": "#8f4300",
        "timing": "#6b5300",
        "noise": "#525c66",
        "event": "#0b57a8",
        "unit": "#6a3fb8",
        "text": "#1f2328",
        "muted": "#525c66",
        "background": "#ffffff",
        "cursor": "#cfe2ff",
        "cursor-blur": "#e6edf5",
        "on-state": "#ffffff",
    },
}


def themes() -> list[Theme]:
    out = []
    for name, p in PALETTES.items():
        dark = name.endswith("dark")
        out.append(
            Theme(
                name=name,
                primary="#3d7cc9" if dark else "#0b57a8",
                secondary="#8d6fd1" if dark else "#6a3fb8",
                accent="#e0a030" if dark else "#8f4300",
                warning="#ecc94b" if dark else "#8f4300",
                error="#ff8080" if dark else "#b3261e",
                success="#5fc98a" if dark else "#1a7f37",
                foreground=p["text"],
                background=p["background"],
                surface="#161c22" if dark else "#f6f8fa",
                panel="#1f2933" if dark else "#eaeef2",
                dark=dark,
                variables={f"row-{k}": v for k, v in p.items()} | widget_colours(p),
            )
        )
    return out


def widget_colours(p: dict[str, str]) -> dict[str, str]:
    """Textual's own widget variables (the cursor of a table or tree, an input's cursor
    and selection, hover) set from the palette: left to Textual, some are the terminal's
    default colour or a contrast of 3.6:1 (white on the primary blue)."""
    return {
        "block-cursor-background": p["cursor"],
        "block-cursor-foreground": p["text"],
        "block-cursor-text-style": "bold",
        "block-cursor-blurred-background": p["cursor-blur"],
        "block-cursor-blurred-foreground": p["text"],
        "block-cursor-blurred-text-style": "none",
        "block-hover-background": p["cursor-blur"],
        "input-cursor-background": p["text"],
        "input-cursor-foreground": p["background"],
        "input-selection-background": p["cursor"],
        "foreground-muted": p["muted"],
    }


def contrast(fg: str, bg: str) -> float:
    """The WCAG contrast ratio of two `#rrggbb` colours (1 to 21)."""

    def luminance(colour: str) -> float:
        h = colour.lstrip("#")
        channels = [int(h[i : i + 2], 16) / 255 for i in (0, 2, 4)]
        lin = [c / 12.92 if c <= 0.03928 else ((c + 0.055) / 1.055) ** 2.4 for c in channels]
        return 0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2]

    hi, lo = sorted((luminance(fg), luminance(bg)), reverse=True)
    return (hi + 0.05) / (lo + 0.05)

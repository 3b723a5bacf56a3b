"""Provides `offline_templates`: textual-serve's page for `modscope serve`, without the web
font it fetches from the internet.

textual-serve's page links a stylesheet on fonts.googleapis.com for its terminal font
(Roboto Mono). A site PC or a plant network often has no internet: the browser then
waits for that request, and the page leaks each visit to a third party. The page's own
font list goes on to the browser's monospace fonts (Roboto Mono is still used where it
is installed), so the link is left out. The page is read from the installed
textual-serve at start-up and written, changed only there, to a temporary folder
removed on exit; nothing of it is kept in this repository.
"""

from __future__ import annotations

import atexit
import re
import shutil
import tempfile
from pathlib import Path

PAGE = "app_index.html"
# a <link> element whose href leaves the server (the web font's stylesheet)
OUTSIDE_LINK = re.compile(r"<link\b[^>]*\bhref=\"https?://[^\"]*\"[^>]*>\s*", re.S)


def offline_page(html: str) -> str:
    """The page with every stylesheet link to another host left out."""
    return OUTSIDE_LINK.sub("", html)


def offline_templates() -> Path:
    """A templates folder for textual-serve's `Server` whose page loads nothing from the
    internet (the installed page, without its web font link); where the installed page
    is not found, textual-serve's own folder (`templates`, relative to its module)."""
    import textual_serve  # here: the optional [serve] extra, present when this is called

    installed = getattr(textual_serve, "__file__", None)
    source = Path(installed or ".").parent / "templates" / PAGE
    if not source.is_file():  # a textual-serve laid out otherwise: its own page, as is
        return Path("templates")
    folder = Path(tempfile.mkdtemp(prefix="modscope-serve-"))
    atexit.register(shutil.rmtree, folder, True)
    (folder / PAGE).write_text(offline_page(source.read_text(encoding="utf-8")), encoding="utf-8")
    return folder

"""Provides `modscope serve`: the TUI in a web browser, one app per visitor, through the
optional textual-serve package (`pip install 'modscope[serve]'`)."""

from __future__ import annotations

import argparse
import atexit
import re
import shlex
import shutil
import socket
import sys
import tempfile
from pathlib import Path
from typing import TextIO
from urllib.parse import urlsplit

from sniffer.cli.options import SubParsers, add_device_options, add_line_options
from sniffer.cli.tui import capture_path
from sniffer.errors import UsageError

SERVE_MISSING = (
    "modscope: error: `modscope serve` needs the optional textual-serve package; "
    "install it with: pip install 'modscope[serve]'\n"
)


def forwarded(args: argparse.Namespace) -> list[str]:
    """The `tui` command line that shows what `serve` was asked to show."""
    argv = ["tui"]
    if args.file:
        argv.append(str(Path(args.file).resolve()))
    for name in ("baud", "bytesize", "parity", "stopbits", "mode", "timeout"):
        value = getattr(args, name, None)
        if value is not None:
            argv += [f"--{name}", str(value)]
    if args.bus:
        argv += ["--bus", str(Path(args.bus).resolve())]
    for unit in args.unit:
        argv += ["--unit", unit]
    for d in args.dict:
        argv += ["--dict", str(Path(d).resolve())]
    return argv


WILDCARDS = ("0.0.0.0", "::", "[::]", "")


def public_url(host: str, port: int, given: str | None) -> str:
    """The address a browser loads the page and its scripts from: `given` (checked), or
    http://HOST:PORT; for a wildcard host (0.0.0.0, ::), this machine's name, since a
    page pointing at 0.0.0.0 works on no other machine."""
    if given:
        parts = urlsplit(given)
        if parts.scheme not in ("http", "https") or not parts.hostname:
            raise UsageError(
                f"--public-url {given}: write the address browsers use to reach this "
                "machine, e.g. --public-url http://10.0.0.5:8000"
            )
        if parts.path not in ("", "/") or parts.query or parts.fragment:
            raise UsageError(
                f"--public-url {given}: give only scheme, host and port "
                "(e.g. http://10.0.0.5:8000); modscope serves from the root"
            )
        return f"{parts.scheme}://{parts.netloc}"
    name = socket.gethostname() if host in WILDCARDS else host
    if ":" in name and not name.startswith("["):
        name = f"[{name}]"  # an IPv6 address in a URL
    return f"http://{name}" + ("" if port == 80 else f":{port}")


def cmd_serve(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    capture_path(args.file)  # fail here, not in the browser, when there is nothing to show
    url = public_url(args.host, args.port, args.public_url)
    try:  # here: an optional extra (modscope[serve]), loaded by this command only
        from textual_serve.server import Server
    except ImportError:
        err.write(SERVE_MISSING)
        return 2
    command = shlex.join([sys.executable, "-m", "sniffer.cli", *forwarded(args)])
    where = "every address" if args.host in WILDCARDS else args.host
    out.write(f"modscope: listening on {where}, port {args.port}; browsers open {url}\n")
    if args.host in WILDCARDS and not args.public_url:
        out.write(
            f"modscope: if other machines cannot resolve {urlsplit(url).hostname}, "
            "pass --public-url http://THIS-ADDRESS:PORT\n"
        )
    out.flush()
    server = Server(
        command,
        host=args.host,
        port=args.port,
        title="modscope",
        public_url=url,
        templates_path=offline_templates(),
    )
    server.serve()
    return 0


def register(sub: SubParsers) -> None:
    p = sub.add_parser(
        "serve",
        help="serve the TUI in a web browser (needs modscope[serve])",
        description="Serve the TUI on a capture in a web browser, one app per visitor.",
        epilog=(
            "examples:\n"
            "  modscope serve                          the demo, on this machine only\n"
            "  modscope serve bus.pcapng --host 0.0.0.0 --port 8000 \\\n"
            "      --public-url http://10.0.0.5:8000   from other machines, at 10.0.0.5\n"
            "The page's scripts connect back to --public-url, so give the address other\n"
            "machines reach this one at (behind a proxy: the proxy's address)."
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("file", nargs="?", help="capture file (default: the bundled demo)")
    p.add_argument(
        "--host",
        default="localhost",
        help="address to listen on (default localhost; 0.0.0.0 for every address)",
    )
    p.add_argument("--port", type=int, default=8000, help="port to listen on (default 8000)")
    p.add_argument(
        "--public-url",
        metavar="URL",
        help="the address browsers use to reach this machine, e.g. http://10.0.0.5:8000 "
        "(default http://HOST:PORT; this machine's name when HOST is 0.0.0.0)",
    )
    add_line_options(p)
    add_device_options(p)
    p.set_defaults(func=cmd_serve)


# -- the page, offline ---------------------------------------------------------------------
# textual-serve's page links a stylesheet on fonts.googleapis.com for its terminal font
# (Roboto Mono). A site PC or a plant network often has no internet: the browser then
# waits for that request, and each visit is told to a third party. The page's own font
# list goes on to the browser's monospace fonts (Roboto Mono is still used where it is
# installed), so the link is left out: the installed page is read at start-up and
# written, changed only there, to a temporary folder removed on exit.

PAGE = "app_index.html"
# a <link> element whose href leaves the server (the web font's stylesheet)
OUTSIDE_LINK = re.compile(r"<link\b[^>]*\bhref=\"https?://[^\"]*\"[^>]*>\s*", re.S)


def offline_page(html: str) -> str:
    """The page with every stylesheet link to another host left out."""
    return OUTSIDE_LINK.sub("", html)


def offline_templates() -> Path:
    """A templates folder for textual-serve's `Server` whose page loads nothing from the
    internet; where the installed page is not found, textual-serve's own (`templates`,
    relative to its module)."""
    import textual_serve  # the optional [serve] extra, present when this is called

    installed = getattr(textual_serve, "__file__", None)
    source = Path(installed or ".").parent / "templates" / PAGE
    if not source.is_file():  # a textual-serve laid out otherwise: its own page, as is
        return Path("templates")
    folder = Path(tempfile.mkdtemp(prefix="modscope-serve-"))
    atexit.register(shutil.rmtree, folder, True)
    (folder / PAGE).write_text(offline_page(source.read_text(encoding="utf-8")), encoding="utf-8")
    return folder

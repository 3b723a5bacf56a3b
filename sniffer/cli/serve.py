"""Provides `modscope serve`: the TUI in a web browser, one app per visitor, through the
optional textual-serve package (`pip install 'modscope[serve]'`).

Safe by default (docs/untrusted-input.md, "serve"): the address printed carries a random
token (or the one in MODSCOPE_SERVE_TOKEN); the page answers only with it, and hands the
browser a cookie that the app's WebSocket must show. The WebSocket must also come from
the page's own origin (a page of another site, opened in the same browser, is refused),
and at most --max-sessions apps run at once. A visitor's export and recording write only
inside --export-dir, under a plain name, never over a file, and are handed to the browser
as downloads; without --export-dir nothing is kept on this machine.
"""

from __future__ import annotations

import argparse
import atexit
import hmac
import os
import re
import secrets
import shlex
import shutil
import socket
import sys
import tempfile
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO
from urllib.parse import quote, urlsplit

from sniffer.cli.options import SubParsers, add_device_options, add_line_options
from sniffer.cli.tui import capture_path
from sniffer.errors import UsageError

if TYPE_CHECKING:
    from aiohttp import web

    Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]

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
TOKEN_ENV = "MODSCOPE_SERVE_TOKEN"  # a token of one's own (a bookmark that lasts)
EXPORT_DIR_ENV = "MODSCOPE_SERVE_EXPORT_DIR"  # read by the TUI's export and recording
SERVED_ENV = "MODSCOPE_SERVED"  # set for the apps `serve` starts: write nowhere else
COOKIE = "modscope_token"
MAX_SESSIONS = 4  # each app is a process of about 50 MB


def origin_of(url: str) -> str:
    """scheme://host[:port] of `url`, lower-cased, default ports dropped."""
    parts = urlsplit(url)
    host = (parts.hostname or "").lower()
    if ":" in host:
        host = f"[{host}]"
    default = {"http": 80, "https": 443, "ws": 80, "wss": 443}.get(parts.scheme)
    port = "" if parts.port in (None, default) else f":{parts.port}"
    return f"{parts.scheme.lower()}://{host}{port}"


class Guard:
    """The checks every request passes (module doc): the token, the origin, the cap."""

    def __init__(self, token: str, public: str, max_sessions: int) -> None:
        self.token = token
        self.public = origin_of(public)
        self.max_sessions = max_sessions
        self.sessions = 0

    def authorised(self, query_token: str | None, cookie: str | None) -> bool:
        given = query_token if query_token is not None else cookie
        return given is not None and hmac.compare_digest(given.encode(), self.token.encode())

    def same_origin(self, origin: str | None, host: str | None, scheme: str) -> bool:
        """Whether a WebSocket's Origin header is the page's own: the public URL's, or
        the address the browser asked for (Host). A browser always sends Origin."""
        if not origin:
            return False
        seen = origin_of(origin)
        return seen == self.public or (host is not None and seen == origin_of(f"{scheme}://{host}"))

    def middleware(self) -> Any:
        from aiohttp import web  # textual-serve's own dependency

        @web.middleware
        async def guard(request: web.Request, handler: Handler) -> web.StreamResponse:
            if request.path.startswith("/static/"):
                return await handler(request)  # the page's scripts and fonts: nothing private
            query_token = request.query.get("token")
            if not self.authorised(query_token, request.cookies.get(COOKIE)):
                raise web.HTTPForbidden(
                    text="modscope serve: open the address with ?token=... that "
                    "`modscope serve` printed\n"
                )
            if request.path == "/ws":
                if not self.same_origin(
                    request.headers.get("Origin"), request.host, request.scheme
                ):
                    raise web.HTTPForbidden(
                        text="modscope serve: this page's origin may not open the app\n"
                    )
                if self.sessions >= self.max_sessions:
                    raise web.HTTPServiceUnavailable(
                        text=f"modscope serve: {self.max_sessions} sessions are open "
                        "already (--max-sessions); close one and reload\n"
                    )
                self.sessions += 1
                try:
                    return await handler(request)
                finally:
                    self.sessions -= 1
            response: web.StreamResponse = await handler(request)
            if query_token is not None:
                response.set_cookie(COOKIE, self.token, httponly=True, samesite="Strict", path="/")
            response.headers["Referrer-Policy"] = "no-referrer"  # the token stays here
            return response

        return guard


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


def export_dir(given: str | None) -> str | None:
    """The folder visitors' exports go to, checked: it exists and is a folder."""
    if given is None:
        return None
    path = Path(given).expanduser().resolve()
    if not path.is_dir():
        raise UsageError(f"--export-dir {given}: no such folder; create it or name another")
    return str(path)


# seconds a download waits for the app's next chunk before it is cut short (see cmd_serve)
DOWNLOAD_WAIT = 60


def cmd_serve(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    capture_path(args.file)  # fail here, not in the browser, when there is nothing to show
    url = public_url(args.host, args.port, args.public_url)
    if args.max_sessions < 1:
        raise UsageError(f"--max-sessions {args.max_sessions}: give 1 or more")
    folder = export_dir(args.export_dir)
    token = os.environ.get(TOKEN_ENV) or secrets.token_urlsafe(18)
    try:  # here: an optional extra (modscope[serve]), loaded by this command only
        from textual_serve import download_manager
        from textual_serve.server import Server
    except ImportError:
        err.write(SERVE_MISSING)
        return 2
    # textual-serve ends a download, cut short, when the app has not sent its next chunk
    # within 4 s; an app busy listing a day on a loaded Pi, or on a shared machine, can
    # take longer, and the browser then keeps a truncated file as if it were whole (seen
    # on a 2-core machine running the tests). The module reads the constant at each
    # chunk, so a longer wait set here holds for this server.
    download_manager.DOWNLOAD_TIMEOUT = max(download_manager.DOWNLOAD_TIMEOUT, DOWNLOAD_WAIT)
    command = shlex.join([sys.executable, "-m", "sniffer.cli", *forwarded(args)])
    where = "every address" if args.host in WILDCARDS else args.host
    out.write(
        f"modscope: listening on {where}, port {args.port}; browsers open "
        f"{url}/?token={quote(token)}\n"
    )
    out.write(
        f"modscope: at most {args.max_sessions} sessions; exports "
        + (f"go to {folder} and download" if folder else "download only (no --export-dir)")
        + "\n"
    )
    if args.host in WILDCARDS and not args.public_url:
        out.write(
            f"modscope: if other machines cannot resolve {urlsplit(url).hostname}, "
            "pass --public-url http://THIS-ADDRESS:PORT\n"
        )
    out.flush()
    # the apps are this process's children and inherit its environment (textual-serve)
    os.environ[SERVED_ENV] = "1"
    os.environ.pop(EXPORT_DIR_ENV, None)
    if folder:
        os.environ[EXPORT_DIR_ENV] = folder
    server = Server(
        command,
        host=args.host,
        port=args.port,
        title="modscope",
        public_url=url,
        templates_path=offline_templates(),
    )
    guard = Guard(token, url, args.max_sessions)
    make_app = server._make_app

    async def guarded_app() -> Any:
        app = await make_app()
        app.middlewares.append(guard.middleware())  # before the app starts (and freezes)
        return app

    server._make_app = guarded_app  # type: ignore[method-assign]
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
            "machines reach this one at (behind a proxy: the proxy's address).\n"
            "The address printed holds a random token (MODSCOPE_SERVE_TOKEN sets one that\n"
            "lasts); without it the page answers 403. Visitors' exports go to --export-dir\n"
            "only, as downloads (docs/untrusted-input.md)."
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
    p.add_argument(
        "--max-sessions",
        type=int,
        default=MAX_SESSIONS,
        metavar="N",
        help=f"apps running at once, about 50 MB each (default {MAX_SESSIONS})",
    )
    p.add_argument(
        "--export-dir",
        metavar="DIR",
        help="the folder visitors' exports and recordings are written to (default: "
        "none; exports are downloads only)",
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

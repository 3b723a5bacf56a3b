"""The `tui` and `serve` commands: registered without importing Textual, serve's missing
extra explained, the command line serve hands to textual-serve."""

from __future__ import annotations

import io
import subprocess
import sys
import types
from pathlib import Path
from typing import Any

import pytest

from sniffer.cli import build_parser, main, serve
from sniffer.session.session import DEMO_CAPTURE

ROOT = Path(__file__).resolve().parent.parent.parent


def test_building_the_parser_does_not_import_textual() -> None:
    code = (
        "import sys\n"
        "from sniffer.cli import build_parser\n"
        "build_parser().parse_args(['tui'])\n"
        "build_parser().parse_args(['serve', '--port', '9000'])\n"
        "print(any(m == 'textual' or m.startswith('textual.') for m in sys.modules))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    assert out.stdout.strip() == "False"


def test_serve_without_the_extra_says_how_to_install_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "textual_serve", None)
    monkeypatch.setitem(sys.modules, "textual_serve.server", None)
    err = io.StringIO()
    args = build_parser().parse_args(["serve"])
    assert serve.cmd_serve(args, io.StringIO(), err) == 2
    assert "pip install 'modscope[serve]'" in err.getvalue()


def test_serve_runs_the_tui_command_for_each_visitor(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    made: dict[str, Any] = {}

    class Server:
        def __init__(self, command: str, **options: Any) -> None:
            made["command"] = command
            made["options"] = options

        def serve(self) -> None:
            made["served"] = True

        async def _make_app(self) -> Any:  # what serve's guard wraps (textual-serve's)
            return None

    package = types.ModuleType("textual_serve")
    server = types.ModuleType("textual_serve.server")
    server.Server = Server  # type: ignore[attr-defined]
    downloads = types.ModuleType("textual_serve.download_manager")
    downloads.DOWNLOAD_TIMEOUT = 4  # type: ignore[attr-defined]  # textual-serve's own
    package.download_manager = downloads  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "textual_serve", package)
    monkeypatch.setitem(sys.modules, "textual_serve.server", server)
    monkeypatch.setitem(sys.modules, "textual_serve.download_manager", downloads)
    capture = tmp_path / "bus log.pcapng"
    capture.write_bytes(DEMO_CAPTURE.read_bytes() if DEMO_CAPTURE.exists() else b"\x01\x03")
    argv = ["serve", str(capture), "--port", "9001", "--baud", "9600", "--unit", "3=rvs-dn"]
    # serve marks its own environment for the apps it starts; run in this process, that
    # mark must not outlive the test (it would make every later TUI test a served visitor,
    # whose exports are downloads and whose recordings need --export-dir)
    for name in (serve.SERVED_ENV, serve.EXPORT_DIR_ENV):
        monkeypatch.setenv(name, "")
        monkeypatch.delenv(name)
    assert main(argv) == 0
    # a textual_serve without its page on disk (this stand-in): its own page is used
    assert made["options"].pop("templates_path") == Path("templates")
    assert made["served"] and made["options"] == {
        "host": "localhost",
        "port": 9001,
        "title": "modscope",
        "public_url": "http://localhost:9001",
    }
    command = made["command"]
    assert command.startswith(sys.executable) and "-m sniffer.cli tui" in command
    # a download waits for a slow app's next chunk longer than textual-serve's 4 s
    assert downloads.DOWNLOAD_TIMEOUT == serve.DOWNLOAD_WAIT
    assert f"'{capture.resolve()}'" in command  # quoted: the name has a space
    assert "--baud 9600" in command and "--unit 3=rvs-dn" in command


def test_serve_refuses_a_missing_file_before_serving(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["serve", "/no/such/capture.pcapng"]) == 2
    assert "no such file" in capsys.readouterr().err


def test_tui_opens_the_capture_even_when_piped(monkeypatch: pytest.MonkeyPatch) -> None:
    if not DEMO_CAPTURE.exists():
        pytest.skip("the demo capture is missing")
    seen: dict[str, Any] = {}

    def run_tui(session: Any, capture: Any, **options: Any) -> int:
        seen.update(session=session, capture=capture, options=options)
        return 0

    import sniffer.tui.app

    monkeypatch.setattr(sniffer.tui.app, "run_tui", run_tui)
    assert main(["tui", "--speed", "original"]) == 0
    assert seen["options"] == {"speed": 1.0}
    assert seen["session"].annotator.label(3) == "Pump 1 starter"  # the demo's bus file
    assert seen["capture"] is not None


def test_forwarded_keeps_what_serve_was_asked() -> None:
    args = build_parser().parse_args(
        [
            "serve",
            "x.pcapng",
            "--parity",
            "n",
            "--mode",
            "ascii",
            "--bus",
            "b.toml",
            "--dict",
            "d.toml",
        ]
    )
    argv = serve.forwarded(args)
    assert argv[:2] == ["tui", str(Path("x.pcapng").resolve())]
    assert argv[2:6] == ["--parity", "N", "--mode", "ascii"]
    assert "--bus" in argv and str(Path("b.toml").resolve()) in argv
    assert "--dict" in argv and str(Path("d.toml").resolve()) in argv

"""Provides helpers shared by tests (moved from test_mqtt_broker.py)."""

from __future__ import annotations

import getpass
import socket
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


@dataclass(frozen=True)
class Pki:
    """A CA and a server certificate it signed (for `localhost` and 127.0.0.1), made with
    the openssl command for one test."""

    ca: Path
    cert: Path
    key: Path


def make_pki(folder: Path, name: str = "ca") -> Pki:
    """A fresh CA named `name` in `folder` and a server certificate signed by it."""
    folder.mkdir(parents=True, exist_ok=True)
    ca, ca_key = folder / f"{name}.pem", folder / f"{name}.key"
    cert, key = folder / f"{name}-server.pem", folder / f"{name}-server.key"
    csr, ext = folder / f"{name}-server.csr", folder / f"{name}-server.ext"

    def run(*args: str) -> None:
        subprocess.run(["openssl", *args], check=True, capture_output=True, timeout=60)

    run("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-subj",
        f"/CN=modscope test {name}", "-keyout", str(ca_key), "-out", str(ca))  # fmt: skip
    run("req", "-newkey", "rsa:2048", "-nodes", "-subj", "/CN=localhost",
        "-keyout", str(key), "-out", str(csr))  # fmt: skip
    ext.write_text("subjectAltName=DNS:localhost,IP:127.0.0.1\n")
    run("x509", "-req", "-in", str(csr), "-CA", str(ca), "-CAkey", str(ca_key),
        "-CAcreateserial", "-days", "2", "-extfile", str(ext), "-out", str(cert))  # fmt: skip
    return Pki(ca, cert, key)


def password_file(folder: Path, user: str, password: str) -> Path:
    """A mosquitto password file holding `user`, made with mosquitto_passwd."""
    path = folder / "passwd"
    path.write_text("")
    subprocess.run(
        ["mosquitto_passwd", "-b", str(path), user, password],
        check=True,
        capture_output=True,
        timeout=30,
    )
    return path


class Broker:
    """A mosquitto process on `port`, with persistence in `folder` (survives restarts).

    `user` is the user running the tests: started as root, mosquitto otherwise drops to
    the `mosquitto` user, cannot write its database into a root-owned temporary folder,
    says so only in its log, and forgets every session when it restarts.

    `passwords` (a mosquitto_passwd file) turns anonymous access off; `pki` makes the
    listener a TLS one with that server certificate."""

    def __init__(
        self, folder: Path, *, passwords: Path | None = None, pki: Pki | None = None
    ) -> None:
        self.port = _free_port()
        self.folder = folder
        self.conf = folder / "mosquitto.conf"
        auth = (
            f"allow_anonymous false\npassword_file {passwords}\n"
            if passwords is not None
            else "allow_anonymous true\n"
        )
        tls = (
            f"cafile {pki.ca}\ncertfile {pki.cert}\nkeyfile {pki.key}\n" if pki is not None else ""
        )
        self.conf.write_text(
            f"listener {self.port} 127.0.0.1\n{tls}{auth}persistence true\n"
            f"persistence_location {folder}/\nmax_queued_messages 10000\n"
            f"user {getpass.getuser()}\n"
        )
        self.proc: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        self.proc = subprocess.Popen(
            ["mosquitto", "-c", str(self.conf)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        for _ in range(100):
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", self.port)) == 0:
                    return
            time.sleep(0.05)
        raise RuntimeError("mosquitto did not start")

    def stop(self) -> None:
        if self.proc is not None:
            self.proc.terminate()
            self.proc.wait(10)
            self.proc = None


@contextmanager
def running(folder: Path) -> Iterator[Broker]:
    """A Mosquitto broker of its own, its files in `folder`, stopped when the block ends."""
    b = Broker(folder)
    b.start()
    try:
        yield b
    finally:
        b.stop()


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    """A Mosquitto broker of its own for one test (import this fixture by name)."""
    with running(tmp_path) as b:
        yield b

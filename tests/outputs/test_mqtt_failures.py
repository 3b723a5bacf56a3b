"""MQTT failures are loud (#26): against a real Mosquitto with TLS and password listeners
made here (a CA and a server certificate from the openssl command, a password file from
mosquitto_passwd), `modscope replay --mqtt` and the watcher `modscope live mqtt://...`
end with exit 2 and one line naming the broker (never the password) and the cause.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from sniffer.outputs.mqtt import MqttError
from sniffer.outputs.mqtt.target import parse_target, redact
from tests.support.broker import Broker, Pki, _free_port, make_pki, password_file

pytestmark = [
    pytest.mark.peer,
    pytest.mark.skipif(
        shutil.which("mosquitto") is None or shutil.which("openssl") is None,
        reason="apt-get install mosquitto openssl",
    ),
]
pytest.importorskip("paho.mqtt.client")

MODSCOPE = str(Path(sys.executable).with_name("modscope"))
SECRET = "s3cret-Pa55"


def _run(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    full = {k: v for k, v in os.environ.items() if not k.startswith("MODSCOPE_MQTT_")}
    full.update(env or {})
    return subprocess.run(
        [MODSCOPE, *args], capture_output=True, text=True, timeout=60, env=full, check=False
    )


def _one_line(done: subprocess.CompletedProcess[str]) -> str:
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert "Traceback" not in done.stderr
    return lines[0]


@pytest.fixture
def pki(tmp_path: Path) -> Pki:
    return make_pki(tmp_path / "pki")


@pytest.fixture
def secure(tmp_path: Path, pki: Pki) -> Iterator[Broker]:
    """A TLS listener that wants user `alice` with SECRET."""
    folder = tmp_path / "secure"
    folder.mkdir()
    b = Broker(folder, passwords=password_file(folder, "alice", SECRET), pki=pki)
    b.start()
    try:
        yield b
    finally:
        b.stop()


def test_nothing_listening_is_exit_2_naming_the_broker() -> None:
    port = _free_port()
    done = _run("replay", "--mqtt", f"mqtt://bob:{SECRET}@127.0.0.1:{port}/x")
    assert done.returncode == 2
    line = _one_line(done)
    assert f"mqtt://127.0.0.1:{port}/x" in line and "connection refused" in line
    assert SECRET not in done.stderr and "bob" not in done.stderr


def test_an_unknown_host_is_exit_2() -> None:
    done = _run("replay", "--mqtt", "mqtt://no-such-host.invalid/x")
    assert done.returncode == 2
    assert "cannot resolve 'no-such-host.invalid'" in _one_line(done)


def test_tls_without_the_ca_is_refused(secure: Broker, pki: Pki, tmp_path: Path) -> None:
    """The system CAs do not know the test CA; another CA is not the one."""
    url = f"mqtts://alice@localhost:{secure.port}/site/a"
    env = {"MODSCOPE_MQTT_PASSWORD": SECRET}
    done = _run("replay", "--mqtt", url, env=env)
    assert done.returncode == 2
    line = _one_line(done)
    assert f"mqtts://localhost:{secure.port}/site/a" in line
    assert "TLS certificate was refused" in line and "--mqtt-ca" in line
    other = make_pki(tmp_path / "other", "other")
    done = _run("replay", "--mqtt", url, "--mqtt-ca", str(other.ca), env=env)
    assert done.returncode == 2
    assert f"--mqtt-ca {other.ca} is not the CA that signed it" in _one_line(done)
    done = _run("replay", "--mqtt", url, "--mqtt-ca", str(tmp_path / "none.pem"), env=env)
    assert done.returncode == 2
    assert f"--mqtt-ca {tmp_path / 'none.pem'}: not a readable" in _one_line(done)


def test_a_plain_client_on_a_tls_listener_is_told_so(secure: Broker) -> None:
    done = _run("replay", "--mqtt", f"mqtt://alice@127.0.0.1:{secure.port}/x")
    assert done.returncode == 2
    assert "mqtts://" in _one_line(done)


def test_a_wrong_password_is_exit_2_never_shown(secure: Broker, pki: Pki, tmp_path: Path) -> None:
    wrong = tmp_path / "wrong"
    wrong.write_text("not-the-password\n")
    url = f"mqtts://alice@localhost:{secure.port}/site/a"
    done = _run("replay", "--mqtt", url, "--mqtt-ca", str(pki.ca), "--mqtt-password-file",
                str(wrong))  # fmt: skip
    assert done.returncode == 2
    line = _one_line(done)
    assert "refused user 'alice'" in line and "not-the-password" not in done.stderr
    # the watcher says the same, not "no broker answers there"
    done = _run("live", url, "--mqtt-ca", str(pki.ca), "--mqtt-password-file", str(wrong))
    assert done.returncode == 2
    assert "refused user 'alice'" in _one_line(done)


def test_the_right_credentials_from_a_file_or_the_environment_publish(
    secure: Broker, pki: Pki, tmp_path: Path
) -> None:
    good = tmp_path / "good"
    good.write_text(SECRET + "\n")
    url = f"mqtts://alice@localhost:{secure.port}/site/a"
    done = _run("replay", "--mqtt", url, "--mqtt-ca", str(pki.ca), "--mqtt-password-file",
                str(good))  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "messages delivered to mqtts://localhost" in done.stderr
    assert "dropped" not in done.stderr and SECRET not in done.stderr
    done = _run("replay", "--mqtt", url, "--mqtt-ca", str(pki.ca),
                env={"MODSCOPE_MQTT_PASSWORD": SECRET})  # fmt: skip
    assert done.returncode == 0, done.stderr
    got = subprocess.run(
        ["mosquitto_sub", "-h", "localhost", "-p", str(secure.port), "--cafile", str(pki.ca),
         "-u", "alice", "-P", SECRET, "-t", "site/a/status", "-C", "1", "-W", "5"],
        capture_output=True, text=True, timeout=30, check=False,
    )  # fmt: skip
    assert got.stdout.strip() == "offline"  # the retained goodbye: it was delivered


def test_passwords_never_appear_in_url_errors() -> None:
    for url in (
        f"mqtt://u:{SECRET}@host:99999/x",
        f"http://u:{SECRET}@host/x",
        f"mqtt://u:{SECRET}@[::1/x",
        f"mqtt://u:{SECRET}@host/a/+/b",
    ):
        with pytest.raises(MqttError) as caught:
            parse_target(url)
        assert SECRET not in str(caught.value) and "***@" in str(caught.value)
    assert redact(f"modscope live mqtt://u:p@{SECRET}@h/x") == "modscope live mqtt://***@h/x"


def test_password_sources_in_order(tmp_path: Path) -> None:
    file = tmp_path / "pw"
    file.write_text("from-file\nsecond line ignored\n")
    env = {"MODSCOPE_MQTT_PASSWORD": "from-env", "MODSCOPE_MQTT_USER": "eve"}
    assert parse_target("mqtt://a:from-url@h/x", password_file=str(file), environ=env).password == (
        "from-url"
    )
    t = parse_target("mqtt://a@h/x", password_file=str(file), environ=env)
    assert (t.username, t.password) == ("a", "from-file")
    t = parse_target("mqtt://h/x", environ=env)
    assert (t.username, t.password) == ("eve", "from-env")
    with pytest.raises(MqttError, match=r"--mqtt-password-file .*: cannot read it"):
        parse_target("mqtt://a@h/x", password_file=str(tmp_path / "missing"), environ={})
    with pytest.raises(MqttError, match="a password without a user name"):
        parse_target("mqtt://h/x", environ={"MODSCOPE_MQTT_PASSWORD": "p"})


def test_a_crash_report_never_shows_the_password() -> None:
    import io

    from sniffer.cli import report_bug

    err = io.StringIO()
    try:
        raise RuntimeError(f"broke while talking to mqtt://bob:{SECRET}@broker/x")
    except RuntimeError:
        assert report_bug(err, ["live", f"mqtts://bob:{SECRET}@broker/x"]) == 70
    text = err.getvalue()
    assert SECRET not in text and "bob" not in text
    assert "mqtts://***@broker/x" in text and "mqtt://***@broker/x" in text

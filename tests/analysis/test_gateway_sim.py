"""A gateway simulation: pymodbus's TCP client -> a small Modbus TCP to RTU gateway
written here -> pymodbus's serial server on a pty bus, captured on both sides (dumpcap on
loopback for TCP, `modscope record` on the bus tap for RTU), with faults injected by the
gateway. `modscope replay TCP SERIAL` must give each transaction the verdict of the fault
injected into it, one for one."""

from __future__ import annotations

import contextlib
import json
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from dissectors.checks import with_crc
from sniffer.cli import main
from tests.support.virtual_bus import ModbusServer, VirtualBus, wait_ready

MODSCOPE = str(Path(sys.executable).with_name("modscope"))
ABSENT = 5  # a unit nobody serves on the bus: the device "times out"

# (fault the gateway injects, unit asked, verdict modscope must give)
PLAN = [
    ("pass", 1, "ok"),
    ("drop request", 1, "not-sent"),  # never put on the serial line, no TCP answer
    ("pass", ABSENT, "device-timeout"),  # sent; nobody answers; the gateway says nothing
    ("lose answer", 2, "answer-lost"),  # the device answers; the gateway drops it
    ("0x0B after timeout", ABSENT, "gateway-exception"),
    ("0x0A, not sent", 1, "gateway-exception"),  # path unavailable: nothing sent
    # a gateway whose own timeout is shorter than the device's answer time: it answers
    # 0x0B while the device does answer on the serial line
    ("0x0B, device answered", 2, "gateway-fault"),
    ("pass", 2, "ok"),
]


class Gateway:
    """Modbus TCP in on loopback, RTU out on a serial port, one request at a time; the
    k-th request gets the k-th fault of `faults`."""

    def __init__(self, serial_port: Path, faults: list[str]) -> None:
        import serial

        self.faults = faults
        self.count = 0
        self.ser = serial.Serial(str(serial_port), 19200, parity="N", stopbits=2, timeout=0)
        self.listener = socket.socket()
        self.listener.bind(("127.0.0.1", 0))
        self.listener.listen(4)
        self.listener.settimeout(0.2)
        self.port: int = self.listener.getsockname()[1]
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, name="gateway", daemon=True)

    def __enter__(self) -> Gateway:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join(5)
        self.listener.close()
        self.ser.close()

    def _serve(self) -> None:
        while not self.stop.is_set():
            try:
                conn, _ = self.listener.accept()
            except TimeoutError:
                continue
            with conn:
                conn.settimeout(0.2)
                self._connection(conn)

    def _connection(self, conn: socket.socket) -> None:
        buf = b""
        while not self.stop.is_set():
            try:
                data = conn.recv(1024)
            except TimeoutError:
                continue
            except OSError:
                return
            if not data:
                return
            buf += data
            while len(buf) >= 7 and len(buf) >= 6 + int.from_bytes(buf[4:6], "big"):
                size = 6 + int.from_bytes(buf[4:6], "big")
                frame, buf = buf[:size], buf[size:]
                answer = self._handle(frame[:2], frame[6:])
                if answer is not None:
                    header = frame[:4] + len(answer).to_bytes(2, "big")
                    conn.sendall(header + answer)

    def _read_answer(self, wait: float) -> bytes:
        """RTU bytes until 50 ms of silence after the first, or `wait` without any."""
        got = b""
        deadline = time.monotonic() + wait
        last = 0.0
        while True:
            chunk = self.ser.read(256)
            now = time.monotonic()
            if chunk:
                got += chunk
                last = now
            elif got and now - last > 0.05:
                return got
            elif not got and now > deadline:
                return b""
            time.sleep(0.002)

    def _handle(self, tid: bytes, body: bytes) -> bytes | None:
        fault = self.faults[self.count] if self.count < len(self.faults) else "pass"
        self.count += 1
        exception = bytes([body[0], body[1] | 0x80])
        if fault == "drop request":
            return None
        if fault == "0x0A, not sent":
            return exception + b"\x0a"
        self.ser.write(with_crc(body))
        if fault == "0x0B, device answered":
            self._read_answer(0.5)  # the answer is drained, not passed on
            return exception + b"\x0b"
        rtu = self._read_answer(0.4)
        if fault == "lose answer":
            return None
        if not rtu:
            return exception + b"\x0b" if fault == "0x0B after timeout" else None
        return rtu[:-2]


@pytest.mark.peer
@pytest.mark.slow
@pytest.mark.skipif(not shutil.which("dumpcap"), reason="needs dumpcap (tshark package)")
def test_gateway_faults_get_their_verdicts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("pymodbus")
    from pymodbus.client import ModbusTcpClient

    tcp_path, serial_path = tmp_path / "tcp.pcapng", tmp_path / "serial.pcapng"
    with VirtualBus(tmp_path) as bus:
        device_end = bus.attach("device")
        gateway_end = bus.attach("gateway")
        tap = bus.attach("tap")
        server = ModbusServer(device_end, units=(1, 2)).start()
        recorder = subprocess.Popen(
            [
                MODSCOPE,
                "record",
                str(tap),
                "--parity",
                "N",
                "--stopbits",
                "2",
                "-w",
                f"{serial_path}",
            ],
            stderr=subprocess.PIPE,
            text=True,
        )
        dumpcap: subprocess.Popen[str] | None = None
        try:
            wait_ready(recorder.stderr)
            with Gateway(gateway_end, [fault for fault, _, _ in PLAN]) as gateway:
                dumpcap = subprocess.Popen(
                    ["dumpcap", "-i", "lo", "-f", f"tcp port {gateway.port}", "-w", str(tcp_path)],
                    stderr=subprocess.PIPE,
                    text=True,
                )
                assert dumpcap.stderr is not None
                for line in dumpcap.stderr:
                    if "Capturing on" in line:
                        break
                time.sleep(1.0)  # dumpcap says it captures a little before it does
                client: Any = ModbusTcpClient(
                    "127.0.0.1", port=gateway.port, timeout=1.0, retries=0
                )
                assert client.connect()
                for k, (_, unit, _) in enumerate(PLAN):
                    with contextlib.suppress(Exception):  # timeouts are the faults
                        client.read_holding_registers(10 + k, count=1, device_id=unit)
                    time.sleep(0.1)
                client.close()
                time.sleep(0.5)
        finally:
            if dumpcap is not None:
                dumpcap.send_signal(signal.SIGINT)
                dumpcap.communicate(timeout=10)
            recorder.send_signal(signal.SIGTERM)
            recorder.communicate(timeout=10)
            server.stop()

    code = main(["replay", str(tcp_path), str(serial_path), "--format", "jsonl"])
    out, err = capsys.readouterr()
    rows = [json.loads(line) for line in out.splitlines()]
    tcp_requests = [r for r in rows if r["mode"] == "tcp" and r["kind"] == "request"]
    assert [r["function"] for r in tcp_requests] == [3] * len(PLAN)
    assert [r["gateway"]["verdict"] for r in tcp_requests] == [v for _, _, v in PLAN]
    # the clock offset was estimated from the transactions seen on both sides, and shown
    assert "clock offset" in err and "estimated from" in err
    # the links point across: a linked TCP request's peer is the serial request with
    # the same unit and PDU
    for r in tcp_requests:
        peer = r["gateway"]["peer"]
        if r["gateway"]["verdict"] in ("not-sent", "gateway-exception") and peer is None:
            continue
        other = rows[peer]
        assert other["mode"] == "rtu" and other["raw"][:-4] == r["raw"][12:]
        assert other["gateway"]["peer"] == r["index"]
        assert r["gateway"]["delay_ms"] >= 0
    assert code in (0, 1)

    code = main(["replay", str(tcp_path), str(serial_path), "--stats"])
    out, _ = capsys.readouterr()
    assert "gateway: 8 Modbus TCP transaction(s)" in out
    assert "not-sent                 1" in out and "gateway-exception        2" in out
    assert "127.0.0.1:" in out  # the per-server section

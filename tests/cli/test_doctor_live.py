"""`modscope doctor PORT --duration S` listening to a virtual RS-485 bus with real peers:
pymodbus's serial server (units 1 and 2) and its client as the master, which also polls
a unit nobody is and a register unit 1 does not have. The doctor names both, passively."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.support.virtual_bus import ModbusServer, VirtualBus, modbus_client, wait_ready

pytest.importorskip("pymodbus")
pytestmark = pytest.mark.peer

MODSCOPE = str(Path(sys.executable).with_name("modscope"))
LINE_ARGS = ["--baud", "19200", "--parity", "N", "--stopbits", "2", "--mode", "rtu"]
TIMING = ["--timeout", "0.6", "--duration", "8s"]


class _Lines:
    def __init__(self, stream: Any) -> None:
        self.stream = stream

    def readline(self) -> str:
        line: bytes = self.stream.readline()
        return line.decode("utf-8", errors="replace")


@pytest.fixture
def bus(tmp_path: Path) -> Iterator[VirtualBus]:
    with VirtualBus(tmp_path) as b:
        yield b


def test_doctor_listens_and_names_the_silent_unit_and_the_failing_poll(bus: VirtualBus) -> None:
    from pymodbus.exceptions import ModbusIOException

    server = ModbusServer(bus.attach("server")).start()
    client_port = bus.attach("client")
    tap = bus.attach("tap", raw=False)
    proc = subprocess.Popen(
        [MODSCOPE, "doctor", str(tap), *LINE_ARGS, *TIMING, "--format", "json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    client = None
    try:
        assert proc.stderr is not None
        wait_ready(_Lines(proc.stderr))
        client = modbus_client(client_port, timeout=0.5)
        for _ in range(4):
            assert not client.read_holding_registers(0, count=5, device_id=1).isError()
            assert not client.read_input_registers(3, count=4, device_id=2).isError()
            assert client.read_holding_registers(500, count=2, device_id=1).isError()
            with pytest.raises(ModbusIOException):
                client.read_holding_registers(0, count=1, device_id=7)
        out, err = proc.communicate(timeout=30)
    finally:
        if client is not None:
            client.close()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        server.stop()
    assert proc.returncode == 1, err.decode()
    found = {(f["kind"], f.get("unit")): f for f in json.loads(out)}
    assert ("silent-unit", 7) in found
    assert found[("silent-unit", 7)]["evidence"]["requests"] == 4
    exception = found[("exception-poll", 1)]
    assert exception["evidence"]["code"] == 2 and exception["evidence"]["exceptions"] == 4
    # units 1 and 2 answer every poll: nothing says they miss or are not there
    for kind in ("silent-unit", "intermittent-unit", "address-conflict"):
        assert (kind, 1) not in found and (kind, 2) not in found
    # passive: the tap never sent a byte onto the bus
    assert bus.sent_by("tap") == b""

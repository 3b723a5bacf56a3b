"""Port doubles for the scan: a UART on a wire that refuses some line settings, as a
pseudo-terminal or a tunnel's far end refuses even parity (pyserial lets the tty ioctl's
`termios.error` through), and an RFC 2217 URL whose server takes no settings at all."""

from __future__ import annotations

import errno
import termios

import serial

from tests.support.uart_double import GarblingPort, GarblingPorts, Wire
from tests.support.virtual_bus import Tripwire


class PickyPort(GarblingPort):
    """A GarblingPort that refuses the formats in `refuse` (e.g. {"8E1"}) when it opens."""

    def __init__(self, wire: Wire, window: float, start: float, refuse: set[str]) -> None:
        self.refuse = refuse
        super().__init__(wire, window, start)

    def open(self) -> None:
        if f"{self.bytesize}{self.parity}{self.stopbits}" in self.refuse:
            self.calls.append("open")
            raise termios.error(errno.EINVAL, "Invalid argument")
        super().open()


class PickyPorts(GarblingPorts):
    """A port factory whose ports refuse some formats; each open is a fresh stretch."""

    def __init__(self, wire: Wire, refuse: set[str], window: float = 0.3) -> None:
        super().__init__(wire, window)
        self.refuse = refuse

    def __call__(self, name: str) -> serial.Serial:
        port = PickyPort(self.wire, self.window, 0.003 + len(self.ports) * self.window, self.refuse)
        self.ports.append(port)
        return port


class NoControlPort(Tripwire):
    """An RFC 2217 URL whose server does not speak the protocol: pyserial's own words."""

    def open(self) -> None:
        self.calls.append("open")
        raise serial.SerialException(
            "Remote does not seem to support RFC2217 or BINARY mode "
            "[we-BINARY:INACTIVE, we-RFC2217:REQUESTED]"
        )


class NoControlPorts:
    def __init__(self) -> None:
        self.ports: list[NoControlPort] = []

    def __call__(self, name: str) -> serial.Serial:
        port = NoControlPort(name)
        self.ports.append(port)
        return port

"""Provides pure Modbus protocol knowledge: checks, envelopes, function codes, devices.

`envelope` says what a transport wraps around a PDU (RTU, ASCII, Modbus TCP's MBAP);
`pdu` holds the function codes by family and `dissect()`; `dictionary` the device
dictionaries, whose own function codes `pdu.vendor` compiles into a registry.
`functions` and `dissect` are facades.

Nothing here does I/O on a bus, and nothing here imports `sniffer`, Textual or pyserial.
"""

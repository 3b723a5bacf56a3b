"""Provides pure Modbus protocol knowledge: checks, function codes, device dictionaries.

Nothing here does I/O on a bus, and nothing here imports `sniffer`, Textual or pyserial.
"""

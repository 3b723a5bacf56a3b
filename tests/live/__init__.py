"""Tests of sniffer.live: passive ports, the capture engine, the recorder, the scan."""

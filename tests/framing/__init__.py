"""Tests of sniffer.framing: the RTU and ASCII framers, the store, pairing."""

"""Tests of sniffer.cli: the commands as a user runs them."""

"""Tests of sniffer.sources: every capture and log format read; the same frames from every
form of the same bytes."""

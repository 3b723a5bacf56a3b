"""Tests of sniffer.meaning: annotation, frame details, SunSpec."""

"""Provides what the tests share: virtual buses, packet builders, seed vectors, TUI helpers."""

"""Tests of sniffer.tui: the Textual app, its panes, keys and screens."""

"""Tests of sniffer.session: the sidecar index, the paged store, windowed replays."""
